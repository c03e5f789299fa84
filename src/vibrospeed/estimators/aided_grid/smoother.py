"""The aided grid smoother: forward-backward on the grid with the acceleration shift inside the
transition (``tracker=grid`` offline; package docstring, "Continuous aiding").

The grid product's smoother (:mod:`vibrospeed.estimators.grid.smoother`) runs the backward
recursion of the hidden Markov chain whose forward recursion is the RBPMF's weight update,
with the filter's per-point emissions ``l_t(j)`` kept as computed. With continuous aiding the
aided filter's transition from ``t`` to ``t + 1`` is the grid's transition ``T`` (random walk,
jumps, "no line" state) followed by the translation ``S_t`` of the line part by
``s_t = (T / (r dx)) sum_hop (u + b)`` cells at the last sample of each aiding hop (identity
elsewhere; :func:`vibrospeed.estimators.aided_grid.shift._shift`: point ``i`` to ``i + k``
with ``1 - f`` and to ``i + k + 1`` with ``f``, ``k = floor(s)``, ``f = s - k``, clamped to the
grid's ends; the "no line" state is not moved)::

    alpha_{t+1}(j) ∝ l_{t+1}(j) sum_i alpha_t(i) (T S_t)(i -> j)
    beta_t(i)      = sum_j (T S_t)(i -> j) l_{t+1}(j) beta_{t+1}(j)
                   = sum_m T(i -> m) sum_j S_t(m -> j) l_{t+1}(j) beta_{t+1}(j)

so the backward step first pulls ``e = l beta`` back through the shift,
``(S^T e)(m) = (1 - f) e(m + k) + f e(m + k + 1)`` (indices clamped as in the forward move),
and then takes the grid smoother's step (:func:`~vibrospeed.estimators.grid.smoother._backstep`)
on it. The smoothed posterior ``alpha_t beta_t`` uses the acceleration (through ``S``) and the
vibration (through ``l``) on both sides of ``t``. Where no hop ends (``s_t = 0``) the steps
are the grid smoother's own, so with ``u = 0`` the result is that of
:func:`vibrospeed.estimators.grid.smoother.smooth` on the same emissions.

The emissions are the aided filter's (the phasor filters travel with their mass under the
shift, so ``l_t(j)`` is the predictive density of the filter that the aiding moved to ``j``):
:func:`forward` runs the aided filter's forward pass in hop-long pieces of
:func:`vibrospeed.estimators.rbpmf.run` (``return_grid_loglik=True``), shifting the state at
each hop end, which gives the numbers of repeated :func:`vibrospeed.estimators.aided_grid.step`.
The same approximation as the grid smoother's (module docstring there): the emissions are
conditioned on the past only.

Scope: continuous aiding (or none), the standstill read from per-sample flags or absent, no
omega fixes, no standstill measurement on the grid (``omega_min > 0``): then every sample has
the same grid transition and the shift is the only time-varying part. Memory: about
``-m grid``'s. The forward pass keeps the emissions (one (n, N + 1) float32 array, 4 (N + 1)
bytes per sample) and its pieces' per-sample columns, no piece's filter state past the next
piece; :func:`smooth` is checkpointed as the grid smoother: the filtered probabilities of the
last ``grid.smoother.KEEP_BYTES`` (64 MiB) of the log and of one ``CHECKPOINT``-sample segment,
the others recomputed segment by segment from the emissions and the shifts (the aided filter
is not run again).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.aided_grid.config import Config
from vibrospeed.estimators.aided_grid.filter import _aid_sums
from vibrospeed.estimators.aided_grid.shift import _copy_grid, _resolve
from vibrospeed.estimators.grid import smoother as gsm
from vibrospeed.estimators.grid.filter import concat, posterior_slots
from vibrospeed.estimators.grid.summary import N_OUT_FIXED


class Forward(NamedTuple):
    """The aided filter's forward pass: ``filt`` the causal columns (an
    :class:`vibrospeed.estimators.rbpmf.Result` over the whole log, ``grid_loglik`` (n, N + 1)
    float32 the per-state emissions), ``shift`` (n,) cells moved after sample t's transition
    (0: no hop ends there), ``still`` (n,) bool the standing samples (add nothing to a hop)."""

    filt: rbpmf.Result
    shift: np.ndarray
    still: np.ndarray


def _check(config: Config) -> None:
    if config.aiding == "mode":
        raise ParameterError("the aided grid smoother needs aiding='continuous' or 'none' (the "
                             "mode detector's skipped updates and boosts are not a fixed "
                             "chain)")
    if config.standstill == "window":
        raise ParameterError("the aided grid smoother reads standstill flags "
                             "(standstill='broadband' or 'none')")
    if config.standstill == "broadband" and config.ss_on_grid:
        raise ParameterError("the aided grid smoother needs omega_min > 0 (a standstill "
                             "measurement on the grid changes the walk while standing)")


def forward(config: Config, y: np.ndarray, u: np.ndarray | None = None, *,
            still: np.ndarray | None = None,
            extra: tuple[np.ndarray, np.ndarray] | None = None) -> Forward:
    """The aided filter (continuous aiding) over ``y`` (n,), the RBPMF input (pre-filtered and
    scaled), with the longitudinal acceleration ``u`` (n,) m/s^2 (None or NaN: none), the
    standstill flags ``still`` (n,) (standing samples add nothing to the hop's sum) and the
    extra log-evidence ``extra = (idx, values)`` as :func:`vibrospeed.estimators.rbpmf.run`'s
    (the comb evidence; end-referred gives the causal filter, mid-frame what the smoother
    uses offline). The causal columns are those of repeated
    :func:`vibrospeed.estimators.aided_grid.step` with that evidence."""
    _check(config)
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = y.size
    u = np.full(n, np.nan) if u is None else np.ascontiguousarray(u, dtype=np.float64)
    if u.shape != (n,):
        raise InputError(f"aided_grid.smoother.forward: 'u' has shape {u.shape}, expected ({n},)")
    ss = np.zeros(n, np.bool_) if still is None else np.asarray(still, np.float64) > 0.5
    if ss.shape != (n,):
        raise InputError(f"aided_grid.smoother.forward: 'still' has shape {ss.shape}, "
                         f"expected ({n},)")
    shift = np.zeros(n)
    if config.aiding == "continuous":
        hop_end, total, _ = _aid_sums(config, u, ss, 0, 0.0)
        shift[hop_end] = (config.tracker.model.dt * total[hop_end]
                          / (config.wheel_radius * config.dx))
    ex_idx = np.zeros(0, np.int64) if extra is None else np.asarray(extra[0], np.int64)
    ex_val = None if extra is None else np.asarray(extra[1], np.float64)
    tracker = config.tracker
    g = rbpmf.init(tracker)
    ends = np.flatnonzero(shift != 0.0)
    cuts = np.concatenate([ends + 1, [n]]) if ends.size == 0 or ends[-1] != n - 1 else ends + 1
    # the pieces keep their per-sample columns only: the emissions go straight into one
    # (n, N + 1) array and each piece's final state (the phasor moments, ~80 kB at N = 200)
    # is dropped once the next piece starts from it
    parts = []
    gll = None
    k = 0
    for e in cuts:
        e = int(e)
        if e <= k:
            continue
        lo, hi = np.searchsorted(ex_idx, (k, e))  # the frames of this piece (increasing)
        ex = (ex_idx[lo:hi] - k, ex_val[lo:hi]) if hi > lo else None
        res = rbpmf.run(tracker, y[k:e], g, extra=ex, return_grid_loglik=True)
        if gll is None:
            gll = np.empty((n, res.grid_loglik.shape[1]), dtype=res.grid_loglik.dtype)
        gll[k:e] = res.grid_loglik
        parts.append(res._replace(final=None, grid_loglik=None))
        g = res.final
        del res
        if shift[e - 1] != 0.0:
            g = _copy_grid(g)
            _resolve(config, g, shift[e - 1] * config.dx)
        k = e
    filt = concat(parts)
    if parts:
        filt = filt._replace(final=g, grid_loglik=gll)
    return Forward(filt, shift, ss)


@njit(cache=True)
def _forward_shifted(gll, shift, lw_init, kf, B, u, eps, p_off, p_on, has_null, log_floor):
    """Filtered probabilities alpha (n, N+1) float32 of the whole log
    (:func:`vibrospeed.estimators.grid.smoother._forward_shifted_range` from ``lw_init``)."""
    n_s, N1 = gll.shape
    alpha = np.empty((n_s, N1), dtype=np.float32)
    gsm._forward_shifted_range(gll, shift, 0, n_s, lw_init.copy(), kf, B, u, eps, p_off, p_on,
                               has_null, log_floor, alpha, np.empty(N1), np.empty(N1))
    return alpha


def filtered(config: Config, fw: Forward) -> np.ndarray:
    """(n, N+1) filtered probabilities recomputed from the emissions and the shifts (the
    aided filter's weights, to float32 rounding)."""
    lw, fwd, _ = gsm._chain(config.tracker)
    gll = gsm._emissions(fw.filt.grid_loglik, config.tracker.n_grid)
    return _forward_shifted(gll, np.ascontiguousarray(fw.shift, np.float64), lw, *fwd)


def smooth(config: Config, fw: Forward, *, return_posterior: bool | np.ndarray = False,
           checkpoint: int | None = gsm.CHECKPOINT, keep: int | None = None) -> gsm.Smoothed:
    """Forward-backward marginals ``p(omega_t | y_1..n, u_1..n)`` of the aided chain from the
    forward pass ``fw`` (:func:`forward`); columns as
    :func:`vibrospeed.estimators.grid.smoother.smooth` (summaries of ``config.tracker``), the
    posterior rows at every sample (``return_posterior=True``) or at the increasing sample
    indices given (:func:`vibrospeed.estimators.grid.filter.posterior_slots`).

    Checkpointed as the grid smoother: the forward HMM recursion over the stored emissions and
    shifts keeps its state (N+1 log weights) every ``checkpoint`` samples, and the filtered
    probabilities of the last segments that fit in ``keep`` samples (default
    :data:`vibrospeed.estimators.grid.smoother.KEEP_BYTES` of float32); the backward pass,
    from the last segment to the first, recomputes the other segments' filtered probabilities
    from their checkpoints (the same operations: bitwise the whole-log result,
    ``checkpoint=None``). The aided filter that made the emissions is not run again. Memory
    for alpha: ``keep`` rows and one segment instead of (n, N+1) float32; time: the HMM
    recursion once over the kept samples, twice over the rest."""
    _check(config)
    lw, fwd, common = gsm._chain(config.tracker)
    N = common[2].size
    gll = gsm._emissions(fw.filt.grid_loglik, N)
    n, N1 = gll.shape
    shift = np.ascontiguousarray(fw.shift, dtype=np.float64)
    if shift.shape != (n,):
        raise InputError(f"aided_grid.smoother.smooth: shift has shape {shift.shape}, "
                         f"expected ({n},)")
    outs = np.zeros((n, N_OUT_FIXED))
    slot = posterior_slots(n, return_posterior)
    posts = np.zeros((int(slot.max()) + 1 if slot.size else 0, N), dtype=np.float32)
    result = posts if slot.size else None
    beta = np.ones(N1)
    if checkpoint is None or checkpoint >= n:
        alpha = _forward_shifted(gll, shift, lw, *fwd)
        gsm._smooth_shifted_range(alpha, 0, gll, shift, n - 1, 0, n, beta, *common, outs, posts,
                              slot)
        return gsm._result(outs, result)
    K = int(checkpoint)
    if K < 1:
        raise ParameterError(f"checkpoint must be at least 1 sample, got {checkpoint}")
    R = gsm.KEEP_BYTES // (4 * N1) if keep is None else max(0, int(keep))
    starts, s_keep, t_keep = gsm._segments(n, K, R)  # alpha of the last segments kept
    states = np.empty((s_keep, N1))
    a, pr = np.empty(N1), np.empty(N1)
    none = np.empty((0, N1), dtype=np.float32)
    lw = lw.copy()
    for s in range(s_keep):  # forward: the state before each segment
        t0 = int(starts[s])
        states[s] = lw
        gsm._forward_shifted_range(gll, shift, t0, min(t0 + K, n), lw, *fwd, none, a, pr)
    if t_keep < n:
        tail = np.empty((n - t_keep, N1), dtype=np.float32)
        gsm._forward_shifted_range(gll, shift, t_keep, n, lw, *fwd, tail, a, pr)
        gsm._smooth_shifted_range(tail, t_keep, gll, shift, n - 1, t_keep, n, beta, *common, outs,
                              posts, slot)
        del tail
    alpha = np.empty((K if s_keep else 0, N1), dtype=np.float32)
    for s in range(s_keep - 1, -1, -1):  # backward, segment by segment
        t0 = int(starts[s])
        t1 = min(t0 + K, n)
        lw = states[s].copy()
        gsm._forward_shifted_range(gll, shift, t0, t1, lw, *fwd, alpha, a, pr)
        # from beta_{t1} (the next segment's first sample; at the end of the log beta = 1)
        gsm._smooth_shifted_range(alpha, t0, gll, shift, min(t1, n - 1), t0, t1, beta, *common,
                              outs, posts, slot)
    return gsm._result(outs, result)
