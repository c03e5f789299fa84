# Over 500 lines: one filter (the paper's GPS/RISS with its lag model and three error modes)
# with its Config, compiled loop, protocol and entry point.
"""GPS + single-accelerometer Kalman fusion, "GPS/RISS" (METHODS.md section 3; O'Kane & Ringwood,
sections IV-VI, eq. 1-18), with the accelerometer offset as a filter state and a GPS delay.

State ``X = [v, a, b, x3, x4, d...]``: speed (m/s), acceleration (m/s^2), accelerometer offset b
(m/s^2; road slope ``g sin theta`` plus calibration bias), the receiver's reported speed x3 and its
derivative x4 (paper eq. 2), and the Pade states of an optional pure GPS delay
(:func:`~vibrospeed.models.gps_riss.receiver_matrices`). Per accelerometer sample, ``dt`` the time
since the previous one:

1. accelerometer pre-processing (paper Fig. 1): ``a_m = gain * a_raw``; optional pitch
   compensation ``p = poly(a_m)`` in degrees (eq. 14), ``a_m <- (a_m - g sin p) / cos p``.
2. predict with the exact transition ``F = expm(A_c dt)`` (paper eq. 7 without its ZOH
   approximation) and ``Q = diag(q_speed, q_accel, q_offset, q_gps...) dt`` (white-noise
   intensities per second).
3. update: on a sample with a *new valid* fix (``gps_speed`` finite and ``gps_sats >= min_sats``;
   a missing or NaN count counts as valid) "KF1 INS/GPS" (eq. 9, 12): ``a_m = a + b + e``,
   var ``r_acc_gps``, and ``gps = x3 + e``, var ``R22``; otherwise "KF INS" (eq. 10): the
   accelerometer row alone, var ``r_acc_ins``. A NaN accelerometer sample drops its row.
4. GPS error E and adaptive weighting (section VI-c, eq. 13, 18):
   ``R22 = r_gps + r_gps_slope E + r_gps_sq E^2`` with E clipped to ``0..e_max``. Default
   ``error_mode="innovation"``: E^2 = max(nu^2 - S, 0), nu the main filter's GPS innovation and S
   its predicted variance (the part of the disagreement the model does not explain, so R22 grows
   with nu^2 on a receiver jump). ``"kf2"``: the paper's KF2 (same model, fixed
   R = (r_acc_gps, r_gps)) predicts the fix through the lag model and E = |fix - prediction|
   before KF2's update;
   ``"states"``: the paper's literal E = |x3_KF2 - lag(x1_KF2)| after it.
5. offset (section VI-b): ``offset_mode="state"`` (default) estimates b inside the filter above
   (random walk ``q_offset``), so grade changes are followed with the filter's own gain and the
   speed covariance includes the offset uncertainty. ``"integrator"`` is the paper's separate
   drift KF ``[drift, offset]`` on ``integral(a_m) - v`` at valid fixes (eq. 16-17), its offset
   subtracted from ``a_m``; ``"off"`` estimates none.

Noise units. The paper's Q = diag(5, 4, 1, 1) and R values have no units or sample rate (only their
ratios matter for its fixed-gain filter), so ``speed_std`` computed with them is ~40x too wide.
The defaults here are physical (accelerometer white noise 0.3 m/s^2 per sample, GPS 0.1 m/s per
fix, jerk intensity, offset random walk), so ``speed_std = sqrt(P11)`` is an honest 1-sigma; the
paper's set is :meth:`Config.paper` (with Q read per second). Override them per sensor.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import config_from_params
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.models.gps_riss import (
    GpsLagModel,
    continuous_matrix,
    receiver_steady_state,
    simulate_receiver,
    transition,
)
from vibrospeed.types import Estimate, Recording, Track

G = 9.80665

# Flags reported per sample in ``run`` output ``mode``.
MODE_INS = 0  #: accelerometer only ("KF INS")
MODE_GPS = 1  #: valid GPS fix fused ("KF1 INS/GPS")
MODE_REJECTED = 2  #: a fix was present but gated out (too few satellites)

_ERROR_MODES = ("innovation", "kf2", "states")
_OFFSET_MODES = ("state", "integrator", "off")


@dataclass(frozen=True)
class GpsFields:
    """The GPS receiver and its satellite gate, one definition for every filter that fuses GPS
    speed (``gps-riss``, ``fuse``: their Configs start with these fields).

    gps_a, gps_b : GPS lag model A_gps (row-major) and B_gps, paper eq. 3-4 (default: the
        paper's second-order receiver).
    gps_delay : pure GPS delay (s) in front of the lag, Pade order ``gps_pade`` (1 or 2).
    min_sats : satellite-count gate (paper: 7): a fix is valid where ``gps_sats >= min_sats``
        or the count is unknown (NaN).
    """

    gps_a: tuple[float, ...] = (0.0, 1.0, -1427.2, -114.2)
    gps_b: tuple[float, ...] = (0.0, 1427.2)
    gps_delay: float = 0.0
    gps_pade: int = 2
    min_sats: float = 7.0

    @property
    def lag(self) -> GpsLagModel:
        """The GPS receiver model."""
        return GpsLagModel(a=tuple(self.gps_a), b=tuple(self.gps_b),  # type: ignore[arg-type]
                           delay=float(self.gps_delay), pade=int(self.gps_pade))

    def valid_fixes(self, gps_speed: np.ndarray, gps_sats: np.ndarray | None) -> np.ndarray:
        """Where a fix is valid: finite speed and not fewer than ``min_sats`` satellites."""
        g = np.asarray(gps_speed, dtype=np.float64)
        if gps_sats is None:
            return np.isfinite(g)
        return np.isfinite(g) & ~(np.asarray(gps_sats, dtype=np.float64) < self.min_sats)

    def _check_gps(self, prefix: str = "") -> None:
        """Validates the lag model and the gate (the Configs' ``__post_init__``)."""
        _ = self.lag
        if not self.min_sats >= 0:
            raise ParameterError(f"{prefix}min_sats must be >= 0, got {self.min_sats}")


@dataclass(frozen=True)
class Config(GpsFields):
    """Parameters (SI units; physical noise defaults, see the module notes; paper set:
    :meth:`paper`).

    Parameters
    ----------
    gps_a, gps_b, gps_delay, gps_pade, min_sats : the GPS receiver and its satellite gate
        (:class:`GpsFields`).
    q_speed, q_accel, q_offset, q_gps : process noise intensities per second of the speed
        ((m/s)^2/s, model error), acceleration ((m/s^2)^2/s, jerk), offset ((m/s^2)^2/s, grade
        changes) and receiver states (paper eq. 11 "P" = 5, 4, -, 1).
    r_acc_ins, r_acc_gps : accelerometer variance per sample in "KF INS" / "KF1" (paper 0.4, 3.5).
    r_gps : GPS speed variance per fix at zero error (paper eq. 13, 18: 40 in its units).
    r_gps_slope, r_gps_sq : R22 growth per m/s and per (m/s)^2 of the GPS error E (paper: 72, 0).
    e_max : clip of E in m/s (paper: 5).  adaptive : use the adaptive R22 (else r_gps).
    error_mode : "innovation", "kf2" or "states" (module notes, step 4).
    gain : accelerometer calibration gain.
    pitch_compensation : apply ``pitch_poly`` (deg, highest power first; paper eq. 14, fitted for
        a motorcycle, so off by default).
    offset_mode : "state", "integrator" (paper VI-b) or "off".
    q_drift, r_drift : integrator drift filter noise ((m/s)^2/s, (m/s)^2); it uses q_offset too.
    p0_speed, p0_accel, p0_offset : initial variances.
    """

    q_speed: float = 1e-4
    q_accel: float = 10.0
    q_offset: float = 5e-3
    q_gps: float = 1e-6
    r_acc_ins: float = 0.09
    r_acc_gps: float = 0.09
    r_gps: float = 0.01
    r_gps_slope: float = 0.0
    r_gps_sq: float = 0.5
    e_max: float = 5.0
    adaptive: bool = True
    error_mode: str = "innovation"
    gain: float = 1.0
    pitch_compensation: bool = False
    pitch_poly: tuple[float, ...] = (-0.0183, 0.2822, 0.0207)
    offset_mode: str = "state"
    q_drift: float = 1e-3
    r_drift: float = 0.1
    p0_speed: float = 1.0
    p0_accel: float = 1.0
    p0_offset: float = 0.25

    def __post_init__(self) -> None:
        self._check_gps()
        for name in ("r_acc_ins", "r_acc_gps", "r_gps", "r_drift", "p0_offset", "p0_speed",
                     "p0_accel", "gain"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("q_speed", "q_accel", "q_offset", "q_gps", "r_gps_slope", "r_gps_sq",
                     "e_max", "q_drift"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.error_mode not in _ERROR_MODES:
            raise ParameterError(f"error_mode must be one of {', '.join(_ERROR_MODES)}, "
                                 f"got '{self.error_mode}'")
        if self.offset_mode not in _OFFSET_MODES:
            raise ParameterError(f"offset_mode must be one of {', '.join(_OFFSET_MODES)}, "
                                 f"got '{self.offset_mode}'")
        if len(self.pitch_poly) < 1:
            raise ParameterError("pitch_poly needs at least one coefficient")

    @classmethod
    def paper(cls, **kw) -> Config:
        """The paper's constants (eq. 11-13, 18; Q read as intensities per second), its KF2 error
        and separate drift filter: the weighting of the paper, but ``speed_std`` is not calibrated.
        """
        base = dict(q_speed=5.0, q_accel=4.0, q_offset=1e-2, q_gps=1.0, r_acc_ins=0.4,
                    r_acc_gps=3.5, r_gps=40.0, r_gps_slope=72.0, r_gps_sq=0.0,
                    error_mode="kf2", offset_mode="integrator", p0_speed=100.0, p0_accel=5.0)
        base.update(kw)
        return cls(**base)

    @classmethod
    def with_lag(cls, lag: GpsLagModel, **kw) -> Config:
        """Default config using the receiver model ``lag`` (e.g. from :func:`identify_lag`)."""
        return cls(gps_a=tuple(lag.a), gps_b=tuple(lag.b), gps_delay=lag.delay,
                   gps_pade=lag.pade, **kw)

    def using_lag(self, lag: GpsLagModel) -> Config:
        """This config with the receiver model replaced by ``lag``."""
        return replace(self, gps_a=tuple(lag.a), gps_b=tuple(lag.b), gps_delay=lag.delay,
                       gps_pade=lag.pade)

    def _arrays(self):
        lag = self.lag
        Ac = continuous_matrix(lag, offset_state=True)
        n = Ac.shape[0]
        state_off = self.offset_mode == "state"
        qc = np.full(n, self.q_gps)
        qc[:3] = (self.q_speed, self.q_accel, self.q_offset if state_off else 0.0)
        ha = np.zeros(n)
        ha[1] = 1.0
        ha[2] = 1.0 if state_off else 0.0
        hg = np.zeros(n)
        hg[3] = 1.0
        p = np.array([
            self.r_acc_ins, self.r_acc_gps, self.r_gps, self.r_gps_slope, self.r_gps_sq,
            self.e_max, float(self.adaptive), self.min_sats, self.gain,
            float(self.pitch_compensation), float(self.offset_mode == "integrator"),
            self.q_drift, self.q_offset, self.r_drift, float(_ERROR_MODES.index(self.error_mode)),
        ], dtype=np.float64)
        return Ac, qc, ha, hg, p, np.array(self.pitch_poly, dtype=np.float64)


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


_NOUT = 8


class Sample(NamedTuple):
    """The inputs of one sample (or, as arrays, of a recording): ``t`` s, ``accel`` m/s^2 the
    longitudinal accelerometer (NaN: none), ``gps_speed`` m/s (finite only at a new fix),
    ``gps_sats`` satellites (NaN or None: unknown, the fix counts as valid)."""

    t: Any
    accel: Any
    gps_speed: Any
    gps_sats: Any = math.nan


class Result(NamedTuple):
    """:func:`run`'s output: the :class:`Output` columns per sample and ``final`` the state
    after the last sample."""

    speed: np.ndarray
    speed_std: np.ndarray
    accel: np.ndarray
    gps_model: np.ndarray
    offset: np.ndarray
    offset_std: np.ndarray
    gps_error: np.ndarray
    r22: np.ndarray
    mode: np.ndarray
    final: State

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
    lag = config.lag
    g = receiver_steady_state(lag, 1.0)
    n = 3 + g.size
    T = np.zeros((n, 3))
    T[:3, :3] = np.eye(3)
    T[3:, 0] = g
    P = T @ np.diag([config.p0_speed, config.p0_accel, config.p0_offset]) @ T.T
    P[3:, 3:] += np.eye(g.size) * max(config.q_gps, 1e-12)
    state_off = config.offset_mode == "state"
    if not state_off:
        P[2, :] = 0.0
        P[:, 2] = 0.0
    x = np.zeros(n)
    x[0] = v0
    x[2] = float(offset0) if state_off else 0.0
    x[3:] = g * v0
    od = np.array([0.0, float(offset0) if config.offset_mode == "integrator" else 0.0])
    Pod = np.diag([config.r_drift, config.p0_offset])
    return State(x, P, x.copy(), P.copy(), g * v0, od, Pod, math.nan, 0.0, v0)


# -- compiled core -----------------------------------------------------------------------------

@njit(cache=True)
def _update(x, P, h, z, r):
    """Scalar update ``z = h x + e``, var(e) = r; Joseph form ``(I - K h) P (I - K h)' + K r K'``.
    Returns the innovation."""
    n = x.size
    Ph = P @ h
    s = 0.0
    for a in range(n):
        s += h[a] * Ph[a]
    s += r
    k = Ph / s
    innov = z - h @ x
    for a in range(n):
        x[a] += k[a] * innov
    IKH = np.eye(n) - np.outer(k, h)
    Pn = IKH @ P @ IKH.T + np.outer(k, k) * r
    for a in range(n):
        for b in range(n):
            P[a, b] = 0.5 * (Pn[a, b] + Pn[b, a])
    return innov


@njit(cache=True)
def _predict(x, P, F, qd):
    """``x = F x``, ``P = F P F' + diag(qd)``."""
    xn = F @ x
    Pn = F @ P @ F.T
    for a in range(x.size):
        x[a] = xn[a]
        Pn[a, a] += qd[a]
    for a in range(x.size):
        for b in range(x.size):
            P[a, b] = Pn[a, b]


@njit(cache=True)
def _step_core(Ac, qc, ha, hg, p, poly, x, P, x2, P2, lz, od, Pod, sc, t, a_raw, gps, sats,
               Fc, out):
    """One sample in place. ``sc = [t_prev, E, v_int, dt of Fc]``; ``Fc`` caches the transition
    of the last step length; ``out`` (8,) receives the results. Returns the mode."""
    dt = 0.0 if math.isnan(sc[0]) else t - sc[0]
    sc[0] = t
    integ = p[10] > 0.5
    emode = int(p[14])
    use_kf2 = emode > 0
    # 1. accelerometer pre-processing: gain, pitch (paper eq. 14, degrees)
    has_a = not math.isnan(a_raw)
    a = p[8] * a_raw
    if has_a and p[9] > 0.5:
        pitch = 0.0
        for c in poly:
            pitch = pitch * a + c
        pr = pitch * math.pi / 180.0
        a = (a - G * math.sin(pr)) / math.cos(pr)
    # integrator drift filter predict (eq. 16) and integral of the pre-processed accelerometer
    if dt > 0.0:
        if has_a:
            sc[2] += dt * a
        else:
            sc[2] += dt * (x[1] + x[2] + od[1])
        if integ:
            od[0] += dt * od[1]
            p00 = Pod[0, 0] + dt * (Pod[0, 1] + Pod[1, 0]) + dt * dt * Pod[1, 1] + p[11] * dt
            p01 = Pod[0, 1] + dt * Pod[1, 1]
            Pod[0, 0] = p00
            Pod[0, 1] = p01
            Pod[1, 0] = p01
            Pod[1, 1] += p[12] * dt
    a_c = a - od[1] if integ else a
    # 2. predict with the exact transition
    if dt > 0.0:
        if dt != sc[3]:
            Fc[:, :] = transition(Ac, dt)
            sc[3] = dt
        qd = qc * dt
        _predict(x, P, Fc, qd)
        if use_kf2:
            # receiver chain driven by KF2's speed and acceleration (prediction of the fix)
            lzn = Fc[3:, 0] * x2[0] + Fc[3:, 1] * x2[1] + np.ascontiguousarray(Fc[3:, 3:]) @ lz
            for i in range(lz.size):
                lz[i] = lzn[i]
            _predict(x2, P2, Fc, qd)
    # 3. gating
    has_fix = not math.isnan(gps)
    valid = has_fix and (math.isnan(sats) or sats >= p[7])
    r22 = math.nan
    r_acc = p[1] if valid else p[0]
    if has_a:
        _update(x, P, ha, a_c, r_acc)
        if use_kf2:
            _update(x2, P2, ha, a_c, r_acc)
    if valid:
        # 4. GPS error E and R22 (eq. 13)
        if emode == 0:  # main filter's innovation beyond its predicted spread
            nu = gps - hg @ x
            s0 = hg @ P @ hg + p[2]
            e = math.sqrt(max(nu * nu - s0, 0.0))
        elif emode == 1:  # KF2's prediction of the fix, before KF2's update
            e = abs(gps - lz[0])
            _update(x2, P2, hg, gps, p[2])
        else:  # "states" (paper VI-c): KF2's x3 against its speed through the lag model
            _update(x2, P2, hg, gps, p[2])
            e = abs(x2[3] - lz[0])
        e = min(max(e, 0.0), p[5])
        sc[1] = e
        r22 = p[2] + p[3] * e + p[4] * e * e if p[6] > 0.5 else p[2]
        _update(x, P, hg, gps, r22)
        # 5. integrator drift filter update (eq. 17): observes integral(a) - v
        if integ:
            s = Pod[0, 0] + p[13] * (r22 / p[2])  # weighted down like the GPS itself
            k0 = Pod[0, 0] / s
            k1 = Pod[1, 0] / s
            innov = (sc[2] - x[0]) - od[0]
            od[0] += k0 * innov
            od[1] += k1 * innov
            p00 = (1.0 - k0) * Pod[0, 0]
            p01 = (1.0 - k0) * Pod[0, 1]
            p11 = Pod[1, 1] - k1 * Pod[0, 1]
            Pod[0, 0] = p00
            Pod[0, 1] = p01
            Pod[1, 0] = p01
            Pod[1, 1] = p11
    out[0] = x[0]
    out[1] = math.sqrt(max(P[0, 0], 0.0))
    out[2] = x[1]
    out[3] = x[3]
    if integ:
        out[4] = od[1]
        out[5] = math.sqrt(max(Pod[1, 1], 0.0))
    else:
        out[4] = x[2]
        out[5] = math.sqrt(max(P[2, 2], 0.0))
    out[6] = sc[1]
    out[7] = r22
    if valid:
        return 1
    if has_fix:
        return 2
    return 0


@njit(cache=True)
def _run_core(Ac, qc, ha, hg, p, poly, x, P, x2, P2, lz, od, Pod, sc, t, a, gps, sats, out, mode):
    Fc = np.eye(x.size)
    for k in range(t.size):
        mode[k] = _step_core(Ac, qc, ha, hg, p, poly, x, P, x2, P2, lz, od, Pod, sc, t[k], a[k],
                             gps[k], sats[k], Fc, out[k])


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


_OUT_NAMES = ("speed", "speed_std", "accel", "gps_model", "offset", "offset_std", "gps_error",
              "r22")


def step(config: Config, state: State, y: Sample | tuple[float, float, float, float]
         ) -> tuple[State, Estimate]:
    """One sample ``y = (t, ax, gps_speed, gps_sats)`` (a :class:`Sample`); NaN marks "no
    sample now".

    ``gps_sats`` NaN means "unknown" (the fix counts as valid). Returns the new state and the
    estimate: ``speed``, ``speed_std`` and the other :class:`Output` columns as extras.
    """
    t, a, g, s = (float(v) for v in y)
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
                  state: State | None = None) -> Output:
    """:func:`run` in chunks with a rich progress bar (same numbers: the state carries over)."""
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
    return Output(*(np.concatenate([getattr(o, f) for o in parts]) for f in Output._fields))


_AXIS_CHANNEL = {"x": "ax", "y": "ay", "z": "az"}


def estimate(recording: Recording, *, axis: str = "x", wheel_radius: float | None = None,
             params: dict | None = None, progress: bool = False,
             return_posterior: bool = False) -> Track:
    """Fused speed for a recording with an accelerometer channel and ``gps_speed``.

    ``axis`` names the longitudinal accelerometer channel: "x" -> ``ax`` (phones often have "y"
    forward -> ``ay``); a channel name may be given directly. ``gps_speed`` must be finite only at
    samples carrying a new fix (NaN between fixes). ``params`` overrides :class:`Config` fields.
    ``progress`` shows a progress bar (the recording is filtered in chunks of 200 000 samples;
    same numbers). The Track's ``speed_std`` is sqrt(P11) (an honest 1-sigma when the noise
    parameters match the sensors; 98 % band by default); extras hold ``offset``, ``offset_std``,
    ``gps_error``, ``accel``, ``gps_model``, ``mode``. ``params["preset"] = "paper"`` starts from
    :meth:`Config.paper` (the paper's noise constants) instead of the calibrated defaults.
    """
    params = dict(params or {})
    preset = str(params.pop("preset", "default")).lower()
    if preset not in ("default", "paper"):
        raise ParameterError(f"unknown gps-riss preset '{preset}' (choose default or paper)")
    base = asdict(Config.paper()) if preset == "paper" else {}
    cfg = config_from_params(Config, params, **base)
    ch = _AXIS_CHANNEL.get(axis, axis)
    recording.require(ch, "gps_speed")
    sats = recording.channels.get("gps_sats")
    args = (cfg, recording.t, recording.channel(ch), recording.channel("gps_speed"), sats)
    o = _run_progress(*args) if progress else run(cfg, Sample(*args[1:])).output
    return Track.from_speed(
        recording.t, o.speed, o.speed_std, wheel_radius=wheel_radius or recording.wheel_radius,
        method="gps-riss", params={k: (list(v) if isinstance(v, tuple) else v)
                                   for k, v in asdict(cfg).items()},
        extras={"offset": o.offset, "offset_std": o.offset_std, "gps_error": o.gps_error,
                "accel": o.accel, "gps_model": o.gps_model, "mode": o.mode.astype(np.float64)},
    )


# -- identification ----------------------------------------------------------------------------

def identify_lag(t, gps_speed, speed_ref, *, wn0: float = 10.0, zeta0: float = 0.8,
                 fit_gain: bool = False, fit_delay: bool = False, delay0: float = 0.2,
                 pade: int = 2) -> tuple[GpsLagModel, dict[str, float]]:
    """Fit the receiver model (paper section IV-b: second-order lag; optionally a gain and a pure
    delay in front, Pade order ``pade`` as the filter uses it) to GPS fixes. With ``fit_delay``
    the fit starts from the delays 0, ``delay0`` and ``2 delay0`` and keeps the best.

    Simulates ``x3`` driven by the reference speed (taken piecewise linear) for candidate
    ``(wn, zeta[, gain][, delay])`` and minimises the squared difference to ``gps_speed`` at its
    finite samples (scipy ``least_squares``; wn, zeta on a log scale). Returns the model and a dict
    with ``wn, zeta, gain, delay, rmse`` (m/s residual) and ``rmse_identity`` (residual of
    ``x3 = speed``).

    Parameters
    ----------
    t : (n,) s.  gps_speed : (n,) m/s, NaN between fixes.  speed_ref : (n,) m/s finite reference.
    """
    from scipy.optimize import least_squares

    t = np.asarray(t, float)
    g = np.asarray(gps_speed, float)
    v = np.asarray(speed_ref, float)
    if not (t.shape == g.shape == v.shape and t.ndim == 1):
        raise InputError("identify_lag: t, gps_speed and speed_ref must be 1-D of equal length")
    ok = np.isfinite(v)
    if not ok.all():
        t, g, v = t[ok], g[ok], v[ok]
    fix = np.isfinite(g)
    if fix.sum() < 10:
        raise InputError(f"identify_lag: need >= 10 GPS fixes with a reference, got {fix.sum()}")

    def model(theta):
        wn, zeta = np.exp(theta[0]), np.exp(theta[1])
        gain = theta[2] if fit_gain else 1.0
        delay = theta[-1] if fit_delay else 0.0
        return GpsLagModel.from_wn_zeta(wn, zeta, gain, delay=delay if delay > 1e-4 else 0.0,
                                        pade=pade)

    def resid(theta):
        return simulate_receiver(t, v, model(theta))[fix] - g[fix]

    lo = [np.log(0.05), np.log(0.05)] + ([0.5] if fit_gain else []) + ([0.0] if fit_delay else [])
    hi = [np.log(500.0), np.log(20.0)] + ([1.5] if fit_gain else []) + (
        [2.0] if fit_delay else [])
    # the delay trades off against the lag (near-equal residuals): start from several delays and
    # keep the best fit
    sol = None
    for d0 in ((0.0, delay0, 2.0 * delay0) if fit_delay else (None,)):
        x0 = [np.log(wn0), np.log(zeta0)] + ([1.0] if fit_gain else []) + (
            [d0] if fit_delay else [])
        cand = least_squares(resid, x0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4)
        if sol is None or cand.cost < sol.cost - 1e-9 * max(sol.cost, 1e-12):
            sol = cand
    lag = model(sol.x)
    info = {"wn": lag.wn, "zeta": lag.zeta, "gain": lag.dc_gain, "delay": lag.delay,
            "rmse": float(np.sqrt(np.mean(sol.fun**2))),
            "rmse_identity": float(np.sqrt(np.mean((v[fix] - g[fix]) ** 2)))}
    return lag, info


def identify_lag_recording(recording: Recording, *, reference: str = "speed_true", **kw
                           ) -> tuple[GpsLagModel, dict[str, float]]:
    """:func:`identify_lag` on a recording's ``gps_speed`` against its ``reference`` channel."""
    recording.require("gps_speed", reference)
    return identify_lag(recording.t, recording.channel("gps_speed"),
                        recording.channel(reference), **kw)
