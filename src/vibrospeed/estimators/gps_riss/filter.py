"""The GPS/RISS filter's protocol (:mod:`vibrospeed.estimators.gps_riss`): the records
``State``, ``Output``, ``Sample``, ``Result``, the start state (:func:`init`, the receiver in
steady state at the initial speed), one sample (:func:`step`), the filter over arrays
(:func:`run`) and the same in chunks behind a progress bar (:func:`_run_progress`), all packing
the state for the compiled core (:mod:`vibrospeed.estimators.gps_riss.core`)."""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.gps_riss.config import Config
from vibrospeed.estimators.gps_riss.core import _run_core, _step_core
from vibrospeed.models.gps_riss import receiver_steady_state
from vibrospeed.types import Estimate


class State(NamedTuple):
    """Filter state after the last sample.

    x, P : (n,), (n, n) main filter ``[v, a, b, x3, x4, d...]`` mean and covariance.
    x2, P2 : KF2 (fixed weighting; error modes "kf2"/"states" only) mean and covariance.
    lag : receiver states driven by the KF2 speed (prediction of the fix, "kf2"/"states").
    od, Pod : (2,), (2, 2) integrator drift filter ``[speed drift, offset]`` (offset_mode
        "integrator").  t : time of the last sample (NaN before the first).  err : GPS error E.
    v_int : integral of the pre-processed accelerometer (m/s).
    """

    x: np.ndarray
    P: np.ndarray
    x2: np.ndarray
    P2: np.ndarray
    lag: np.ndarray
    od: np.ndarray
    Pod: np.ndarray
    t: float
    err: float
    v_int: float

    @property
    def speed(self) -> float:
        """Fused speed estimate (m/s)."""
        return float(self.x[0])

    @property
    def offset(self) -> float:
        """Accelerometer offset estimate (m/s^2), whichever filter holds it."""
        return float(self.x[2] + self.od[1])


class Output(NamedTuple):
    """Per-sample results of :func:`run` (all (n,) float64 except ``mode`` int8).

    speed, speed_std : fused speed and sqrt(P11), m/s.  accel : a, m/s^2.
    gps_model : x3, the filter's idea of what the receiver reports, m/s.
    offset, offset_std : accelerometer offset estimate and its std, m/s^2.  gps_error : E, m/s.
    r22 : GPS variance used at fixes (NaN elsewhere).  mode : MODE_INS / MODE_GPS / MODE_REJECTED.
    """

    speed: np.ndarray
    speed_std: np.ndarray
    accel: np.ndarray
    gps_model: np.ndarray
    offset: np.ndarray
    offset_std: np.ndarray
    gps_error: np.ndarray
    r22: np.ndarray
    mode: np.ndarray


#: the compiled core's float columns, in its order: every :class:`Output` column but ``mode``
_OUT_NAMES = Output._fields[:-1]
_NOUT = len(_OUT_NAMES)


class Sample(NamedTuple):
    """The inputs of one sample (or, as arrays, of a recording): ``t`` s, ``accel`` m/s^2 the
    longitudinal accelerometer (NaN: none), ``gps_speed`` m/s (finite only at a new fix),
    ``gps_sats`` satellites (NaN or None: unknown, the fix counts as valid)."""

    t: Any
    accel: Any
    gps_speed: Any
    gps_sats: Any = math.nan


class Result(NamedTuple("_ResultFields", [*Output.__annotations__.items(), ("final", State)])):
    """:func:`run`'s output: the :class:`Output` columns per sample (named and documented
    there, in the same order) followed by ``final``, the state after the last sample."""

    __slots__ = ()

    @property
    def output(self) -> Output:
        """The per-sample columns alone."""
        return Output(*self[:-1])


def init(config: Config, v0: float = 0.0, *, offset0: float = 0.0) -> State:
    """State at speed ``v0`` (m/s), acceleration 0, with the receiver in steady state.

    Variances: ``p0_speed``, ``p0_accel``, ``p0_offset``; the receiver states are fully correlated
    with the speed (steady state) plus their per-second process noise. ``offset0`` (m/s^2) is the
    initial accelerometer offset guess.
    """
    v0 = float(v0)
    if not math.isfinite(v0):
        raise ParameterError(f"initial speed must be finite, got {v0}")
    if not math.isfinite(float(offset0)):  # every speed was NaN from it
        raise ParameterError(f"offset0 must be finite (m/s^2), got {offset0}")
    lag = config.lag
    g = receiver_steady_state(lag, 1.0)
    n = 3 + g.size
    T = np.zeros((n, 3))
    T[:3, :3] = np.eye(3)
    T[3:, 0] = g
    P = np.zeros((n + 1, n + 1))  # the last state: the receiver's extra lag, 0 +- gps_lag_std
    P[:n, :n] = T @ np.diag([config.p0_speed, config.p0_accel, config.p0_offset]) @ T.T
    P[3:n, 3:n] += np.eye(g.size) * max(config.q_gps, 1e-12)
    P[n, n] = config.gps_lag_std ** 2
    state_off = config.offset_mode == "state"
    if not state_off:
        P[2, :] = 0.0
        P[:, 2] = 0.0
    x = np.zeros(n + 1)
    x[0] = v0
    x[2] = float(offset0) if state_off else 0.0
    x[3:n] = g * v0
    od = np.array([0.0, float(offset0) if config.offset_mode == "integrator" else 0.0])
    Pod = np.diag([config.r_drift, config.p0_offset])
    return State(x, P, x.copy(), P.copy(), g * v0, od, Pod, math.nan, 0.0, v0)


def _copy_state(state: State, n: int):
    x = np.array(state.x, dtype=np.float64)
    if x.shape != (n,):
        raise ParameterError(f"state has {x.size} states but the config's model needs {n} "
                             "(GPS delay on/off changed?)")
    return (x, np.array(state.P, dtype=np.float64),
            np.array(state.x2, dtype=np.float64), np.array(state.P2, dtype=np.float64),
            np.array(state.lag, dtype=np.float64), np.array(state.od, dtype=np.float64),
            np.array(state.Pod, dtype=np.float64),
            np.array([state.t, state.err, state.v_int, -1.0], dtype=np.float64))


def _pack(arrs) -> State:
    x, P, x2, P2, lz, od, Pod, sc = arrs
    return State(x, P, x2, P2, lz, od, Pod, float(sc[0]), float(sc[1]), float(sc[2]))


def step(config: Config, state: State, y: Sample | tuple[float, float, float, float]
         ) -> tuple[State, Estimate]:
    """One sample ``y = (t, ax, gps_speed, gps_sats)`` (a :class:`Sample`); NaN marks "no
    sample now".

    ``gps_sats`` NaN means "unknown" (the fix counts as valid). Returns the new state and the
    estimate: ``speed``, ``speed_std`` and the other :class:`Output` columns as extras.
    """
    t, a, g, s = (math.nan if v is None else float(v) for v in y)  # None: unknown (Sample)
    if not math.isfinite(t):  # read as "time goes backwards at t = nan" before
        raise InputError(f"t must be a finite time in s, got {t}")
    if not math.isnan(state.t) and not t >= state.t:
        raise InputError(f"time goes backwards at t = {t} s (previous {state.t} s)")
    Ac, qc, ha, hg, p, poly = config._arrays()
    arrs = _copy_state(state, Ac.shape[0])
    out = np.empty(_NOUT)
    mode = _step_core(Ac, qc, ha, hg, p, poly, *arrs, t, a, g, s, np.eye(Ac.shape[0]), out)
    ex = {k: float(v) for k, v in zip(_OUT_NAMES, out, strict=True)}
    ex["mode"] = int(mode)
    return _pack(arrs), Estimate(speed=ex.pop("speed"), speed_std=ex.pop("speed_std"), extras=ex)


def run(config: Config, y: Sample, state: State | None = None) -> Result:
    """Filter a whole recording; identical numbers to repeated :func:`step`.

    Parameters
    ----------
    y : a :class:`Sample` of arrays: ``t`` (n,) s non-decreasing, ``accel`` (n,) m/s^2
        longitudinal accelerometer (NaN = none), ``gps_speed`` (n,) m/s, finite only at samples
        carrying a new fix, ``gps_sats`` (n,) satellites, or None / NaN (every fix valid).
    state : start state (default ``init(config, first valid GPS speed or 0)``).
    """
    t, ax, gps_speed, gps_sats = y
    if gps_sats is not None and np.ndim(gps_sats) == 0:
        gps_sats = None if math.isnan(float(gps_sats)) else np.full(np.size(t), gps_sats)
    t = np.ascontiguousarray(t, dtype=np.float64)
    n = t.size
    ax = np.ascontiguousarray(ax, dtype=np.float64)
    g = np.ascontiguousarray(gps_speed, dtype=np.float64)
    s = np.full(n, np.nan) if gps_sats is None else np.ascontiguousarray(gps_sats, np.float64)
    if not (ax.shape == g.shape == s.shape == (n,)):
        raise InputError("run: t, ax, gps_speed and gps_sats must have the same length")
    if not np.all(np.isfinite(t)):  # an IndexError below before
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"t must be finite times in s, got {t[bad]} at sample {bad}")
    if n > 1 and not np.all(np.diff(t) >= 0):
        bad = int(np.flatnonzero(np.diff(t) < 0)[0]) + 1
        raise InputError(f"time goes backwards at sample {bad}")
    if state is None:
        fin = np.flatnonzero(config.valid_fixes(g, s))
        state = init(config, float(g[fin[0]]) if fin.size else 0.0)
    Ac, qc, ha, hg, p, poly = config._arrays()
    arrs = _copy_state(state, Ac.shape[0])
    out = np.empty((n, _NOUT))
    mode = np.empty(n, dtype=np.int8)
    _run_core(Ac, qc, ha, hg, p, poly, *arrs, t, ax, g, s, out, mode)
    return Result(*(np.ascontiguousarray(out[:, i]) for i in range(_NOUT)), mode, _pack(arrs))


def _run_progress(config: Config, t, ax, g, s, chunk: int = 200_000,
                  state: State | None = None, end: list | None = None) -> Output:
    """:func:`run` in chunks with a rich progress bar (same numbers: the state carries over);
    the state after the last chunk is appended to ``end`` where given."""
    from rich.progress import Progress

    t = np.asarray(t, dtype=np.float64)
    g = np.asarray(g, dtype=np.float64)
    ax = np.asarray(ax, dtype=np.float64)
    parts = []
    with Progress(transient=True) as bar:
        task = bar.add_task("gps-riss", total=t.size)
        for k0 in range(0, t.size, chunk):
            sl = slice(k0, k0 + chunk)
            if state is None:
                fin = np.flatnonzero(config.valid_fixes(g, s))
                state = init(config, float(g[fin[0]]) if fin.size else 0.0)
            o = run(config, Sample(t[sl], ax[sl], g[sl], None if s is None else s[sl]),
                    state=state)
            state = o.final
            parts.append(o.output)
            bar.update(task, advance=min(chunk, t.size - k0))
    if end is not None:
        end.append(state)
    return Output(*(np.concatenate([getattr(o, f) for o in parts]) for f in Output._fields))
