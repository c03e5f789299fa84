"""Offline and fixed-lag smoothing on the RBPMF grid: forward-backward
marginals and credible bands of omega (the Viterbi MAP path of the same chain:
:mod:`vibrospeed.estimators.grid.viterbi`).

Model actually smoothed
-----------------------
The RBPMF (:mod:`vibrospeed.estimators.rbpmf`) replaces, at every step, the mixture over omega
histories of each grid point's Kalman filter by one moment-matched Gaussian (paper III-D, the
merge of Algorithm 1). Its weights therefore follow *exactly* the forward recursion of a hidden
Markov chain on the grid (plus the optional "no line" state)::

    alpha_t(j) ∝ l_t(j) sum_i alpha_{t-1}(i) T(i -> j),    l_t(j) = N(y_t; h m_j, h P_j h' + r)

with the emission ``l_t(j) = p(y_t | omega_t = j, y_1..t-1)`` the grid point's predictive
density from the merged linear-state moments. The smoother runs the *backward* recursion of
that same chain::

    beta_t(i) = sum_j T(i -> j) l_{t+1}(j) beta_{t+1}(j)
    p(omega_t = j | y_1..T) ∝ alpha_t(j) beta_t(j)

i.e. the emissions are kept as the filter computed them (conditioned on the past only, not
re-conditioned on the future). Justification: (a) for a fixed omega path the linear states
are exactly Gaussian and ``prod_t l_t`` is then the exact ``p(y_1..T | omega_1..T)``; the only
approximation is the one the filter already makes (collapsing the path dependence into the
moments at the current grid point, a good approximation when neighbouring grid points carry
similar phasors, which the kernel's width ~ one grid spacing ensures); (b) with it, the forward
pass here reproduces the filter's weights to float32 rounding (tested), so filter and smoother
are two views of one model and the smoother's bands are consistent with the filter's; (c) a
two-filter / backward-information treatment of the 2M linear states would need a backward
Kalman filter per grid point and pairwise merges, i.e. the N^2 work the RBPMF avoids. The
per-point emissions are the filter's by-product (``rbpmf.run(..., return_grid_loglik=True)``),
stored as float32: memory 4 (N + 1) bytes per sample.

The transition ``T`` is the filter's: banded random walk ``K`` with probability
``1 - eps - p_off``, a jump to anywhere (weights ``u_j`` proportional to the cell widths) with
``eps``, "line -> none" ``p_off``, "none -> line" ``p_on`` (rbpmf.Config.rates).

Computation: every band sum (the transition forward and backward) runs
offset by offset over the whole grid (:func:`band_tables`: the kernel by offset, the grid index
innermost, the vector padded with B zeros or -inf on each side), so that the loops over grid
points compile to SIMD while each point's terms are taken in the order of a per-point loop:
the numbers are those of the per-point loops (``tests/test_scale_smoother.py``). What is left
per sample is mostly the exp and log of each state's weight (about 4 us at N = 200).

Fixed lag: blocks of ``L = lag / T`` samples; at the end of block b+1 the backward recursion
runs from there (``beta = 1``) down to the start of block b, so each sample of block b uses the
data up to ``L..2L`` samples after it (output delay <= 2 lag, work 2x the backward pass).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

import vibrospeed.estimators.grid.summary as cols
from vibrospeed.estimators.grid.config import Config
from vibrospeed.estimators.grid.filter import init, posterior_slots

# _summary is compiled into _emit (numba's cache keys on this file: see core.py; last change
# of summary.py: the band widened to hold the reported mode)
from vibrospeed.estimators.grid.summary import COL_LOGLIK, N_OUT_FIXED, _summary


class Smoothed(NamedTuple):
    """Smoothed posterior per sample (n,): mean, std, band of the mixture (the "no line" mass
    spread uniformly on the grid), MAP of the marginal, ``p_null``, ``p_half``, ``p_double``;
    ``posterior`` (n, N) float32 of the grid part when asked for."""

    omega: np.ndarray
    omega_std: np.ndarray
    omega_map: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    p_null: np.ndarray
    p_half: np.ndarray
    p_double: np.ndarray
    posterior: np.ndarray | None
    p_third: np.ndarray | None = None
    p_triple: np.ndarray | None = None
    omega_mode: np.ndarray | None = None  # mean of the highest-mass window (the mode)
    p_mode: np.ndarray | None = None  # the basin's share of the signal mass
    omega_mode_std: np.ndarray | None = None  # spread within the basin about omega_mode


def _setup(config: Config):
    k = config.kern
    st = init(config)
    lw = np.append(st.log_w, st.log_w_null)
    eps, p_off, p_on, _ = config.rates()
    u = k.widths / np.sum(k.widths)
    q = 0.5 * (1.0 - config.level)
    return lw, k.kb, int(k.B), k.grid, k.edges, u, eps, p_off, p_on, q


def band_tables(kb: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
    """The band kernel by offset, grid index innermost, for loops that run over the grid.

    ``kb[j, d]`` (N, W = 2B + 1) is ``K(i -> j)`` for the source ``i = j + d - B``. Returns
    ``kf`` (W, N), ``kf[d, j] = K(j + d - B -> j)`` (the sources of target j in increasing
    order: the forward sum), and ``kr`` (W, N), ``kr[d, i] = K(i -> i + d - B)`` (the targets of
    source i in increasing order: the backward sum); 0 where that grid point does not exist.
    With the vector padded by B zeros on each side, a sum over the band is then
    ``s[j] += x[j + d] k[d, j]`` for d = 0..W-1: the terms of each point in the order of the
    per-point loop (the added zeros change no bit), in a loop over j that compiles to SIMD."""
    kb = np.asarray(kb, dtype=np.float64)
    N, W = kb.shape
    kf = np.zeros((W, N))
    kr = np.zeros((W, N))
    j = np.arange(N)
    for d in range(W):
        src = j + d - B  # forward: source of target j
        ok = (src >= 0) & (src < N)
        kf[d, ok] = kb[j[ok], d]
        tgt = j + d - B  # backward: target of source j, K(j -> tgt) = kb[tgt, j - tgt + B]
        ok = (tgt >= 0) & (tgt < N)
        kr[d, ok] = kb[tgt[ok], 2 * B - d]
    return kf, kr


def _chain(config: Config) -> tuple:
    """``(lw, fwd, common)``: the prior log weights (N+1) and the argument tuples of
    :func:`_forward_range` and :func:`_smooth_range` after their per-run arrays, built once per
    Config (kept with it)."""
    got = config.__dict__.get("_smoother_chain")
    if got is None:
        lw, kb, B, grid, edges, u, eps, p_off, p_on, q = _setup(config)
        kf, kr = band_tables(kb, B)
        has_null = bool(config.has_null)
        fwd = (kf, B, u, eps, p_off, p_on, has_null, float(config.log_floor))
        common = (kr, B, grid, edges, u, eps, p_off, p_on, has_null, q, 1.0 - q,
                  float(config.amb_rel), float(config.amb_abs))
        got = config.__dict__["_smoother_chain"] = (lw, fwd, common)
    return got


@njit(cache=True)
def _predict(a, kf, B, u, eps, p_off, p_on, has_null, ap, s, out):
    """out = a T (one transition of the probability vector a (N+1,)); ``ap`` (N + 2B) holds
    zeros in its first and last B entries, ``s`` (N): scratch."""
    N = u.size
    W = kf.shape[0]
    a0 = a[N] if has_null else 0.0
    rw = 1.0 - eps - p_off
    J = eps * (1.0 - a0) + p_on * a0
    for i in range(N):
        ap[B + i] = a[i]
        s[i] = 0.0
    for d in range(W):  # s[j] = sum_i a[i] K(i -> j), sources i = j + d - B in order
        for j in range(N):
            s[j] += ap[j + d] * kf[d, j]
    for j in range(N):
        out[j] = rw * s[j] + J * u[j]
    out[N] = p_off * (1.0 - a0) + (1.0 - p_on) * a0 if has_null else 0.0


@njit(cache=True)
def _translate(p, N, s, out):
    """``out[:N] = S p[:N]``: the line part moved by ``s`` cells (point ``i`` to ``i + k`` with
    ``1 - f`` and to ``i + k + 1`` with ``f``, ``k = floor(s)``, ``f = s - k``, clamped to the
    grid's ends; the aided tracker's shift, :mod:`vibrospeed.estimators.aided_grid.shift`)."""
    k = int(np.floor(s))
    f = s - k
    for j in range(N):
        out[j] = 0.0
    for i in range(N):
        if p[i] == 0.0:
            continue
        for part in range(2):
            a = (1.0 - f) if part == 0 else f
            if a == 0.0:
                continue
            j = i + k + part
            if j < 0:
                j = 0
            elif j > N - 1:
                j = N - 1
            out[j] += p[i] * a


@njit(cache=True)
def _translate_back(e, N, s, out):
    """``out[:N] = S^T e[:N]``: ``out(m) = (1 - f) e(m + k) + f e(m + k + 1)`` (clamped)."""
    k = int(np.floor(s))
    f = s - k
    for m in range(N):
        acc = 0.0
        for part in range(2):
            a = (1.0 - f) if part == 0 else f
            if a == 0.0:
                continue
            j = m + k + part
            if j < 0:
                j = 0
            elif j > N - 1:
                j = N - 1
            acc += a * e[j]
        out[m] = acc


@njit(cache=True)
def _forward_range(gll, t0, t1, lw, kf, B, u, eps, p_off, p_on, has_null, log_floor, alpha, a,
                   pr):
    """The forward recursion for t in [t0, t1): ``lw`` (N+1, the log predicted weights before
    t0) is advanced in place; filtered probabilities of t go to ``alpha[t - t0]`` (float32)
    when ``alpha`` has rows (none: the state alone is carried). ``a``, ``pr``: scratch."""
    _forward_shifted_range(gll, np.zeros(0), t0, t1, lw, kf, B, u, eps, p_off, p_on, has_null,
                           log_floor, alpha, a, pr)


@njit(cache=True)
def _forward_shifted_range(gll, shift, t0, t1, lw, kf, B, u, eps, p_off, p_on, has_null,
                           log_floor, alpha, a, pr):
    """:func:`_forward_range` with the line part of the prediction moved by ``shift[t]`` cells
    after sample t (:func:`_translate`; ``shift`` empty: none), the chain of the aided grid
    smoother (:mod:`vibrospeed.estimators.aided_grid.smoother`)."""
    N1 = gll.shape[1]
    N = N1 - 1
    keep = alpha.shape[0] > 0
    moves = shift.size > 0
    ps = np.empty(N1)
    ap = np.zeros(N + 2 * B)
    s = np.empty(N)
    for t in range(t0, t1):
        mx = -np.inf
        for j in range(N):
            lw[j] += gll[t, j]
            if lw[j] > mx:
                mx = lw[j]
        if has_null:
            lw[N] += gll[t, N]
            if lw[N] > mx:
                mx = lw[N]
        tot = 0.0
        for j in range(N1):
            if j == N and not has_null:
                a[j] = 0.0
                continue
            d = lw[j] - mx
            if d < -log_floor:
                d = -log_floor
            a[j] = np.exp(d)
            tot += a[j]
        for j in range(N1):
            a[j] /= tot
        # stored as float32: floored at 1e-37 (the smallest normal float32 is 1.2e-38) so
        # that alpha * beta cannot vanish on every state when strong evidence disagrees
        if keep:
            for j in range(N):
                alpha[t - t0, j] = max(a[j], 1e-37)
            alpha[t - t0, N] = max(a[N], 1e-37) if has_null else 0.0
        _predict(a, kf, B, u, eps, p_off, p_on, has_null, ap, s, pr)
        if moves and shift[t] != 0.0:
            _translate(pr, N, shift[t], ps)
            for j in range(N):
                pr[j] = ps[j]
        for j in range(N1):
            lw[j] = np.log(pr[j]) if pr[j] > 0.0 else -np.inf


@njit(cache=True)
def _forward(gll, lw_init, kf, B, u, eps, p_off, p_on, has_null, log_floor):
    """Filtered probabilities alpha (n, N+1) float32, exactly the RBPMF's weight recursion."""
    n_s, N1 = gll.shape
    alpha = np.empty((n_s, N1), dtype=np.float32)
    _forward_range(gll, 0, n_s, lw_init.copy(), kf, B, u, eps, p_off, p_on, has_null,
                   log_floor, alpha, np.empty(N1), np.empty(N1))
    return alpha


@njit(cache=True)
def _backstep(beta, gll_next, kr, B, u, eps, p_off, p_on, has_null, e, ep, s, out):
    """out(i) = sum_j T(i -> j) l_{t+1}(j) beta_{t+1}(j), normalised to max 1. ``ep``
    (N + 2B) holds zeros in its first and last B entries, ``e`` (N+1), ``s`` (N): scratch."""
    N = u.size
    W = kr.shape[0]
    mx = -np.inf
    for j in range(N + 1):
        if (j < N or has_null) and gll_next[j] > mx:
            mx = gll_next[j]
    ue = 0.0
    for j in range(N):
        e[j] = np.exp(gll_next[j] - mx) * beta[j]
        ue += u[j] * e[j]
    e[N] = np.exp(gll_next[N] - mx) * beta[N] if has_null else 0.0
    rw = 1.0 - eps - p_off
    for j in range(N):
        ep[B + j] = e[j]
        s[j] = 0.0
    for d in range(W):  # s[i] = sum_j K(i -> j) e[j], targets j = i + d - B in order
        for i in range(N):
            s[i] += kr[d, i] * ep[i + d]
    jump = eps * ue
    off = p_off * e[N]
    top = 0.0
    for i in range(N):
        out[i] = rw * s[i] + jump + off
        if out[i] > top:
            top = out[i]
    out[N] = (1.0 - p_on) * e[N] + p_on * ue if has_null else 0.0
    if out[N] > top:
        top = out[N]
    if top > 0.0:
        for i in range(N + 1):
            out[i] /= top


@njit(cache=True)
def _emit(alpha_t, beta, g, grid, edges, u, q_lo, q_hi, amb_rel, amb_abs, v, row, post_row,
          cur):
    N = grid.size
    s = 0.0
    for j in range(N + 1):
        g[j] = alpha_t[j] * beta[j]
        s += g[j]
    if not s > 0.0:  # pragma: no cover - guarded by the alpha floor
        s = 0.0
        for j in range(N + 1):
            g[j] = alpha_t[j]
            s += g[j]
    for j in range(N + 1):
        g[j] /= s
    # hold 1: the stateless mode (no hysteresis); cur is only written
    jmap = _summary(g[:N], g[N], u, grid, edges, q_lo, q_hi, amb_rel, amb_abs, v, row, 1.0, cur)
    row[COL_LOGLIK] = 0.0
    if post_row.size == N:
        for j in range(N):
            post_row[j] = g[j]
    return jmap


@njit(cache=True)
def _smooth_range(alpha, a0, gll, t_end, t_lo, t_hi, beta, kr, B, grid, edges, u, eps, p_off,
                  p_on, has_null, q_lo, q_hi, amb_rel, amb_abs, outs, posts, slot):
    """Backward from t_end down to t_lo, ``beta`` (N+1) holding beta_{t_end} on entry and
    beta_{t_lo} on exit; outputs for t in [t_lo, t_hi) from ``alpha[t - a0]``, the posterior of
    sample t into ``posts[slot[t]]`` where that is >= 0 (``slot`` empty: none)."""
    _smooth_shifted_range(alpha, a0, gll, np.zeros(0), t_end, t_lo, t_hi, beta, kr, B, grid,
                          edges, u, eps, p_off, p_on, has_null, q_lo, q_hi, amb_rel, amb_abs,
                          outs, posts, slot)


@njit(cache=True)
def _smooth_shifted_range(alpha, a0, gll, shift, t_end, t_lo, t_hi, beta, kr, B, grid, edges,
                          u, eps, p_off, p_on, has_null, q_lo, q_hi, amb_rel, amb_abs, outs,
                          posts, slot):
    """:func:`_smooth_range` of the chain of :func:`_forward_shifted_range`: where
    ``shift[t]`` is not 0, ``e = l_{t+1} beta_{t+1}`` is pulled back through the shift
    (:func:`_translate_back`) before the step, ``beta_t = T (S_t^T e)`` (``shift`` empty:
    none)."""
    N = grid.size
    moves = shift.size > 0
    nb = np.empty(N + 1)
    e = np.empty(N + 1)
    es = np.empty(N + 1)
    zero = np.zeros(N + 1)
    ep = np.zeros(N + 2 * B)
    s = np.empty(N)
    g = np.empty(N + 1)
    v = np.empty(N)
    empty = np.empty(0, dtype=np.float32)
    cur = np.full(1, -1, np.int64)
    for t in range(t_end, t_lo - 1, -1):
        if t < t_end:
            if not moves or shift[t] == 0.0:
                _backstep(beta, gll[t + 1], kr, B, u, eps, p_off, p_on, has_null, e, ep, s, nb)
            else:
                mx = -np.inf
                for j in range(N + 1):
                    if (j < N or has_null) and gll[t + 1, j] > mx:
                        mx = gll[t + 1, j]
                for j in range(N + 1):
                    e[j] = np.exp(gll[t + 1, j] - mx) * beta[j] if (j < N or has_null) \
                        else 0.0
                _translate_back(e, N, shift[t], es)
                es[N] = e[N]
                _backstep(es, zero, kr, B, u, eps, p_off, p_on, has_null, e, ep, s, nb)
            for j in range(N + 1):
                beta[j] = nb[j]
        if t < t_hi:
            pr = posts[slot[t]] if slot.size > 0 and slot[t] >= 0 else empty
            _emit(alpha[t - a0], beta, g, grid, edges, u, q_lo, q_hi, amb_rel, amb_abs, v,
                  outs[t], pr, cur)


def _result(outs: np.ndarray, posts: np.ndarray | None) -> Smoothed:
    c = cols
    return Smoothed(*(outs[:, i] for i in (c.COL_MEAN, c.COL_STD, c.COL_MAP, c.COL_LO,
                                           c.COL_HI, c.COL_P_NULL, c.COL_P_HALF,
                                           c.COL_P_DOUBLE)),
                    posts, *(outs[:, i] for i in (c.COL_P_THIRD, c.COL_P_TRIPLE, c.COL_MODE,
                                                  c.COL_P_MODE, c.COL_MODE_STD)))


def _emissions(gll: np.ndarray, N: int) -> np.ndarray:
    """The emissions as given (the filter's float32; float32 -> float64 is exact in the
    kernels, so no float64 copy of the (n, N+1) array is made), C-contiguous."""
    gll = np.asarray(gll)
    if gll.dtype not in (np.float32, np.float64):
        gll = gll.astype(np.float64)
    gll = np.ascontiguousarray(gll)
    if gll.ndim != 2 or gll.shape[1] != N + 1:
        raise ValueError(f"grid_loglik must be (n, {N + 1}), got {gll.shape}")
    return gll


def _prep(config, gll, return_posterior):
    """Chain tables, emissions, output rows, the posterior rows and their slots
    (:func:`vibrospeed.estimators.grid.filter.posterior_slots`)."""
    lw, fwd, common = _chain(config)
    N = common[2].size
    gll = _emissions(gll, N)
    n = gll.shape[0]
    outs = np.zeros((n, N_OUT_FIXED))
    slot = posterior_slots(n, return_posterior)
    n_post = int(slot.max()) + 1 if slot.size else 0
    posts = np.zeros((n_post, N), dtype=np.float32)
    return lw.copy(), gll, outs, posts, slot, fwd, common


def filtered(config: Config, grid_loglik: np.ndarray) -> np.ndarray:
    """(n, N+1) filtered probabilities recomputed from the emissions (the RBPMF's weights)."""
    lw, fwd, common = _chain(config)
    return _forward(_emissions(grid_loglik, common[2].size), lw, *fwd)


#: Samples between the forward states the smoother keeps (:func:`smooth`).
CHECKPOINT = 4096
#: Bytes of filtered probabilities (float32) that :func:`smooth`'s first forward pass keeps
#: for the last segments, so that the backward pass does not compute those again, and of
#: back pointers (int32) that the Viterbi path (:mod:`~vibrospeed.estimators.grid.viterbi`)
#: keeps for its traceback: 64 MiB each (one at a time), about 83 000 samples at N = 200 (the
#: whole of a 10 min log at 100 Hz; a block of the streaming path keeps its 600 s the same
#: way).
KEEP_BYTES = 64 * 2**20


def _segments(n: int, K: int, R: int) -> tuple[np.ndarray, int, int]:
    """A checkpointed pass over ``n`` samples: ``(starts, s_keep, t_keep)``, the segments'
    first samples every ``K``; the segments from ``s_keep`` on (samples ``t_keep..n``) fit in
    ``R`` rows, so the first pass keeps their rows and the second does not recompute them."""
    starts = np.arange(0, n, K)
    s_keep = starts.size
    while s_keep > 0 and n - starts[s_keep - 1] <= R:
        s_keep -= 1
    return starts, s_keep, int(starts[s_keep]) if s_keep < starts.size else n


def smooth(config: Config, grid_loglik: np.ndarray, *,
           return_posterior: bool | np.ndarray = False, checkpoint: int | None = CHECKPOINT,
           keep: int | None = None) -> Smoothed:
    """Forward-backward marginals ``p(omega_t | y_1..T)`` for the whole log.

    ``grid_loglik`` : (n, N+1) from ``rbpmf.run(config, y, return_grid_loglik=True)``.
    ``return_posterior`` : the posterior rows at every sample (True) or at the increasing
    sample indices given (:func:`vibrospeed.estimators.grid.filter.posterior_slots`).

    Checkpointed: the forward pass keeps its state (N+1 log weights) every ``checkpoint``
    samples, and the filtered probabilities of the last segments that fit in ``keep`` samples
    (default :data:`KEEP_BYTES` of float32); the backward pass, from the last segment to the
    first, recomputes the other segments' filtered probabilities from their checkpoints (the
    same operations, so the result is bitwise that of the whole-log pass,
    ``checkpoint=None``). Memory for alpha: ``keep`` rows and one segment (``checkpoint`` x
    (N+1) float32) instead of the whole log; time: the forward pass once over the kept
    samples, twice over the rest.
    """
    lw, gll, outs, posts, slot, fwd, c = _prep(config, grid_loglik, return_posterior)
    n, N1 = gll.shape
    beta = np.ones(N1)
    if checkpoint is None or checkpoint >= n:
        alpha = _forward(gll, lw, *fwd)
        _smooth_range(alpha, 0, gll, n - 1, 0, n, beta, *c, outs, posts, slot)
        return _result(outs, posts if slot.size else None)
    K = int(checkpoint)
    if K < 1:
        raise ValueError(f"checkpoint must be at least 1 sample, got {checkpoint}")
    R = KEEP_BYTES // (4 * N1) if keep is None else max(0, int(keep))
    starts, s_keep, t_keep = _segments(n, K, R)  # alpha of the last segments kept
    tail = np.empty((n - t_keep, N1), dtype=np.float32)
    states = np.empty((s_keep, N1))
    a, pr = np.empty(N1), np.empty(N1)
    none = np.empty((0, N1), dtype=np.float32)
    lw = lw.copy()
    for s in range(s_keep):  # forward: the state before each segment
        t0 = int(starts[s])
        states[s] = lw
        _forward_range(gll, t0, min(t0 + K, n), lw, *fwd, none, a, pr)
    if t_keep < n:
        _forward_range(gll, t_keep, n, lw, *fwd, tail, a, pr)
        _smooth_range(tail, t_keep, gll, n - 1, t_keep, n, beta, *c, outs, posts, slot)
    alpha = np.empty((min(K, n), N1), dtype=np.float32)
    for s in range(s_keep - 1, -1, -1):  # backward, segment by segment
        t0 = int(starts[s])
        t1 = min(t0 + K, n)
        lw = states[s].copy()
        _forward_range(gll, t0, t1, lw, *fwd, alpha, a, pr)
        # from beta_{t1} (the next segment's first sample; at the end of the log beta = 1)
        _smooth_range(alpha, t0, gll, min(t1, n - 1), t0, t1, beta, *c, outs, posts, slot)
    return _result(outs, posts if slot.size else None)


def fixed_lag(config: Config, grid_loglik: np.ndarray, *, lag: float = 2.0,
              return_posterior: bool | np.ndarray = False) -> Smoothed:
    """Fixed-lag smoother: each sample uses the data up to ``lag..2 lag`` s after it (blocks of
    ``lag`` s; an online device emits block b at the end of block b+1). Uses only data a
    device has at that time, computed here from the stored emissions; the filtered
    probabilities are kept for one block at a time."""
    lw, gll, outs, posts, slot, fwd, c = _prep(config, grid_loglik, return_posterior)
    n, N1 = gll.shape
    L = max(1, int(round(lag / config.model.dt)))
    a, pr = np.empty(N1), np.empty(N1)
    lw = lw.copy()
    alpha = np.empty((min(L, n), N1), dtype=np.float32)
    for s0 in range(0, n, L):
        s1 = min(s0 + L, n)
        _forward_range(gll, s0, s1, lw, *fwd, alpha, a, pr)
        t_end = min(s0 + 2 * L, n) - 1
        _smooth_range(alpha, s0, gll, t_end, s0, s1, np.ones(N1), *c, outs, posts, slot)
    return _result(outs, posts if slot.size else None)
