"""The aided grid tracker as a filter: :class:`State`, :func:`init`, :func:`step`, :func:`run`.
Per sample the detectors decide (standstill, acceleration mode, boost; continuous aiding sums
``u`` over a hop), the omega measurements multiply the grid weights, the RBPMF step runs
(:func:`vibrospeed.estimators.rbpmf.step`, with the comb evidence of a frame ending there) and
the posterior is shifted (:mod:`vibrospeed.estimators.aided_grid.shift`).

Conventions as in the RBPMF: the stored state is the prior for the next sample, ``step``
returns the posterior at ``t_k``; ``run`` gives exactly the numbers of repeated ``step``
(vibration-only stretches are passed to :func:`rbpmf.run`, which equals repeated
:func:`rbpmf.step`). Only the RBPMF's public API is used (``Config``, ``State``, ``init``,
``step``, ``run``, ``Config.grid``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vibrospeed.config import check_state
from vibrospeed.errors import InputError
from vibrospeed.estimators import grid as gridmod
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.aided_grid.config import Config
from vibrospeed.estimators.aided_grid.shift import _copy_grid, _move, _resolve
from vibrospeed.estimators.aiding import Sample, input_arrays
from vibrospeed.signal import detectors as det
from vibrospeed.signal.detectors import _mode_core, _window_core
from vibrospeed.types import Estimate


class State(NamedTuple):
    """Prior for the next sample: ``grid`` (RBPMF state), ``offset`` (rad/s, sub-cell shift not
    yet applied to the grid), detector states ``window`` and ``mode``; with comb evidence the
    last ``comb.frame_len`` RBPMF inputs ``buf`` (ring buffer, oldest at ``count % L``) and the
    number ``count`` of samples seen; ``usum`` (m/s^2 x samples) the sum of ``u + accel_bias`` in
    the current aiding hop (``aiding='continuous'``)."""

    grid: rbpmf.State
    offset: float
    window: det.WindowState
    mode: det.ModeState
    buf: np.ndarray | None = None
    count: int = 0
    usum: float = 0.0


class _Posterior(NamedTuple):
    """Posterior at one sample (rad/s); band = the tracker's credible interval (the first six
    fields are the run's columns in this order)."""

    omega: float
    omega_std: float
    omega_map: float
    omega_lo: float
    omega_hi: float
    p_null: float
    standstill: bool
    accelerating: bool
    boost: bool
    ubar: float
    amplitudes: np.ndarray


def init(config: Config) -> State:
    """RBPMF prior of the tracker config (uniform over the grid unless its ``omega0`` is set),
    no offset, empty detectors (and an empty comb frame buffer)."""
    buf = None if config.comb is None else np.zeros(config.comb.frame_len)
    return State(rbpmf.init(config.tracker), 0.0, det.window_init(config.ss_len),
                 det.mode_init(config.mode_len), buf, 0)


def _check_state(config: Config, state: State) -> None:
    """A state made for other detector windows (or another comb frame) ran silently with
    them: the detectors take their lengths from the state. (The grid state is checked by the
    RBPMF.)"""
    check_state("aided_grid", "windows and comb frame",
                window=(state.window.buf, (config.ss_len,)),
                mode=(state.mode.buf, (config.mode_len,)),
                comb=(state.buf, None if config.comb is None else (config.comb.frame_len,)))


def _push(buf: np.ndarray, count: int, y: np.ndarray) -> np.ndarray:
    """Ring buffer ``buf`` (oldest at ``count % L``) after appending ``y``."""
    L = buf.size
    out = buf.copy()
    if y.size >= L:
        pos = (count + y.size - L + np.arange(L)) % L
        out[pos] = y[-L:]
    else:
        out[(count + np.arange(y.size)) % L] = y
    return out


def _decide(config: Config, window: det.WindowState, mode: det.ModeState, y: float,
            u: float, still: float = np.nan) -> tuple[bool, bool, bool, float]:
    """Detectors in place -> (standstill, accelerating, boost, ubar)."""
    acc, boost, ubar = _mode_core(mode.buf, mode.pos_count, mode.flag, u, config.mode_mu)
    if config.aiding != "mode":
        acc = boost = False
    if config.standstill == "broadband":
        ss = bool(still > 0.5)
        return ss, bool(acc) and not ss, bool(boost) and not ss, float(ubar)
    ss = False
    if config.standstill == "window":
        ss = bool(_window_core(window.buf, window.pos_count, window.flag, y, config.ss_mu))
    return ss and not acc, bool(acc), bool(boost), float(ubar)


def _aid_sums(config: Config, u: np.ndarray, ss: np.ndarray, count: int,
              usum: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Continuous aiding over samples ``count .. count + n - 1``: ``(hop_end, total, usum)``
    with ``hop_end`` (n,) the hops' last samples, ``total`` (n,) the sum of ``u + accel_bias``
    over the hop ending there (0 elsewhere; standing and NaN samples add nothing) and the
    running sum carried past the last sample."""
    L = config.aid_len
    n = u.size
    add = np.where(np.isfinite(u) & ~ss, u + config.accel_bias, 0.0)
    hop_end = (count + np.arange(n) + 1) % L == 0
    total = np.zeros(n)
    s = float(usum)
    for k in range(n):  # sequential sums: the numbers of repeated step
        s += float(add[k])
        if hop_end[k]:
            total[k] = s
            s = 0.0
    return hop_end, total, s


def _core(config: Config, g: rbpmf.State, offset: float, y: float, u: float, gain: float,
          ref: float, ref_var: float, ss: bool, acc: bool, boost: bool,
          ubar: float, ext: np.ndarray | None = None,
          shift: float = 0.0) -> tuple[rbpmf.State, float, _Posterior]:
    """One sample on a detector decision; ``g`` is modified in place before the RBPMF step;
    ``ext`` the comb evidence of a frame ending here (None: none); ``shift`` rad/s of
    continuous aiding applied after the step (one linear split)."""
    T = config.tracker.model.dt
    r = config.wheel_radius
    if boost and config.boost:
        offset = _move(config, g, offset, config.mode_len * T * ubar / r)
    if not acc:
        offset = _resolve(config, g, offset)
    ll = None
    ss_m = ss and config.ss_on_grid
    if ss_m or (np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0):
        om = config.grid + offset
        ll = np.zeros(om.size)
        if ss_m:
            ll -= 0.5 * om * om / config.r_ss
        if np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0:
            ll -= 0.5 * (om - ref) ** 2 / ref_var
        ll0 = g.log_w_null
        if np.isfinite(ll0):  # "no line": omega uniform on the (linear) grid
            mx = np.max(ll)
            ll0 = ll0 + mx + np.log(np.mean(np.exp(ll - mx)))
        g = rbpmf.State(g.log_w + ll, g.mean, g.cov, ll0, g.mode_j)
    vib, accel, still = config.trackers
    cfg = accel if acc else (still if ss_m else vib)
    yin = np.nan if acc else y * gain
    if acc and not config.comb_in_accel:
        ext = None
    g, e = rbpmf.step(cfg, g, yin, extra=ext)
    est = _output(e.omega, e.omega_std, e.omega_map, e.omega_lo, e.omega_hi, e.p_null, offset,
                  ss, acc, boost, ubar, e.amplitudes)
    if acc and np.isfinite(u):
        g = _copy_grid(g)
        offset = _move(config, g, offset, T * (u + config.accel_bias) / r)
    if shift != 0.0:
        g = _copy_grid(g)
        offset = _resolve(config, g, offset + shift)
    return g, offset, est


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: MAP (rad/s), mass of the
#: "no line" state, acceleration / boost modes, ubar (m/s^2, mean of the last a_x), amplitudes
ESTIMATE_EXTRAS = ("omega_map", "p_null", "accelerating", "boost", "ubar", "amplitudes")


def _output(om, sd, omap, lo, hi, p_null, offset, ss, acc, boost, ubar, amps) -> _Posterior:
    return _Posterior(max(om + offset, 0.0), float(sd), max(omap + offset, 0.0),
                    max(lo + offset, 0.0), max(hi + offset, 0.0), float(p_null), bool(ss),
                    bool(acc), bool(boost), float(ubar), np.asarray(amps))


def step(config: Config, state: State, y: float | Sample, u: float = np.nan, *,
         gain: float = 1.0, ref: float = np.nan, ref_var: float = np.nan,
         still: float = np.nan) -> tuple[State, Estimate]:
    """Process one sample (inputs as :func:`vibrospeed.estimators.aided.step`, or its
    :class:`~vibrospeed.estimators.aiding.Sample`: ``y`` the pre-filtered vibration sample in
    m/s^2 read by the standstill test, ``y * gain`` fed to the RBPMF, ``u`` = a_x in m/s^2,
    ``ref``/``ref_var`` an omega fix, ``still`` the standstill flag read with
    ``standstill='broadband'``; this tracker has no ``comb`` input)."""
    if isinstance(y, Sample):
        y, u, gain, ref, ref_var, still = y[:6]
    _check_state(config, state)
    window = det.WindowState(state.window.buf.copy(), state.window.pos_count.copy(),
                             state.window.flag.copy())
    mode = det.ModeState(state.mode.buf.copy(), state.mode.pos_count.copy(),
                         state.mode.flag.copy())
    ss, acc, boost, ubar = _decide(config, window, mode, float(y), float(u), float(still))
    shift, usum = 0.0, float(state.usum)
    if config.aiding == "continuous":
        if np.isfinite(u) and not ss:
            usum += float(u) + config.accel_bias
        if (state.count + 1) % config.aid_len == 0:
            shift = config.tracker.model.dt * usum / config.wheel_radius
            usum = 0.0
    ext, buf = None, state.buf
    if config.comb is not None:
        yy = np.array([float(y) * float(gain)])
        idx, vals = gridmod.evidence(config.comb, yy,
                                     gridmod.State(state.grid, state.buf, state.count))
        ext = vals[0] if idx.size else None
        buf = _push(state.buf, state.count, yy)
    g = _copy_grid(state.grid)
    g, offset, est = _core(config, g, float(state.offset), float(y), float(u), float(gain),
                           float(ref), float(ref_var), ss, acc, boost, ubar, ext, shift)
    extras = {k: getattr(est, k) for k in ESTIMATE_EXTRAS}
    return State(g, offset, window, mode, buf, state.count + 1, usum), Estimate(
        est.omega, est.omega_std, est.omega_lo, est.omega_hi,
        has_signal=float(config.tracker.claims(est.p_null)),
        standstill=float(est.standstill),
        extras=extras)


class Result(NamedTuple):
    """Batch output over samples (n,) unless noted: the columns of :func:`step`'s estimates."""

    omega: np.ndarray
    omega_std: np.ndarray
    omega_map: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    p_null: np.ndarray
    standstill: np.ndarray
    accelerating: np.ndarray
    boost: np.ndarray
    ubar: np.ndarray
    amplitudes: np.ndarray  # (n, M)
    final: State


def run(config: Config, y: np.ndarray | Sample, u: np.ndarray | None = None, *,
        gain: np.ndarray | None = None, ref: np.ndarray | None = None,
        ref_var: np.ndarray | None = None, still: np.ndarray | None = None,
        state: State | None = None) -> Result:
    """Run over whole signals (``y`` may be a :class:`~vibrospeed.estimators.aiding.Sample` of
    arrays; scalars hold for every sample); identical to repeated :func:`step`.

    The detectors depend on the inputs only, so they run first (same compiled cores);
    stretches of plain vibration samples (no standstill, no fix, no acceleration mode, offset 0)
    go to :func:`rbpmf.run` in one call, the other samples through the per-sample core.
    """
    if isinstance(y, Sample):
        n = np.size(y.y)
        y, u, gain, ref, ref_var, still = (
            np.full(n, v, dtype=np.float64) if np.ndim(v) == 0 else v for v in y[:6])
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = y.size
    u, gain, ref, ref_var = input_arrays(n, u, gain, ref, ref_var, "aided_grid.run")
    still = np.full(n, np.nan) if still is None else np.ascontiguousarray(still, np.float64)
    if still.shape != (n,):
        raise InputError(f"aided_grid.run: 'still' has shape {still.shape}, expected ({n},) "
                         "like y")
    st = init(config) if state is None else state
    _check_state(config, st)
    window = det.WindowState(st.window.buf.copy(), st.window.pos_count.copy(),
                             st.window.flag.copy())
    mode = det.ModeState(st.mode.buf.copy(), st.mode.pos_count.copy(), st.mode.flag.copy())
    acc, boost, ubar = det._mode_run(u, mode.buf, mode.pos_count, mode.flag, config.mode_mu)
    if config.aiding != "mode":
        acc, boost = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
    if config.standstill == "broadband":
        ss = still > 0.5
        acc, boost = acc & ~ss, boost & ~ss
    else:
        if config.standstill == "window":
            ss = det._window_run(y, window.buf, window.pos_count, window.flag, config.ss_mu)
        else:
            ss = np.zeros(n, np.bool_)
        ss = ss & ~acc
    has_ref = np.isfinite(ref) & np.isfinite(ref_var) & (ref_var > 0)
    special = (ss if config.ss_on_grid else np.zeros(n, np.bool_)) | acc | boost | has_ref
    shift = np.zeros(n)
    usum = float(st.usum)
    if config.aiding == "continuous":
        hop_end, total, usum = _aid_sums(config, u, ss, st.count, usum)
        shift[hop_end] = config.tracker.model.dt * total[hop_end] / config.wheel_radius
        special = special | (shift != 0.0)
    yin = y * gain
    ev_row = np.full(n, -1, np.int64)
    ev_idx, ev_vals, buf = np.zeros(0, np.int64), np.zeros((0, 0)), st.buf
    if config.comb is not None:
        ev_idx, ev_vals = gridmod.evidence(config.comb, yin,
                                           gridmod.State(st.grid, st.buf, st.count))
        ev_row[ev_idx] = np.arange(ev_idx.size)
        buf = _push(st.buf, st.count, yin)
    M = config.tracker.model.M
    out = np.full((n, 6), np.nan)
    amps = np.full((n, M), np.nan)
    g = _copy_grid(st.grid)
    offset = float(st.offset)
    k = 0
    while k < n:
        if not special[k] and offset == 0.0:
            e = k + 1
            while e < n and not special[e]:
                e += 1
            sel = (ev_idx >= k) & (ev_idx < e)
            extra = (ev_idx[sel] - k, ev_vals[sel]) if np.any(sel) else None
            res = rbpmf.run(config.tracker, yin[k:e], g, extra=extra)
            g = res.final
            out[k:e] = np.column_stack([np.maximum(res.omega, 0.0), res.omega_std,
                                        np.maximum(res.omega_map, 0.0),
                                        np.maximum(res.omega_lo, 0.0),
                                        np.maximum(res.omega_hi, 0.0), res.p_null])
            amps[k:e] = res.amplitudes
            k = e
            continue
        g = _copy_grid(g)
        g, offset, est = _core(config, g, offset, float(y[k]), float(u[k]), float(gain[k]),
                               float(ref[k]), float(ref_var[k]), bool(ss[k]), bool(acc[k]),
                               bool(boost[k]), float(ubar[k]),
                               ev_vals[ev_row[k]] if ev_row[k] >= 0 else None, float(shift[k]))
        out[k] = est[:6]
        amps[k] = est.amplitudes
        k += 1
    return Result(*(out[:, c] for c in range(6)), ss, acc, boost, ubar, amps,
                  State(g, offset, window, mode, buf, st.count + n, usum))
