"""Viterbi MAP path of the grid chain (:mod:`vibrospeed.estimators.grid.smoother`'s model).

The path maximises the joint probability of the same hidden Markov chain the smoother
marginalises (banded random walk, jump, "no line" state; emissions the filter's per-point
log-likelihoods), in the log domain::

    delta_t(j) = l_t(j) + max_i [delta_{t-1}(i) + log T(i -> j)]

O(N B) per step: outside the band only the jump term remains, so the maximum over all sources
is the band's maximum, the jump from the best point, or "none -> line". The band is scanned
offset by offset over the whole grid (as the smoother's sums) with the same comparisons in the
same order per target as a per-point loop (``tests/test_scale_smoother.py``).

Checkpointed like the smoother: the recursion's state every ``checkpoint`` samples, back
pointers for the last segments only, the rest recomputed during the traceback.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.estimators.grid.config import Config
from vibrospeed.estimators.grid.smoother import (
    CHECKPOINT,
    KEEP_BYTES,
    _emissions,
    _segments,
    _setup,
)


class Path(NamedTuple):
    """Viterbi MAP path: ``state`` (n,) grid index (N for "no line"), ``omega`` (n,) rad/s
    (NaN in "no line"), ``log_joint`` of the path (emissions and transitions)."""

    state: np.ndarray
    omega: np.ndarray
    log_joint: float




@njit(cache=True)
def _viterbi_tables(kb, B, u, eps, p_off, p_on, has_null):
    """Log transition terms: ``lt`` (W, N), ``lt[d, j]`` for the target j from the source
    ``j + d - B`` in the band (-inf where it is off the grid), jump-in ``lju``, "none -> line"
    ``lon``, ``loff``, ``lstay0``."""
    N = u.size
    rw = 1.0 - eps - p_off
    W = kb.shape[1]
    lt = np.full((W, N), -np.inf)
    for j in range(N):
        for d in range(W):
            val = rw * kb[j, d] + eps * u[j]
            i = j + d - B
            if 0 <= i < N and val > 0.0:
                lt[d, j] = np.log(val)
    lju = np.full(N, -np.inf)
    lon = np.full(N, -np.inf)
    for j in range(N):
        if eps > 0.0:
            lju[j] = np.log(eps * u[j])
        if has_null:
            lon[j] = np.log(p_on * u[j])
    loff = np.log(p_off) if has_null else -np.inf
    lstay0 = np.log(1.0 - p_on) if has_null else -np.inf
    return lt, lju, lon, loff, lstay0


@njit(cache=True)
def _viterbi_range(gll, t0, t1, lw_init, delta, nd, back, B, has_null, lt, lju, lon, loff,
                   lstay0):
    """The Viterbi recursion for t in [t0, t1): ``delta`` (N+1) holds delta_{t0-1} on entry
    (ignored when t0 = 0: the start from ``lw_init``) and delta_{t1-1} on exit; the back
    pointers of t go to ``back[t - t0]``.

    Per target j the best source is the first maximum over the band's sources in increasing
    order, then the jump from the best point, then "no line"; the band is scanned offset by
    offset over all j at once (scores padded with B -inf on each side), the same comparisons
    in the same order per j."""
    N1 = gll.shape[1]
    N = N1 - 1
    W = lt.shape[0]
    dp = np.full(N + 2 * B, -np.inf)
    bv = np.empty(N)
    bi = np.empty(N, dtype=np.int32)
    start = t0
    if t0 == 0:
        for j in range(N1):
            delta[j] = lw_init[j] + gll[0, j] if (j < N or has_null) else -np.inf
            back[0, j] = j
        start = 1
    for t in range(start, t1):
        best = 0
        for i in range(N):
            if delta[i] > delta[best]:
                best = i
        for i in range(N):
            dp[B + i] = delta[i]
            bv[i] = -np.inf
            bi[i] = i
        for d in range(W):  # source i = j + d - B
            for j in range(N):
                val = dp[j + d] + lt[d, j]
                if val > bv[j]:
                    bv[j] = val
                    bi[j] = j + d - B
        db = delta[best]
        dn = delta[N]
        for j in range(N):
            val = db + lju[j]
            if val > bv[j]:
                bv[j] = val
                bi[j] = best
        if has_null:
            for j in range(N):
                val = dn + lon[j]
                if val > bv[j]:
                    bv[j] = val
                    bi[j] = N
        for j in range(N):
            nd[j] = bv[j] + gll[t, j]
            back[t - t0, j] = bi[j]
        if has_null:
            a = dn + lstay0
            b = db + loff
            if a >= b:
                nd[N] = a + gll[t, N]
                back[t - t0, N] = N
            else:
                nd[N] = b + gll[t, N]
                back[t - t0, N] = best
        else:
            nd[N] = -np.inf
            back[t - t0, N] = N
        for j in range(N1):
            delta[j] = nd[j]


@njit(cache=True)
def _trace(back, t0, t1, path):
    """path[t - 1] = back[t - t0, path[t]] for t = t1 - 1 down to max(t0, 1)."""
    for t in range(t1 - 1, max(t0, 1) - 1, -1):
        path[t - 1] = back[t - t0, path[t]]


def _tables(config: Config) -> tuple:
    """``(lw, grid, tabs)``: the prior log weights (N+1), the grid and the argument tuple of
    :func:`_viterbi_range` after its per-run arrays, built once per Config (kept with it)."""
    got = config.__dict__.get("_viterbi_chain")
    if got is None:
        lw, kb, B, grid, _, u, eps, p_off, p_on, _ = _setup(config)
        has_null = bool(config.has_null)
        tabs = (B, has_null, *_viterbi_tables(kb, B, u, eps, p_off, p_on, has_null))
        got = config.__dict__["_viterbi_chain"] = (lw, grid, tabs)
    return got


def viterbi(config: Config, grid_loglik: np.ndarray, *,
            checkpoint: int | None = CHECKPOINT, keep: int | None = None) -> Path:
    """Most probable state sequence of the grid chain (Viterbi, log domain, O(n N B)).

    Not what the grid tracker reports: with its tempered likelihood a single path pays the
    log of one kernel entry at every sample (the walk spreads each step over several grid
    points) and gains little from the data per sample, so the path stays in "no line" (which
    stays put) or, without that state, on a grid end (whose kernel rows hold fewer entries),
    while the smoothed marginal, which sums over the paths, follows the line. The tracker's
    ``omega_map`` is the smoothed posterior's MAP.

    Checkpointed like :func:`smooth`: the recursion's state (N+1 log scores) is kept every
    ``checkpoint`` samples, and the back pointers of the last segments that fit in ``keep``
    samples (default :data:`KEEP_BYTES` of int32); the traceback, from the last segment to
    the first, recomputes the other segments' back pointers from their checkpoints (bitwise
    the whole-log result, ``checkpoint=None``): back pointers for ``keep`` samples and one
    segment instead of (n, N+1) int32."""
    lw, grid, tabs = _tables(config)
    gll = _emissions(grid_loglik, grid.size)
    n, N1 = gll.shape
    K = n if checkpoint is None else int(checkpoint)
    if K < 1:
        raise ValueError(f"checkpoint must be at least 1 sample, got {checkpoint}")
    K = min(K, n)
    if checkpoint is None:
        R = n
    else:
        R = KEEP_BYTES // (4 * N1) if keep is None else max(0, int(keep))
    starts, s_keep, t_keep = _segments(n, K, R)  # back pointers of the last segments kept
    states = np.empty((s_keep, N1))
    delta, nd = np.empty(N1), np.empty(N1)
    back = np.empty((K if s_keep else 0, N1), dtype=np.int32)
    tail = np.empty((n - t_keep, N1), dtype=np.int32)
    for s in range(s_keep):  # forward: delta before each segment
        t0 = int(starts[s])
        states[s] = delta
        _viterbi_range(gll, t0, min(t0 + K, n), lw, delta, nd, back, *tabs)
    if t_keep < n:
        _viterbi_range(gll, t_keep, n, lw, delta, nd, tail, *tabs)
    path = np.empty(n, dtype=np.int64)
    k = 0
    for j in range(N1):
        if delta[j] > delta[k]:
            k = j
    lj = float(delta[k])
    path[n - 1] = k
    if t_keep < n:
        _trace(tail, t_keep, n, path)
    for s in range(s_keep - 1, -1, -1):  # traceback, segment by segment
        t0 = int(starts[s])
        t1 = min(t0 + K, n)
        delta[:] = states[s]
        _viterbi_range(gll, t0, t1, lw, delta, nd, back, *tabs)
        _trace(back, t0, t1, path)
    om = np.where(path < grid.size, grid[np.minimum(path, grid.size - 1)], np.nan)
    return Path(path, om, lj)
