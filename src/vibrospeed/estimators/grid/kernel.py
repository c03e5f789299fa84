"""The omega grid and the random-walk transition kernel of the grid tracker (banded or exact,
one- or two-component), with the rotation blocks ``F(omega_j)`` of the harmonic model.
``config`` below is the tracker's :class:`~vibrospeed.estimators.grid.config.Config`, which
builds its kernel here (so this module does not import it).


Banded kernel and its error bound
---------------------------------
With ``sigma = sqrt(T var(v^omega))`` (paper values at 100 Hz: 0.2 rad/s) the kernel is
negligible beyond a few grid spacings. ``kernel="banded"`` keeps, for every source row, only the
targets ``|i - j| <= B``, with ``B`` the smallest band whose discarded row mass
``eps_i = sum_{|j - i| > B} K_ij`` is at most ``kernel_tol`` for *every* row (found once at
:func:`build_kernel` in O(N^2) time, O(N) memory), and renormalises the kept entries. Each banded
row is then within total variation ``eps <= kernel_tol`` (L1 ``2 eps``) of the exact row, so one
transition of any weight vector moves it by at most ``2 kernel_tol`` in L1; the merged moments
are weighted by these same numbers. The bound is per transition and in L1: it does not bound
the *relative* weight of far-off grid points (banded: at the floor; exact: hundreds of nats
above it), which a later likelihood can magnify, so during an acquisition (a cart start-up)
banded and exact runs can differ by more than the bound suggests (measured:
benchmarks/reference/RESULTS.md). Work per sample is
O(N B (2M)^2). ``kernel="exact"`` keeps the full rows (B = N - 1; O(N^2) kernel memory) as
the reference. The optional two-component walk (``Config.q_omega_fast``, ``p_fast``) uses the
mixture rows ``(1 - p) K_slow + p K_fast`` with the same band rule and bound (B then follows
the wide component).

Weights are kept in log space and floored at ``log_floor`` nats below the best grid point
(default 600, i.e. a relative weight 1e-261): every hypothesis stays alive (the paper's argument
for the grid), the weights cannot underflow, and the floor changes the posterior by less than
``N e^-600``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.estimators.kalman import blocks_from_F


class Kernel(NamedTuple):
    """grid (N,) rad/s; edges (N+1,) cell edges; widths (N,); kb (N, 2B+1) kernel by target:
    ``kb[j, d] = K(i = j + d - B -> j)``; B band half-width; tail: max discarded row mass;
    blocks (N, M, 2, 2) of ``HarmonicModel.F(grid)``."""

    grid: np.ndarray
    edges: np.ndarray
    widths: np.ndarray
    kb: np.ndarray
    B: int
    tail: float
    blocks: np.ndarray


def make_grid(n: int, lo: float, hi: float, spacing: str = "linear") -> np.ndarray:
    """(n,) grid on [lo, hi]; ``spacing`` 'linear' or 'log'. ``n = 1`` gives the mid-point."""
    if n == 1:
        return np.array([0.5 * (lo + hi)])
    if spacing == "log":
        return np.geomspace(lo, hi, n)
    return np.linspace(lo, hi, n)


def cell_edges(grid: np.ndarray) -> np.ndarray:
    """(N+1,) cell edges: mid-points, ends extended by half the neighbouring spacing."""
    if grid.size == 1:
        return np.array([grid[0] - 0.5, grid[0] + 0.5])
    mid = 0.5 * (grid[1:] + grid[:-1])
    return np.concatenate([[grid[0] - (mid[0] - grid[0])], mid, [grid[-1] + (grid[-1] - mid[-1])]])


def _grid_variance(r: np.ndarray) -> np.ndarray:
    """Variance, in units of the spacing squared, of ``exp(-k^2 / (2 r^2))`` on the integers
    (the sampled Gaussian kernel on an infinite uniform grid, ``r = sigma / Delta``)."""
    k = np.arange(-40, 41, dtype=np.float64)
    e = np.exp(-0.5 * (k[None, :] / np.maximum(r, 1e-300)[:, None]) ** 2)
    return (e * k * k).sum(axis=1) / e.sum(axis=1)


def matched_sigmas(sigma: float, widths: np.ndarray) -> np.ndarray:
    """(N,) per-row sigma whose sampled Gaussian has variance ``sigma^2`` on a uniform grid of
    that row's cell width (``kernel_var="matched"``): ``g(s / Delta) = (sigma / Delta)^2`` with
    :func:`_grid_variance` ``g``, solved by bisection on ``[0, 1.5]`` (``g`` increases;
    ``g(r) = r^2`` within 1e-6 from r = 1.2 on, where ``s = sigma``)."""
    r = sigma / widths
    out = r.copy()
    small = r < 1.2
    if small.any():
        target = r[small] ** 2
        lo, hi = np.zeros(target.size), np.full(target.size, 1.5)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            low = _grid_variance(mid) < target
            lo, hi = np.where(low, mid, lo), np.where(low, hi, mid)
        out[small] = 0.5 * (lo + hi)
    return out * widths


def row_sigmas(config, sigma: float, widths: np.ndarray) -> np.ndarray:
    """(N,) the random walk's per-row sigma for ``config.kernel_var``."""
    if config.kernel_var == "matched" and sigma > 0.0:
        return matched_sigmas(sigma, widths)
    return np.full(widths.size, sigma)


@njit(cache=True)
def _band_tails(grid, widths, sigmas):
    """max_i (discarded mass of row i) for every band half-width B = 0..N-1, O(N) memory
    (row i a Gaussian of sigma ``sigmas[i]``)."""
    N = grid.size
    maxtail = np.zeros(N)
    row = np.empty(N)
    bymass = np.empty(N)
    for i in range(N):
        tot = 0.0
        for j in range(N):
            z = (grid[j] - grid[i]) / sigmas[i]
            row[j] = np.exp(-0.5 * z * z) * widths[j]
            tot += row[j]
        for d in range(N):
            bymass[d] = 0.0
        for j in range(N):
            bymass[abs(j - i)] += row[j] / tot
        # tail(B) = 1 - sum_{d <= B} bymass[d], accumulated from the outside for accuracy
        acc = 0.0
        for B in range(N - 1, -1, -1):
            if acc > maxtail[B]:
                maxtail[B] = acc
            acc += bymass[B]
    return maxtail


@njit(cache=True)
def _band_kernel(grid, widths, sigmas, B):
    """(N, 2B+1) row-normalised (over the band) kernel, indexed by target; row i a Gaussian
    of sigma ``sigmas[i]`` (0: stays at i)."""
    N = grid.size
    kb = np.zeros((N, 2 * B + 1))
    for i in range(N):
        lo = max(0, i - B)
        hi = min(N - 1, i + B)
        tot = 0.0
        for j in range(lo, hi + 1):
            if sigmas[i] > 0.0:
                z = (grid[j] - grid[i]) / sigmas[i]
                v = np.exp(-0.5 * z * z) * widths[j]
            else:
                v = 1.0 if j == i else 0.0
            kb[j, i - j + B] = v
            tot += v
        for j in range(lo, hi + 1):
            kb[j, i - j + B] /= tot
    return kb


@njit(cache=True)
def _mix_row(grid, widths, sigmas, probs, i, row):
    """Row i of the mixture kernel ``sum_c probs[c] K_c(i, .)`` into ``row`` (N,), each
    component ``K_c(i, j) ~ N(grid_j; grid_i, sigmas[c, i]^2) widths_j`` normalised over the
    grid (``sigmas[c, i] = 0``: stays at i)."""
    N = grid.size
    for j in range(N):
        row[j] = 0.0
    for c in range(sigmas.shape[0]):
        if probs[c] == 0.0:
            continue
        sg = sigmas[c, i]
        if sg == 0.0:
            row[i] += probs[c]
            continue
        tot = 0.0
        for j in range(N):
            z = (grid[j] - grid[i]) / sg
            tot += np.exp(-0.5 * z * z) * widths[j]
        f = probs[c] / tot
        for j in range(N):
            z = (grid[j] - grid[i]) / sg
            row[j] += np.exp(-0.5 * z * z) * widths[j] * f


@njit(cache=True)
def _band_tails_mix(grid, widths, sigmas, probs):
    """As :func:`_band_tails` for the mixture rows of :func:`_mix_row`."""
    N = grid.size
    maxtail = np.zeros(N)
    row = np.empty(N)
    bymass = np.empty(N)
    for i in range(N):
        _mix_row(grid, widths, sigmas, probs, i, row)
        tot = 0.0
        for j in range(N):
            tot += row[j]
        for d in range(N):
            bymass[d] = 0.0
        for j in range(N):
            bymass[abs(j - i)] += row[j] / tot
        acc = 0.0
        for B in range(N - 1, -1, -1):
            if acc > maxtail[B]:
                maxtail[B] = acc
            acc += bymass[B]
    return maxtail


@njit(cache=True)
def _band_kernel_mix(grid, widths, sigmas, probs, B):
    """(N, 2B+1) mixture kernel by target, each row renormalised over its band."""
    N = grid.size
    kb = np.zeros((N, 2 * B + 1))
    row = np.empty(N)
    for i in range(N):
        _mix_row(grid, widths, sigmas, probs, i, row)
        lo = max(0, i - B)
        hi = min(N - 1, i + B)
        tot = 0.0
        for j in range(lo, hi + 1):
            tot += row[j]
        for j in range(lo, hi + 1):
            kb[j, i - j + B] = row[j] / tot
    return kb


def _build_mix(config, grid: np.ndarray, widths: np.ndarray) -> tuple:
    """(kb, B, tail) of the two-component random walk (``Config.q_omega_fast``, ``p_fast``)."""
    model = config.model
    T = model.dt
    sig = np.sqrt(np.array([model.q_omega_step, T * config.q_omega_fast], dtype=np.float64))
    probs = np.array([1.0 - config.p_fast, config.p_fast], dtype=np.float64)
    sigmas = np.stack([row_sigmas(config, float(x), widths) for x in sig])
    N = grid.size
    if N == 1 or not np.any(sig * (probs > 0) > 0):
        B, tail = 0, 0.0
    elif config.kernel == "exact":
        B, tail = N - 1, 0.0
    else:
        tails = _band_tails_mix(grid, widths, sigmas, probs)
        ok = np.flatnonzero(tails <= config.kernel_tol)
        B = int(ok[0]) if ok.size else N - 1
        tail = float(tails[B])
    return _band_kernel_mix(grid, widths, sigmas, probs, B), B, tail


def build_kernel(config) -> Kernel:
    """Grid, cell widths, the (banded or exact) transition kernel and the F blocks."""
    model = config.model
    grid = make_grid(config.n_grid, config.omega_min, config.omega_max, config.spacing)
    edges = cell_edges(grid)
    widths = np.diff(edges)
    sigma = float(np.sqrt(model.q_omega_step))
    N = grid.size
    if config.has_fast:
        kb, B, tail = _build_mix(config, grid, widths)
        blocks = np.ascontiguousarray(blocks_from_F(model.F(grid)))
        return Kernel(grid, edges, widths, kb, B, tail, blocks)
    sigmas = row_sigmas(config, sigma, widths)
    if sigma == 0.0 or N == 1:
        B, tail = 0, 0.0
    elif config.kernel == "exact":
        B, tail = N - 1, 0.0
    else:
        tails = _band_tails(grid, widths, sigmas)
        ok = np.flatnonzero(tails <= config.kernel_tol)
        B = int(ok[0]) if ok.size else N - 1
        tail = float(tails[B])
    kb = _band_kernel(grid, widths, sigmas, B)
    blocks = np.ascontiguousarray(blocks_from_F(model.F(grid)))
    return Kernel(grid, edges, widths, kb, B, tail, blocks)


def check_grid_spacing(config) -> str | None:
    """A note when the random-walk step is much smaller than the grid spacing (STYLE 11).

    With the paper's values at 100 Hz: step 0.2 rad/s, spacing 0.55 rad/s; the posterior then
    moves between grid points through the kernel's tails only, which slows the reaction to fast
    speed changes. Returned as a note, not an error.
    """
    g = config.grid
    if g.size < 2:
        return None
    step = float(np.sqrt(config.model.q_omega_step))
    spacing = float(np.max(np.diff(g)))
    if step < 0.25 * spacing:
        return (f"omega random-walk step {step:.3g} rad/s is < 1/4 of the grid spacing "
                f"{spacing:.3g} rad/s: the posterior can hardly move between grid points")
    return None

