"""Rao-Blackwellized point-mass filter, the chassis-vibration paper's variant (paper III-D,
Algorithm 1; METHODS.md 1.3).

A fixed grid ``omega_j`` (j = 1..N) carries weights ``w_j`` and, per grid point, a Kalman filter
(mean ``m_j`` (2M,), covariance ``P_j`` (2M, 2M)) of the phasor states of
:class:`vibrospeed.models.harmonic.HarmonicModel`. One iteration, for sample ``y_k``:

1. measurement update per grid point (:func:`vibrospeed.estimators.kalman.update_one`)::

       log w_j += log N(y_k; h m_j, h P_j h' + r);   normalise in log space

2. output: posterior mean, std, MAP and the ``level`` credible interval of omega from the grid
   posterior (each mass spread uniformly over its cell, so quantiles interpolate);
3. linear time update per *source* point i: ``m_i- = F(omega_i) m_i``,
   ``P_i- = F(omega_i) P_i F(omega_i)' + T Q_lin`` (F from ``HarmonicModel.F(grid)``);
4. transition ``w_ij = w_i K_ij`` with the random-walk kernel
   ``K_ij = N(omega_j; omega_i, T var(v^omega)) Delta_j / sum_j(...)`` (``Delta_j`` cell width,
   rows normalised over the grid so no mass leaves it), ``W_j = sum_i w_ij``;
5. moment-matching merge with ``lambda_ij = w_ij / W_j``::

       m_j = sum_i lambda_ij m_i-,   P_j = sum_i lambda_ij (P_i- + m_i- m_i-') - m_j m_j'

   valid because ``p(x^lin_{t+1} | omega_{t+1}, omega_t) = p(x^lin_{t+1} | omega_t)`` for this
   model (paper III-D): the N^2 pairwise filters are never formed, memory is O(N).

The state stored between samples is the *prior* for the next sample (as in
:mod:`vibrospeed.estimators.ekf`): ``step`` = steps 1-5. NaN samples skip step 1.

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
banded and exact runs can differ by more than the bound suggests (docs/reference.md: up to
7.5 rad/s for a moment on one cart drive, RMSE 0.816 vs 0.802 rad/s). Work per sample is
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

from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import config_from_params, flat_dict
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import scaling as _scaling
from vibrospeed.estimators.kalman import blocks_from_F
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Recording, Track

#: measurement noise variance used with the running-RMS scaling (signal RMS 0.5, variance
#: 0.25): the harmonics are assumed to carry about 80 % of the pre-filtered signal power.
DEFAULT_R = 0.05

N_OUT_FIXED = 6  # mean, std, map, lo, hi, predictive log-likelihood; then M amplitudes


def _paper_model(dt: float = 0.01) -> HarmonicModel:
    return HarmonicModel.from_paper_table1(dt, r=DEFAULT_R)


@dataclass(frozen=True)
class Config:
    """RBPMF parameters (defaults: paper Table I and section IV-B).

    model : harmonic model; Table I: M = 3, var(v^omega) = 4, var(v^a,b) = 0.001,
        var(alpha_0) = 0.1. ``r`` (not in the paper) defaults to :data:`DEFAULT_R` for a signal
        normalised to RMS ``signal_rms``.
    n_grid, omega_min, omega_max : grid of N points on [omega_min, omega_max] rad/s
        (paper: 200 on [10, 120]). ``spacing``: "linear" (paper) or "log" (geometric, constant
        relative resolution).
    kernel : "banded" (default) or "exact" (full rows, reference). ``kernel_tol``: largest
        discarded mass per kernel row (see module docstring).
    kernel_var : "sampled" (default, the paper's) or "matched": how the random walk's
        variance ``T q_omega`` reaches the grid. The sampled density ``N(omega_j; omega_i,
        sigma^2) Delta_j`` has a variance on the grid well below ``sigma^2`` once ``sigma`` is
        smaller than the spacing (sigma / Delta = 0.36: 33 %; 0.14: 1e-10), so the walk's
        effective q_omega shrinks with the sample rate; "matched" widens each row's Gaussian
        (:func:`matched_sigmas`) until its variance on a grid of that row's spacing is
        ``sigma^2``, so q_omega means the same at any sample rate (equal to "sampled" within
        1e-6 for sigma >= 1.2 Delta).
    omega0, omega0_std : Gaussian prior on omega in rad/s; ``omega0=None`` (default) is the
        paper's "unknown initial angular velocity", a prior uniform in omega.
    log_floor : weights kept within this many nats of the best grid point.
    level : probability of the credible interval (paper figures: 98 %).
    prefilter : pre-filter preset for :func:`estimate` (paper: HP order 2 at 8 Hz).
    scaling : "rms" (running-RMS normalisation, :mod:`.scaling`) or "none" (data used as is).
    rms_tau : time constant of the running RMS in s. signal_rms : RMS after normalisation.
    nyquist : "warn" (default; harmonics above Nyquist alias, which the rotation model still
        describes exactly, only the fundamental must stay below it) or "error" (require
        ``M omega_max < pi fs``).

    Beyond the paper (issue 7; all off by default = the paper's filter, see :func:`improved`):

    jump_rate : 1/s, rate of a jump of omega to anywhere on the grid (re-acquisition). Per step
        ``eps = 1 - exp(-jump_rate T)`` of every grid point's mass moves to the grid with
        weights proportional to the cell widths (uniform in omega), and the jumped mass gets the
        linear-state prior ``N(0, var(alpha_0) I)``.
    off_rate, on_rate : 1/s, switching rates of a "no line" state (``off_rate = 0``: no such
        state). In it the sample is broadband, ``y ~ N(0, null_var)`` with ``null_var``
        defaulting to ``signal_rms^2`` (the running-RMS scaled signal's power). Its mass is
        reported as ``p_null``; the band spreads it uniformly over the grid (honest "no signal").
    p_null0 : prior mass of the "no line" state at the first sample; None (default): the
        switching chain's stationary share ``off_rate / (off_rate + on_rate)`` (2 % for the
        grid's rates, i.e. "a wheel line is there" before any data). 0.5 ("not known yet")
        suits a device switched on at standstill: an idling engine then reads "no line"
        sooner (causal grid, 5 seeds, has_signal while standing in the first 8 s: car 68 ->
        48 %, cart 64 -> 31 %), but a start while driving locks later (the "no line" mass
        re-enters the grid uniformly: car, lock < 2 s 83 -> 78 % of 175 starts; docs/beyond.md
        update 4).
    amb_rel, amb_abs : half-width ``max(amb_abs, amb_rel * x)`` of the window around ``x =
        MAP/2`` and ``2 MAP`` in which the posterior mass ``p_half``, ``p_double`` is reported;
        the same window defines the mode (``point``).
    smooth : "none" (causal filter), "fb" (forward-backward smoother over the whole log, with
        the Viterbi MAP path) or "lag" (fixed-lag smoother, ``lag`` s); see
        :mod:`vibrospeed.estimators.grid_smoother`.
    fit : comma-separated model parameters to fit by marginal likelihood before tracking
        (e.g. ``"q_omega,q_amp,r"``; :mod:`vibrospeed.estimators.fit`); empty: none.
    temper : power ``c`` in (0, 1] on the per-sample predictive likelihoods (grid and "no
        line"): ``log w_j += c log N(y; h m_j, S_j)``. ``c = 1`` is the paper's filter; ``c < 1``
        is the coarsened ("power") likelihood for a misspecified model (unmodelled resonances
        and interfering lines make the per-sample evidence over-confident): the posterior then
        moves as if it had seen ``c`` times the samples, leaving room for other evidence
        (:mod:`vibrospeed.estimators.grid`).
    temper_fs : Hz or None (default: ``temper`` is per sample). Set, ``temper`` is the power
        at this sample rate and a recording sampled at ``fs`` uses ``min(1, temper *
        temper_fs / fs)`` per sample (:attr:`temper_step`): the tempered evidence *per second*
        and its balance with per-second evidence (the grid's comb) then do not depend on the
        sample rate (simulated car at 400 Hz, 3 seeds, grid smoother: 76.7 % within tolerance
        with 0.2 per sample, 90.3 % with 0.2 at 100 Hz; docs/beyond.md update 4).
    null_model : time-domain emission of the "no line" state. ``"white"`` (default):
        ``y ~ N(0, null_var)``. ``"mixture"``: the signal part's own one-step predictive
        density, ``p0(y_k) = sum_j p(omega_j | y_1..k-1, line) p(y_k | omega_j, y_1..k-1)``
        (tempered like the grid's), so the per-sample data never favour "line" over "no
        line": a single strong line (idling engine, resonance) that the harmonic model fits
        no longer proves that a *wheel* is turning; that decision is left to ``extra``
        evidence that scores the harmonic comb (:mod:`vibrospeed.estimators.grid`) and to the
        switching rates. The data still place omega within the signal part.
    point : the point estimate :func:`estimate` reports as the Track's ``omega``: ``"mean"``
        (the paper's posterior mean) or ``"mode"``: the conditional mean of the window
        ``|omega - x| <= max(amb_abs, amb_rel x)`` that holds the most mass (a window, not the
        highest grid point, so a spiky posterior does not make the point hop between close
        peaks: issue 3, 87 car starts, strict lock < 2 s 90 -> 92 % at q_omega 4, 71 -> 82 %
        at 16). Its basin is the set of windows reached from it by non-increasing window mass;
        ``p_mode`` is the mass they cover. For a unimodal
        posterior both are equal; while the posterior is split between lines (acquisition
        from a uniform prior, a resonance, omega/2) the global mean lies between the modes,
        on no line, while the mode mean stays on the most probable one. Both are always in
        the outputs (``omega`` and ``omega_mode``, with the basin's share ``p_mode`` of the
        signal mass); samples with ``p_mode < mode_share`` are flagged ``multimodal``.
        ``step``/``run`` report the chosen one as ``omega`` (and the mean as ``omega_mean``).
    mode_hold : hysteresis of the mode in the causal filter (``step`` / ``run``; 1: none): the
        current mode window, re-centred on its best window within its half-width, is kept
        unless another window holds more than ``mode_hold`` times its mass, so a second line
        that briefly draws level does not make the point estimate hop (issue 3 follow-up 5).
        The smoothers report the stateless mode.
    q_omega_fast, p_fast : two-component ("slow cruise / fast acceleration") omega random
        walk (issue 3 follow-up; off by default, ``p_fast = 0`` is the paper's kernel): each
        step's increment is drawn from ``(1 - p_fast) N(0, T q_omega) + p_fast N(0, T
        q_omega_fast)`` (rad/s)^2/s, i.e. kernel rows ``K = (1 - p_fast) K_slow + p_fast
        K_fast`` with each component normalised over the grid. The band B (and the work per
        sample) follows the wider component; the ``kernel_tol`` bound holds for the mixture
        rows. Memory stays O(N B).
    """

    model: HarmonicModel = field(default_factory=_paper_model)
    n_grid: int = 200
    omega_min: float = 10.0
    omega_max: float = 120.0
    spacing: str = "linear"
    kernel: str = "banded"
    kernel_tol: float = 1e-9
    kernel_var: str = "sampled"
    omega0: float | None = None
    omega0_std: float = 2.0
    log_floor: float = 600.0
    level: float = 0.98
    prefilter: str = "paper-hp"
    scaling: str = "rms"
    rms_tau: float = _scaling.DEFAULT_TAU
    signal_rms: float = _scaling.DEFAULT_SIGNAL_RMS
    nyquist: str = "warn"
    jump_rate: float = 0.0
    off_rate: float = 0.0
    on_rate: float = 1.0
    null_var: float | None = None
    p_null0: float | None = None
    amb_rel: float = 0.05
    amb_abs: float = 1.5
    smooth: str = "none"
    lag: float = 2.0
    fit: str = ""
    temper: float = 1.0
    temper_fs: float | None = None
    null_model: str = "white"
    point: str = "mean"
    mode_share: float = 0.9
    mode_hold: float = 1.0
    q_omega_fast: float = 0.0
    p_fast: float = 0.0

    def __post_init__(self) -> None:
        if int(self.n_grid) != self.n_grid or self.n_grid < 1:
            raise ParameterError(f"n_grid must be a positive integer, got {self.n_grid}")
        if not 0 <= self.omega_min <= self.omega_max:
            raise ParameterError(
                f"grid needs 0 <= omega_min <= omega_max, got [{self.omega_min}, {self.omega_max}]"
            )
        if self.n_grid > 1 and not self.omega_min < self.omega_max:
            raise ParameterError("omega_min must be < omega_max when n_grid > 1")
        if self.spacing not in ("linear", "log"):
            raise ParameterError(f"spacing must be 'linear' or 'log', got '{self.spacing}'")
        if self.spacing == "log" and self.omega_min <= 0:
            raise ParameterError("spacing='log' needs omega_min > 0")
        if self.kernel not in ("banded", "exact"):
            raise ParameterError(f"kernel must be 'banded' or 'exact', got '{self.kernel}'")
        if self.kernel_var not in ("sampled", "matched"):
            raise ParameterError(f"kernel_var must be 'sampled' or 'matched', got "
                                 f"'{self.kernel_var}'")
        if not 0 < self.kernel_tol < 0.5:
            raise ParameterError(f"kernel_tol must be in (0, 0.5), got {self.kernel_tol}")
        if not 0 < self.level < 1:
            raise ParameterError(f"level must be in (0, 1), got {self.level}")
        if not self.omega0_std > 0:
            raise ParameterError(f"omega0_std must be > 0, got {self.omega0_std}")
        if not 10 <= self.log_floor <= 700:
            raise ParameterError(f"log_floor must be in [10, 700] nats, got {self.log_floor}")
        if self.scaling not in ("rms", "none"):
            raise ParameterError(f"scaling must be 'rms' or 'none', got '{self.scaling}'")
        if self.nyquist not in ("warn", "error"):
            raise ParameterError(f"nyquist must be 'warn' or 'error', got '{self.nyquist}'")
        for name in ("jump_rate", "off_rate", "on_rate", "amb_rel", "amb_abs"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.off_rate > 0 and not self.on_rate > 0:
            raise ParameterError("on_rate must be > 0 when off_rate > 0")
        if self.p_null0 is not None and not 0 < self.p_null0 < 1:
            raise ParameterError(f"p_null0 must be in (0, 1) (or None), got {self.p_null0}")
        if self.null_var is not None and not self.null_var > 0:
            raise ParameterError(f"null_var must be > 0, got {self.null_var}")
        if self.smooth not in ("none", "fb", "lag"):
            raise ParameterError(f"smooth must be 'none', 'fb' or 'lag', got '{self.smooth}'")
        if self.null_model not in ("white", "mixture"):
            raise ParameterError(f"null_model must be 'white' or 'mixture', got "
                                 f"'{self.null_model}'")
        if not 0 < self.temper <= 1:
            raise ParameterError(f"temper must be in (0, 1], got {self.temper}")
        if self.temper_fs is not None and not self.temper_fs > 0:
            raise ParameterError(f"temper_fs must be > 0 Hz (or None), got {self.temper_fs}")
        if self.point not in ("mean", "mode"):
            raise ParameterError(f"point must be 'mean' or 'mode', got '{self.point}'")
        if not self.q_omega_fast >= 0:
            raise ParameterError(f"q_omega_fast must be >= 0, got {self.q_omega_fast}")
        if not 0 <= self.p_fast <= 1:
            raise ParameterError(f"p_fast must be in [0, 1], got {self.p_fast}")
        if not 0 < self.mode_share <= 1:
            raise ParameterError(f"mode_share must be in (0, 1], got {self.mode_share}")
        if not self.mode_hold >= 1:
            raise ParameterError(f"mode_hold must be >= 1, got {self.mode_hold}")
        if not self.lag > 0:
            raise ParameterError(f"lag must be > 0 s, got {self.lag}")
        bad = [p for p in self.fit_names if p not in ("q_omega", "q_amp", "r")]
        if bad:
            raise ParameterError(f"fit: unknown parameter(s) {', '.join(bad)} "
                                 "(choose from q_omega, q_amp, r)")

    @property
    def fit_names(self) -> list[str]:
        """Parameters named in ``fit``."""
        return [p.strip() for p in str(self.fit).split(",") if p.strip()]

    @property
    def has_fast(self) -> bool:
        """Whether the omega random walk is the two-component mixture (``p_fast > 0``)."""
        return self.p_fast > 0

    @property
    def has_null(self) -> bool:
        """Whether the "no line" state is part of the model."""
        return self.off_rate > 0

    def rates(self) -> tuple[float, float, float, float]:
        """Per-step probabilities ``(eps_jump, p_off, p_on, null_var)``."""
        T = self.model.dt
        eps = -np.expm1(-self.jump_rate * T)
        p_off = -np.expm1(-self.off_rate * T) if self.has_null else 0.0
        p_on = -np.expm1(-self.on_rate * T) if self.has_null else 0.0
        nv = self.null_var if self.null_var is not None else self.signal_rms**2
        return float(eps), float(p_off), float(p_on), float(nv)

    @classmethod
    def from_paper_table1(cls, dt: float = 0.01, **kw) -> Config:
        """Paper Table I / IV-B: M = 3, var(v^omega) = 4, var(v^a,b) = 0.001, var(a_0) = 0.1,
        N = 200 linear on [10, 120] rad/s, HP order 2 at 8 Hz; ``r`` = :data:`DEFAULT_R`."""
        return cls(model=_paper_model(dt), n_grid=200, omega_min=10.0, omega_max=120.0, **kw)

    @property
    def temper_step(self) -> float:
        """Power on each sample's predictive likelihood: ``temper``, or with ``temper_fs``
        ``min(1, temper * temper_fs * dt)``."""
        if self.temper_fs is None:
            return float(self.temper)
        return min(1.0, float(self.temper) * (float(self.temper_fs) * self.model.dt))

    @cached_property
    def kern(self) -> Kernel:
        """Grid and transition kernel (built once per config)."""
        return build_kernel(self)

    @property
    def grid(self) -> np.ndarray:
        """(N,) grid of omega in rad/s."""
        return self.kern.grid

    def to_dict(self) -> dict:
        """JSON-serialisable parameters (model flattened)."""
        return flat_dict(self)


# ------------------------------------------------------------------------------------------
# grid and kernel
# ------------------------------------------------------------------------------------------
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


def row_sigmas(config: Config, sigma: float, widths: np.ndarray) -> np.ndarray:
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


def _build_mix(config: Config, grid: np.ndarray, widths: np.ndarray) -> tuple:
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


def build_kernel(config: Config) -> Kernel:
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


def check_grid_spacing(config: Config) -> str | None:
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


# ------------------------------------------------------------------------------------------
# state
# ------------------------------------------------------------------------------------------
class State(NamedTuple):
    """Prior for the next sample: ``log_w`` (N,) log-weights of the grid points, ``mean``
    (N, 2M), ``cov`` (N, 2M, 2M) per grid point, ``log_w_null`` log-weight of the "no line"
    state (-inf when the model has none). The weights sum to 1 over grid and null."""

    log_w: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    log_w_null: float = -np.inf
    mode_j: int = -1


class Estimate(NamedTuple):
    """Posterior at one sample (rad/s): mean, std, MAP, credible interval [lo, hi]; the
    predictive log-likelihood ``log p(y_k | y_1..k-1)``; ``p_null`` (mass of "no line"),
    ``p_half``, ``p_double`` (mass near MAP/2 and 2 MAP); amplitudes (M,) at the MAP point;
    ``posterior`` (N,) grid weights (signal part); ``p_third``, ``p_triple`` (mass near MAP/3
    and 3 MAP)."""

    omega: float
    omega_std: float
    omega_map: float
    omega_lo: float
    omega_hi: float
    loglik: float
    p_null: float
    p_half: float
    p_double: float
    amplitudes: np.ndarray
    posterior: np.ndarray
    p_third: float = 0.0
    p_triple: float = 0.0
    omega_mode: float = np.nan
    p_mode: float = np.nan
    omega_mean: float = np.nan


class Result(NamedTuple):
    """Batch output, arrays over samples (n,) unless noted."""

    omega: np.ndarray
    omega_std: np.ndarray
    omega_map: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    loglik: np.ndarray
    p_null: np.ndarray
    p_half: np.ndarray
    p_double: np.ndarray
    amplitudes: np.ndarray  # (n, M)
    posterior: np.ndarray | None  # (n, N) float32 when asked for
    grid_loglik: np.ndarray | None  # (n, N + 1) float32 when asked for (last column: null)
    final: State
    p_third: np.ndarray | None = None  # mass near MAP/3
    p_triple: np.ndarray | None = None  # mass near 3 MAP
    omega_mode: np.ndarray | None = None  # mean of the highest-mass window (the mode)
    p_mode: np.ndarray | None = None  # the basin's share of the signal mass
    omega_mean: np.ndarray | None = None  # the posterior mean (= omega unless point="mode")


#: outputs per sample: mean, std, map, lo, hi, pred loglik, p_null, p_half, p_double, p_third,
#: p_triple, mode mean, mode mass; then M amplitudes
N_OUT_FIXED = 13


def init(config: Config) -> State:
    """Prior at the first sample: weights uniform in omega (or Gaussian around ``omega0``),
    phasor means 0, covariances ``var(alpha_0) I``; with a "no line" state, its stationary
    probability ``off / (off + on)``."""
    k = config.kern
    N = k.grid.size
    n = config.model.n_lin
    if config.omega0 is None:
        lw = np.log(k.widths)
    else:
        z = (k.grid - config.omega0) / config.omega0_std
        lw = -0.5 * z * z + np.log(k.widths)
    lw = lw - np.max(lw)
    lw = np.maximum(lw, -config.log_floor)
    lw -= np.log(np.sum(np.exp(lw)))
    lw0 = -np.inf
    if config.has_null:
        p0 = (config.off_rate / (config.off_rate + config.on_rate) if config.p_null0 is None
              else float(config.p_null0))
        lw = lw + np.log1p(-p0)
        lw0 = float(np.log(p0))
    mean = np.zeros((N, n))
    cov = np.broadcast_to(np.eye(n) * config.model.p0_amp, (N, n, n)).copy()
    return State(lw, mean, cov, lw0)


# ------------------------------------------------------------------------------------------
# compiled core
# ------------------------------------------------------------------------------------------
LOG_2PI = float(np.log(2.0 * np.pi))


@njit(cache=True)
def _quantile(w, edges, q):
    """Quantile of the piecewise-uniform density with mass w_j on cell [edges_j, edges_j+1]."""
    acc = 0.0
    N = w.size
    for j in range(N):
        if acc + w[j] >= q and w[j] > 0.0:
            f = (q - acc) / w[j]
            if f < 0.0:
                f = 0.0
            if f > 1.0:
                f = 1.0
            return edges[j] + f * (edges[j + 1] - edges[j])
        acc += w[j]
    return edges[N]


@njit(cache=True)
def _mass_near(w, grid, x, rel, ab):
    """Mass of ``w`` on grid points within max(ab, rel x) of x."""
    hw = max(ab, rel * x)
    s = 0.0
    for j in range(grid.size):
        if abs(grid[j] - x) <= hw:
            s += w[j]
    return s


@njit(cache=True)
def _summary(w, w0, u, grid, edges, q_lo, q_hi, amb_rel, amb_abs, v, out, hold, cur):
    """Outputs 0-4, 6-10 from grid weights ``w`` (signal, sum 1 - w0) and null mass ``w0``:
    omega is the mean given a line (grid part renormalised); std and band are of the mixture
    ``v_j = w_j + w0 u_j`` (the null's omega is unknown: uniform on the grid);
    MAP and ambiguity masses are of the signal part."""
    N = grid.size
    mu = 0.0
    mc = 0.0
    jmap = 0
    for j in range(N):
        v[j] = w[j] + w0 * u[j]
        mu += v[j] * grid[j]
        mc += w[j] * grid[j]
        if w[j] > w[jmap]:
            jmap = j
    var = 0.0
    for j in range(N):
        d = grid[j] - mu
        var += v[j] * d * d
    # reported omega: the mean given that a line is present (= mu without a null state)
    out[0] = mc / (1.0 - w0) if w0 > 0.0 and w0 < 1.0 else mu
    out[1] = np.sqrt(var)
    out[2] = grid[jmap]
    out[3] = _quantile(v, edges, q_lo)
    out[4] = _quantile(v, edges, q_hi)
    out[6] = w0
    # the mode: the window of half-width max(amb_abs, amb_rel x) around a grid point x that
    # holds the most signal mass (v_j, two pointers; v is free after the quantiles), reported
    # as the window's conditional mean; a window, not the single highest point, so a spiky
    # posterior (fine grid, tempered data) does not hop between neighbouring peaks
    lo = 0
    hi = 0
    s = 0.0
    jb = 0
    for j in range(N):
        hw = max(amb_abs, amb_rel * grid[j])
        while hi < N and grid[hi] <= grid[j] + hw:
            s += w[hi]
            hi += 1
        while grid[lo] < grid[j] - hw:
            s -= w[lo]
            lo += 1
        v[j] = s
        if s > v[jb]:
            jb = j
    # hysteresis (mode_hold > 1): keep the current window, re-centred on its best window
    # within its half-width, unless the best window holds more than hold x its mass
    if hold > 1.0 and cur[0] >= 0:
        c = cur[0]
        hwc = max(amb_abs, amb_rel * grid[c])
        jc = c
        for j in range(N):
            if abs(grid[j] - grid[c]) <= hwc and v[j] > v[jc]:
                jc = j
        if not v[jb] > hold * v[jc]:
            jb = jc
    cur[0] = jb
    hw = max(amb_abs, amb_rel * grid[jb])
    sb = 0.0
    mb = 0.0
    for j in range(N):
        if abs(grid[j] - grid[jb]) <= hw:
            sb += w[j]
            mb += w[j] * grid[j]
    out[11] = mb / sb if sb > 0.0 else grid[jb]
    # its basin: the windows reached from jb by non-increasing window mass; p_mode is the
    # signal mass they cover (1e-12: the running sums' rounding, so a flat posterior is one
    # basin)
    a = jb
    while a > 0 and v[a - 1] <= v[a] + 1e-12:
        a -= 1
    b = jb
    while b < N - 1 and v[b + 1] <= v[b] + 1e-12:
        b += 1
    x_lo = grid[a] - max(amb_abs, amb_rel * grid[a])
    x_hi = grid[b] + max(amb_abs, amb_rel * grid[b])
    sb = 0.0
    for j in range(N):
        if grid[j] >= x_lo and grid[j] <= x_hi:
            sb += w[j]
    sig = 1.0 - w0
    out[12] = min(1.0, sb / sig) if sig > 1e-300 else 1.0
    if sig > 1e-300:
        x = grid[jmap]
        out[7] = _mass_near(w, grid, x / 2.0, amb_rel, amb_abs) / sig
        out[8] = _mass_near(w, grid, 2.0 * x, amb_rel, amb_abs) / sig
        out[9] = _mass_near(w, grid, x / 3.0, amb_rel, amb_abs) / sig
        out[10] = _mass_near(w, grid, 3.0 * x, amb_rel, amb_abs) / sig
    else:
        out[7] = 0.0
        out[8] = 0.0
        out[9] = 0.0
        out[10] = 0.0
    return jmap


@njit(cache=True)
def _step(lw, lw0, mean, cov, y, r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo, q_hi,
          eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold, cur, ex, w,
          v, X, acc, out, post, gll):
    """One RBPMF iteration in place on (lw, lw0[0], mean, cov); writes ``out``, ``post`` (N,)
    and ``gll`` (N + 1,) per-point log-emissions (if sized): ``temper`` times the predictive
    log-likelihood plus ``ex`` (N + 1,) extra log-evidence for this sample (if sized; last entry
    for the "no line" state). ``null_mix``: the "no line" state's time-domain emission is the
    signal part's predictive mixture (Config.null_model "mixture") instead of N(0, null_var).

    Specialised to the harmonic model: ``h = [1, 0, 1, 0, ...]`` (rank-1 update with
    ``P h' = sum of the even columns``), ``F`` block diagonal with rotations ``cs[i, m] =
    (cos, sin)(m omega_i T)`` precomputed per grid point, ``Q = qd I``.
    """
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    has_null = p_off > 0.0
    finite = np.isfinite(y)
    ph = acc[:n]
    # ---- 1. measurement update per grid point: log w_j += log N(y; h m_j, S_j) ----------
    if finite:
        for j in range(N):
            mj = mean[j]
            Pj = cov[j]
            yhat = 0.0
            for a in range(M):
                yhat += mj[2 * a]
            for i in range(n):
                s_ = 0.0
                for a in range(M):
                    s_ += Pj[i, 2 * a]
                ph[i] = s_
            S = r
            for a in range(M):
                S += ph[2 * a]
            nu = y - yhat
            inv = 1.0 / S
            g = nu * inv
            for i in range(n):
                mj[i] += ph[i] * g
            for i in range(n):
                pi = ph[i] * inv
                for k in range(i, n):
                    val = Pj[i, k] - pi * ph[k]
                    Pj[i, k] = val
                    Pj[k, i] = val
            ll = -0.5 * (LOG_2PI + np.log(S) + nu * nu * inv) * temper
            if null_mix:
                v[j] = lw[j]  # prior log-weight
                w[j] = lw[j] + ll  # prior times (tempered) predictive
            if ex.size > 0:
                ll += ex[j]
            lw[j] += ll
            if gll.size > 0:
                gll[j] = ll
        if has_null:
            if null_mix:
                # log sum_j p_j l_j - log sum_j p_j (signal part's predictive mixture)
                ma = -np.inf
                mb = -np.inf
                for j in range(N):
                    if w[j] > ma:
                        ma = w[j]
                    if v[j] > mb:
                        mb = v[j]
                sa = 0.0
                sb = 0.0
                for j in range(N):
                    sa += np.exp(w[j] - ma)
                    sb += np.exp(v[j] - mb)
                ll0 = ma + np.log(sa) - mb - np.log(sb)
            else:
                ll0 = -0.5 * (LOG_2PI + np.log(null_var) + y * y / null_var) * temper
            if ex.size > 0:
                ll0 += ex[N]
            lw0[0] += ll0
            if gll.size > 0:
                gll[N] = ll0
    else:
        if ex.size > 0:
            for j in range(N):
                lw[j] += ex[j]
            if has_null:
                lw0[0] += ex[N]
        if gll.size > 0:
            for j in range(N + 1):
                gll[j] = ex[j] if ex.size > 0 else 0.0
    mx = lw0[0] if has_null else -np.inf
    for j in range(N):
        if lw[j] > mx:
            mx = lw[j]
    # floor at log_floor nats below the best state, then normalise (one exp per point)
    s = 0.0
    for j in range(N):
        d = lw[j] - mx
        if d < -log_floor:
            d = -log_floor
        w[j] = np.exp(d)
        s += w[j]
    w0 = 0.0
    if has_null:
        d = lw0[0] - mx
        if d < -log_floor:
            d = -log_floor
        w0 = np.exp(d)
        s += w0
    pred_ll = mx + np.log(s)
    inv_s = 1.0 / s
    for j in range(N):
        w[j] *= inv_s
    w0 *= inv_s
    # ---- 2. outputs ---------------------------------------------------------------------
    jmap = _summary(w, w0, u, grid, edges, q_lo, q_hi, amb_rel, amb_abs, v, out, hold, cur)
    out[5] = pred_ll if finite else 0.0
    for a in range(M):
        al = mean[jmap, 2 * a]
        be = mean[jmap, 2 * a + 1]
        out[N_OUT_FIXED + a] = np.sqrt(al * al + be * be)
    if post.size == N:
        for j in range(N):
            post[j] = w[j]
    # ---- 3. linear time update per source point i (in place: m = F m, P = F P F' + Q),
    #         packed into X[i] = [m_i-, upper(P_i- + m_i- m_i-')] -------------------------
    for i in range(N):
        m = mean[i]
        P = cov[i]
        for a in range(M):
            c = cs[i, a, 0]
            sn = cs[i, a, 1]
            x0 = m[2 * a]
            x1 = m[2 * a + 1]
            m[2 * a] = c * x0 + sn * x1
            m[2 * a + 1] = -sn * x0 + c * x1
        for a in range(M):
            a0 = 2 * a
            ca = cs[i, a, 0]
            sa = cs[i, a, 1]
            for b in range(a, M):
                c0 = 2 * b
                cb = cs[i, b, 0]
                sb = cs[i, b, 1]
                p00 = P[a0, c0]
                p01 = P[a0, c0 + 1]
                p10 = P[a0 + 1, c0]
                p11 = P[a0 + 1, c0 + 1]
                # R_a P_ab, R = [[c, s], [-s, c]]
                t00 = ca * p00 + sa * p10
                t01 = ca * p01 + sa * p11
                t10 = -sa * p00 + ca * p10
                t11 = -sa * p01 + ca * p11
                # (R_a P_ab) R_b'
                r00 = t00 * cb + t01 * sb
                r01 = -t00 * sb + t01 * cb
                r10 = t10 * cb + t11 * sb
                r11 = -t10 * sb + t11 * cb
                if b == a:
                    r01 = 0.5 * (r01 + r10)
                    r10 = r01
                    r00 += qd
                    r11 += qd
                P[a0, c0] = r00
                P[a0, c0 + 1] = r01
                P[a0 + 1, c0] = r10
                P[a0 + 1, c0 + 1] = r11
        Xi = X[i]
        c = n
        for a in range(n):
            ma = m[a]
            Xi[a] = ma
            for b in range(a, n):
                Xi[c] = P[a, b] + ma * m[b]
                c += 1
    # ---- 4.-5. transition (random walk, jumps, null) and moment-matching merge ----------
    L = X.shape[1]
    rw = 1.0 - eps - p_off
    J = eps * (1.0 - w0) + p_on * w0  # mass redistributed uniformly with the prior
    for j in range(N):
        lo = max(0, j - B)
        hi = min(N - 1, j + B)
        for c in range(L):
            acc[c] = 0.0
        W = 0.0
        for i in range(lo, hi + 1):
            lam = w[i] * kb[j, i - j + B]
            W += lam
            Xi = X[i]
            for c in range(L):
                acc[c] += lam * Xi[c]
        if rw != 1.0:
            W *= rw
            for c in range(L):
                acc[c] *= rw
        Ju = J * u[j]
        if Ju > 0.0:
            W += Ju
            # prior: mean 0, second moment p0 I
            c = n
            for a in range(n):
                acc[c] += Ju * p0
                c += n - a
        inv = 1.0 / W
        # m_j = sum lam m_i- / W ;  P_j = sum lam (P_i- + m_i- m_i-') / W - m_j m_j'
        mj = mean[j]
        Pj = cov[j]
        for a in range(n):
            mj[a] = acc[a] * inv
        c = n
        for a in range(n):
            for b in range(a, n):
                val = acc[c] * inv - mj[a] * mj[b]
                Pj[a, b] = val
                Pj[b, a] = val
                c += 1
        lw[j] = np.log(W)
    if has_null:
        lw0[0] = np.log(p_off * (1.0 - w0) + (1.0 - p_on) * w0)


@njit(cache=True)
def _run(ys, lw, lw0, mean, cov, r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo, q_hi,
         eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold, cur, ex_idx,
         ex_val, want_post, want_gll):
    n_s = ys.size
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    outs = np.empty((n_s, N_OUT_FIXED + M))
    posts = np.empty((n_s if want_post else 0, N), dtype=np.float32)
    glls = np.empty((n_s if want_gll else 0, N + 1), dtype=np.float32)
    post = np.empty(N if want_post else 0)
    gll = np.empty(N + 1 if want_gll else 0)
    w = np.empty(N)
    v = np.empty(N)
    L = n + n * (n + 1) // 2
    X = np.empty((N, L))
    acc = np.empty(L)
    no_ex = np.empty(0)
    f = 0
    n_ex = ex_idx.size
    for k in range(n_s):
        while f < n_ex and ex_idx[f] < k:
            f += 1
        ex = ex_val[f] if (f < n_ex and ex_idx[f] == k) else no_ex
        _step(lw, lw0, mean, cov, ys[k], r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo,
              q_hi, eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold,
              cur, ex, w, v, X, acc, outs[k], post, gll)
        if want_post:
            for j in range(N):
                posts[k, j] = post[j]
        if want_gll:
            for j in range(N + 1):
                glls[k, j] = gll[j]
    return outs, posts, glls


def _check_h(model: HarmonicModel) -> None:
    h = model.H
    if not (np.all(h[0::2] == 1.0) and np.all(h[1::2] == 0.0)):  # pragma: no cover - invariant
        raise ParameterError("rbpmf needs the harmonic model's h = [1, 0, 1, 0, ...]")


def _args(config: Config) -> tuple:
    k = config.kern
    m = config.model
    _check_h(m)
    q = 0.5 * (1.0 - config.level)
    cs = np.ascontiguousarray(np.stack([k.blocks[:, :, 0, 0], k.blocks[:, :, 0, 1]], axis=-1))
    u = k.widths / np.sum(k.widths)
    eps, p_off, p_on, nv = config.rates()
    return (float(m.r), cs, float(m.dt * m.q_amp), k.kb, int(k.B), k.grid, k.edges, u,
            float(config.log_floor), q, 1.0 - q, eps, p_off, p_on, nv, float(m.p0_amp),
            float(config.amb_rel), float(config.amb_abs), config.temper_step,
            config.null_model == "mixture", float(config.mode_hold))


def _extra_vec(config: Config, ex) -> np.ndarray:
    N = config.n_grid
    e = np.ascontiguousarray(ex, dtype=np.float64)
    if e.shape == (N,):
        e = np.append(e, 0.0)
    if e.shape != (N + 1,):
        raise ParameterError(f"extra evidence must have {N} or {N + 1} entries, got {e.shape}")
    return e


def step(config: Config, state: State, y: float, extra=None) -> tuple[State, Estimate]:
    """Process one sample; returns the prior for the next sample and the posterior now.

    ``extra`` : optional (N,) or (N + 1,) log-evidence added to the grid points' (and the "no
    line" state's) log-weights with this sample (e.g. :mod:`vibrospeed.estimators.grid`)."""
    lw = state.log_w.copy()
    lw0 = np.array([state.log_w_null])
    mean = state.mean.copy()
    cov = state.cov.copy()
    N, n = mean.shape
    M = n // 2
    out = np.empty(N_OUT_FIXED + M)
    post = np.empty(N)
    L = n + n * (n + 1) // 2
    ex = np.empty(0) if extra is None else _extra_vec(config, extra)
    cur = np.array([state.mode_j], dtype=np.int64)
    _step(lw, lw0, mean, cov, float(y), *_args(config), cur, ex, np.empty(N), np.empty(N),
          np.empty((N, L)), np.empty(L), out, post, np.empty(0))
    om = out[11] if config.point == "mode" else out[0]
    est = Estimate(om, *out[1:5], out[5], out[6], out[7], out[8], out[N_OUT_FIXED:].copy(),
                   post, out[9], out[10], out[11], out[12], out[0])
    return State(lw, mean, cov, float(lw0[0]), int(cur[0])), est


def run(
    config: Config,
    y: np.ndarray,
    state: State | None = None,
    *,
    return_posterior: bool = False,
    return_grid_loglik: bool = False,
    extra: tuple[np.ndarray, np.ndarray] | None = None,
) -> Result:
    """Run over a whole (already pre-filtered, scaled) signal; identical to repeated
    :func:`step`. ``return_posterior``: also return the grid posterior (n, N) as float32;
    ``return_grid_loglik``: the per-state log-emissions (n, N + 1) float32 that
    :mod:`vibrospeed.estimators.grid_smoother` needs (last column: the "no line" state).
    ``extra = (idx, values)``: log-evidence ``values[f]`` ((N,) or (N + 1,) per row) added at
    sample ``idx[f]`` (indices into ``y``, increasing), as :func:`step`'s ``extra``."""
    st = init(config) if state is None else state
    lw = np.array(st.log_w, dtype=np.float64)
    lw0 = np.array([st.log_w_null], dtype=np.float64)
    mean = np.ascontiguousarray(st.mean, dtype=np.float64).copy()
    cov = np.ascontiguousarray(st.cov, dtype=np.float64).copy()
    ys = np.ascontiguousarray(y, dtype=np.float64)
    N = config.n_grid
    if extra is None:
        ex_idx, ex_val = np.zeros(0, np.int64), np.zeros((0, N + 1))
    else:
        ex_idx = np.ascontiguousarray(extra[0], dtype=np.int64)
        ex_val = np.ascontiguousarray(extra[1], dtype=np.float64)
        if ex_val.ndim == 2 and ex_val.shape[1] == N:
            ex_val = np.ascontiguousarray(np.column_stack([ex_val, np.zeros(len(ex_val))]))
        if ex_val.shape != (ex_idx.size, N + 1):
            raise ParameterError(f"extra evidence must be ({ex_idx.size}, {N} or {N + 1}), "
                                 f"got {ex_val.shape}")
        if ex_idx.size > 1 and np.any(np.diff(ex_idx) <= 0):
            raise ParameterError("extra evidence indices must be strictly increasing")
    cur = np.array([st.mode_j], dtype=np.int64)
    outs, posts, glls = _run(ys, lw, lw0, mean, cov, *_args(config), cur, ex_idx, ex_val,
                             bool(return_posterior), bool(return_grid_loglik))
    om = outs[:, 11] if config.point == "mode" else outs[:, 0]
    return Result(om, *(outs[:, c] for c in range(1, 9)), outs[:, N_OUT_FIXED:],
                  posts if return_posterior else None, glls if return_grid_loglik else None,
                  State(lw, mean, cov, float(lw0[0]), int(cur[0])), outs[:, 9], outs[:, 10],
                  outs[:, 11], outs[:, 12], outs[:, 0])


def improved(config: Config | None = None, **kw) -> Config:
    """``config`` (default: the paper's) with the issue-7 settings :data:`IMPROVED` switched on;
    ``kw`` overrides any Config field."""
    import dataclasses

    base = Config() if config is None else config
    kw = {**IMPROVED, **kw}
    mkw = {k: kw.pop(k) for k in list(kw) if k in ("M", "q_omega", "q_amp", "r", "p0_amp")}
    return dataclasses.replace(base, model=dataclasses.replace(base.model, **mkw), **kw)


#: noise levels for the improved tracker on the running-RMS scaled signal (docs/beyond.md):
#: between the marginal-likelihood fits on the car (r 0.2, q_omega 16, q_amp 0.002) and the
#: cart (r 0.0125, q_omega 0.125, q_amp 0.002); r large enough that a weak line still beats
#: the "no line" state.
IMPROVED_NOISE = {"r": 0.15, "q_amp": 0.002}
#: issue-7 settings used by :func:`improved` and ``params={"improved": True}``: jumps at
#: 0.05/s (a lost track is re-found within ~1/(0.05 * share of evidence) s; the posterior
#: cost is a floor of eps u_j on far grid points), "no line" state entered at 0.05/s, left at
#: 0.5/s, plus :data:`IMPROVED_NOISE`.
IMPROVED = {"jump_rate": 0.05, "off_rate": 0.05, "on_rate": 0.5, **IMPROVED_NOISE}


# ------------------------------------------------------------------------------------------
# entry point
# ------------------------------------------------------------------------------------------
def prepare(recording: Recording, axis: str, config_cls, params: dict | None, default_model):
    """Shared by the harmonic trackers: pre-filter, Nyquist check, scaling and the config.

    Returns ``(config, y_scaled, rms, notes)``; ``config.model.dt`` is the recording's period.
    """
    from vibrospeed.estimators.common import check_nyquist, prepare_axis, split_params

    params = dict(params or {})
    model_kw, cfg_kw = split_params(HarmonicModel, params)
    model_kw.pop("dt", None)
    base = default_model(1.0).to_dict()
    base.pop("dt")
    probe = config_from_params(config_cls, cfg_kw,
                               model=config_from_params(HarmonicModel, model_kw, dt=1.0, **base))
    y, dt, notes = prepare_axis(recording, axis, prefilter=probe.prefilter, M=probe.model.M,
                                normalize_tau=None,
                                omega_range=(probe.omega_min, probe.omega_max))
    fs = 1.0 / dt
    src = recording.source or "recording"
    om_max = float(probe.omega_max)
    M = probe.model.M
    if om_max >= np.pi * fs:
        raise ParameterError(
            f"{src}: sample rate {fs:.4g} Hz is too low for omega up to {om_max:.4g} rad/s "
            f"(the fundamental needs fs > {om_max / np.pi:.4g} Hz; lower omega_max)"
        )
    if probe.nyquist == "error":
        check_nyquist(fs, M, om_max, src)
    elif M * om_max >= np.pi * fs:
        notes.append(
            f"harmonics alias above omega = {np.pi * fs / M:.4g} rad/s (M = {M}, fs = "
            f"{fs:.4g} Hz); the rotation model describes the aliased lines exactly"
        )
    model = config_from_params(HarmonicModel, model_kw, dt=dt, **base)
    config = config_from_params(config_cls, cfg_kw, model=model)
    if config.scaling == "rms":
        y, rms = _scaling.normalise(y, dt, tau=config.rms_tau, target=config.signal_rms)
        notes.append(f"running-RMS normalisation to {config.signal_rms} (tau {config.rms_tau} s)")
    else:
        rms = np.full_like(y, config.signal_rms)
    return config, y, rms, notes


def _truthy(v) -> bool:
    if isinstance(v, str):
        return v.strip().lower() in ("1", "true", "yes", "on")
    return bool(v)


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Track omega on accelerometer axis ``axis`` of a uniformly sampled recording.

    The axis is pre-filtered (``prefilter``, paper HP by default), normalised by its running RMS
    (``scaling``) and tracked. ``params`` may set any :class:`Config` or
    :class:`HarmonicModel` field, plus ``improved=true`` (the issue-7 settings of
    :data:`IMPROVED` under any explicit params). ``smooth="fb"`` / ``"lag"`` smooths
    (:mod:`.grid_smoother`), ``fit="q_omega,q_amp,r"`` fits those by marginal likelihood first
    (:mod:`.fit`; values in the Track's params and notes).

    The Track's ``omega`` is the posterior mean (``point="mode"``: the mean of the MAP mode,
    the posterior mean then in extras ``omega_mean``), its band the ``level`` credible interval;
    extras ``omega_mode``, ``p_mode`` and ``multimodal`` (``p_mode < mode_share``) always;
    extras (per sample): ``omega_map`` (filter: MAP; smoother: Viterbi path, NaN in "no line"),
    ``loglik``, ``p_null``, ``p_half``, ``p_double``, ``p_third``, ``p_triple`` (mass near
    MAP/2, 2 MAP, MAP/3, 3 MAP), ``confidence`` (= 1 - p_null), ``has_signal`` (1.0 where
    confidence >= 0.5), ``ambiguous`` (1.0 where any of the four >= 0.05), ``amp1..M`` (in
    signal units), ``rms``. With ``return_posterior`` the extras also
    hold ``posterior`` (n, N) float32 and ``grid`` (N,) (for the posterior image).

    Examples
    --------
    >>> import numpy as np
    >>> from vibrospeed.types import Recording
    >>> t = np.arange(0, 20, 0.01)
    >>> rng = np.random.default_rng(0)
    >>> ay = np.sin(50 * t) + 0.5 * np.sin(100 * t) + 0.3 * rng.normal(size=t.size)
    >>> tr = estimate(Recording(t, {"ay": ay}))
    >>> bool(abs(tr.omega[-1] - 50) < 1)
    True
    """
    config, y, rms, notes = prepare(recording, axis, Config, _with_improved(params),
                                    _paper_model)
    return track(recording, config, y, rms, notes, axis=axis, wheel_radius=wheel_radius,
                 progress=progress, return_posterior=return_posterior, method="rbpmf")


def _with_improved(params: dict | None) -> dict:
    params = dict(params or {})
    if _truthy(params.pop("improved", False)):
        params = {**IMPROVED, **params}
    return params


def config_for(recording: Recording, *, axis: str = "y", params: dict | None = None) -> Config:
    """The :class:`Config` that :func:`estimate` builds for ``recording`` and ``params``: hand it
    to :class:`vibrospeed.estimators.online.OnlineTracker` to run the same filter on a device."""
    return prepare(recording, axis, Config, _with_improved(params), _paper_model)[0]


#: gain of the paper's high-pass (order 2) below which a note warns that the pre-filter
#: suppresses the low end of the grid (and with it the fundamental of slow wheels)
_PREFILTER_NOTE_GAIN = 0.5


def prefilter_note(config: Config, fs: float) -> str | None:
    """A note when the pre-filter's high-pass attenuates ``omega_min`` by more than half: e.g.
    ``paper-hp`` (8 Hz = 50 rad/s) on a 10 rad/s cart leaves the fundamental at 4 % and the
    2nd harmonic at 16 % of their amplitudes, so a body resonance wins (issue 7)."""
    from scipy.signal import sosfreqz

    from vibrospeed.signal import prefilter as pf

    try:
        sos = pf.design(config.prefilter, fs, M=config.model.M,
                        omega_range=(config.omega_min, config.omega_max))
    except Exception:  # pragma: no cover - preset validated in prepare
        return None
    _, h = sosfreqz(sos, worN=[config.omega_min / (2 * np.pi)], fs=fs)
    g = float(np.abs(h[0]))
    if g < _PREFILTER_NOTE_GAIN:
        return (f"pre-filter '{config.prefilter}' passes only {100 * g:.0f} % of the amplitude at "
                f"omega_min = {config.omega_min:g} rad/s: slow wheels' low harmonics are "
                "suppressed (use -p prefilter=thesis-hp for slow vehicles)")
    return None


def fit_for_track(config: Config, y: np.ndarray, extra, notes: list) -> Config:
    """``config`` with ``config.fit_names`` fitted by marginal likelihood on ``y`` (with the
    causal filter's ``extra`` evidence); the fitted values and any warnings go to ``notes``."""
    from vibrospeed.estimators import fit as _fit

    fr = _fit.fit(config, y, names=config.fit_names, extra=extra)
    notes.append("fitted by marginal likelihood: " + ", ".join(
        f"{k} = {v:.4g}" for k, v in fr.values.items()) + f" (log p(y) {fr.loglik:.6g})")
    notes.extend(f"fit: {w}" for w in fr.warnings)
    return fr.config


def track(recording: Recording, config: Config, y: np.ndarray, rms: np.ndarray, notes: list,
          *, axis: str, wheel_radius: float | None, progress: bool = False,
          return_posterior: bool = False, method: str = "rbpmf",
          extra: tuple[np.ndarray, np.ndarray] | None = None,
          extra_params: dict | None = None) -> Track:
    """The part of :func:`estimate` after :func:`prepare` (shared with
    :mod:`vibrospeed.estimators.grid`): optional fit, filter or smoother, Track with extras.
    ``extra``: log-evidence per :func:`run`."""
    if config.fit_names:
        config = fit_for_track(config, y, extra, notes)
    for note in (check_grid_spacing(config), prefilter_note(config, 1.0 / config.model.dt)):
        if note:
            notes.append(note)
    if config.kern.B > 0:
        notes.append(f"banded kernel: B = {config.kern.B}, discarded row mass <= "
                     f"{config.kern.tail:.2g}")
    M = config.model.M
    if config.smooth == "none":
        res = _run_chunked(config, y, return_posterior, progress, extra)
        omega, std, lo, hi = res.omega, res.omega_std, res.omega_lo, res.omega_hi
        omap, p_null, p_half, p_double = res.omega_map, res.p_null, res.p_half, res.p_double
        p_third, p_triple = res.p_third, res.p_triple
        post = res.posterior
    else:
        from vibrospeed.estimators import grid_smoother

        res = run(config, y, return_grid_loglik=True, extra=extra)
        if config.smooth == "fb":
            sm = grid_smoother.smooth(config, res.grid_loglik, return_posterior=return_posterior)
            vit = grid_smoother.viterbi(config, res.grid_loglik)
            omap = vit.omega
            notes.append("forward-backward smoother on the grid; omega_map = Viterbi path")
        else:
            sm = grid_smoother.fixed_lag(config, res.grid_loglik, lag=config.lag,
                                         return_posterior=return_posterior)
            omap = sm.omega_map
            notes.append(f"fixed-lag smoother, lag {config.lag:g} s (delay <= 2 lag)")
        omega, std, lo, hi = sm.omega, sm.omega_std, sm.omega_lo, sm.omega_hi
        p_null, p_half, p_double, post = sm.p_null, sm.p_half, sm.p_double, sm.posterior
        p_third, p_triple = sm.p_third, sm.p_triple
    if config.smooth == "none":  # res.omega is already the chosen point estimate
        o_mode, p_mode, o_mean = res.omega_mode, res.p_mode, res.omega_mean
    else:
        o_mode, p_mode, o_mean = sm.omega_mode, sm.p_mode, sm.omega
        if config.point == "mode":
            omega = o_mode
    if config.point == "mode":
        notes.append("omega = mean of the MAP mode (point='mode'); the posterior mean is in "
                     "extras['omega_mean']")
    conf = 1.0 - p_null
    amb = np.maximum(np.maximum(p_half, p_double), np.maximum(p_third, p_triple))
    extras: dict[str, np.ndarray] = {
        "omega_map": omap, "loglik": res.loglik, "p_null": p_null, "p_half": p_half,
        "p_double": p_double, "p_third": p_third, "p_triple": p_triple, "confidence": conf,
        "has_signal": (conf >= 0.5).astype(np.float64),
        "ambiguous": (amb >= 0.05).astype(np.float64), "rms": rms,
        "omega_mode": o_mode, "p_mode": p_mode,
        "multimodal": (p_mode < config.mode_share).astype(np.float64),
    }
    if config.point == "mode":
        extras["omega_mean"] = o_mean
    for m in range(M):
        extras[f"amp{m + 1}"] = res.amplitudes[:, m] * rms / config.signal_rms
    if return_posterior:
        extras["posterior"] = post
        extras["grid"] = config.grid.copy()
    return Track.from_omega(
        recording.t, omega, std, lo=lo, hi=hi,
        level=config.level, wheel_radius=wheel_radius or recording.wheel_radius, method=method,
        params={**config.to_dict(), **(extra_params or {}), "axis": axis}, extras=extras,
        notes=notes,
    )


def _run_chunked(config: Config, y: np.ndarray, return_posterior: bool, progress: bool,
                 extra=None) -> Result:
    if not progress or extra is not None:
        return run(config, y, return_posterior=return_posterior, extra=extra)
    from rich.progress import Progress

    chunk = 20000
    parts = []
    state = init(config)
    with Progress(transient=True) as bar:
        task = bar.add_task("rbpmf", total=y.size)
        for k0 in range(0, y.size, chunk):
            res = run(config, y[k0 : k0 + chunk], state, return_posterior=return_posterior)
            parts.append(res)
            state = res.final
            bar.update(task, advance=min(chunk, y.size - k0))
    cat = [np.concatenate([getattr(p, f) for p in parts]) for f in Result._fields[:10]]
    post = np.concatenate([p.posterior for p in parts]) if return_posterior else None
    tail = [np.concatenate([getattr(p, f) for p in parts]) for f in Result._fields[13:]]
    return Result(*cat, post, None, state, *tail)
