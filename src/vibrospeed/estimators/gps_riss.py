"""GPS + single-accelerometer Kalman fusion, "GPS/RISS" (METHODS.md section 3; O'Kane & Ringwood,
sections IV-VI, eq. 1-18).

Per accelerometer sample, with ``dt`` the time since the previous sample:

1. accelerometer pre-processing (paper Fig. 1): ``a = gain * a_raw``; optional pitch compensation
   ``p = poly(a)`` in degrees (eq. 14), ``a <- (a - g sin p) / cos p``; then the offset estimate
   ``b`` of the drift filter is subtracted (section VI-b).
2. predict the 4-state model ``X = [speed, accel, GPS speed, its derivative]`` with the exact
   transition ``F = expm(A_c dt)`` (:mod:`vibrospeed.models.gps_riss`) and
   ``Q = diag(q) * dt * q_rate``.
3. update: on a sample with a *new valid* GPS fix (``gps_speed`` finite and ``gps_sats >=
   min_sats``; a missing or NaN satellite count counts as valid) "KF1 INS/GPS",
   ``H = [[0,1,0,0],[0,0,1,0]]``, ``R = diag(r_acc_gps, R22)`` (eq. 9, 12); otherwise "KF INS",
   ``H = [0,1,0,0]``, ``R = r_acc_ins`` (eq. 10). A NaN accelerometer sample drops its row.
4. GPS error (section VI-c): "KF2" runs the same model with the fixed ``R = diag(3.5, 40)``
   (eq. 18); its speed is passed through the GPS lag model and ``E = |x3_KF2 - lag(x1_KF2)|``
   (clipped to ``0..e_max``) sets ``R22 = r_gps_slope * E + r_gps`` (eq. 13: 72 E + 40).
5. offset/drift (section VI-b, eq. 16-17): an integrator KF ``[drift, offset]`` with ``H = [1, 0]``
   observes ``integral(a) - x1`` on samples with a valid fix; its offset is subtracted in step 1.

Noise units. The paper gives ``Q = diag(5, 4, 1, 1)`` (its eq. 11, called "P") and the R values
without units or sample rate; its gains were computed off-line at 400 Hz. Read literally as
per-step variances at 400 Hz the speed state is almost free and the accelerometer is nearly
ignored (followed every simulated GPS jump), so by default we read q as white-noise intensities
per second, ``Q = diag(q) dt`` (``q_rate = 1``), and keep R per sample; ``q_rate = 400`` gives the
literal reading. Step 2 above writes this as ``Q = diag(q) * dt * q_rate``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import config_from_params
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.models.gps_riss import GpsLagModel, simulate_receiver, transition
from vibrospeed.types import Recording, Track

G = 9.80665

# Flags reported per sample in ``run`` output ``mode``.
MODE_INS = 0  #: accelerometer only ("KF INS")
MODE_GPS = 1  #: valid GPS fix fused ("KF1 INS/GPS")
MODE_REJECTED = 2  #: a fix was present but gated out (too few satellites)


@dataclass(frozen=True)
class Config:
    """Parameters (paper values as defaults; units SI).

    Parameters
    ----------
    gps_a, gps_b : GPS lag model A_gps (row-major) and B_gps, paper eq. 3-4.
    q : process noise diag of ``[speed, accel, GPS speed, GPS accel]`` (paper eq. 11 "P":
        5, 4, 1, 1); per-step ``Q = q * dt * q_rate``, so with the default ``q_rate = 1`` q is an
        intensity per second; ``q_rate = 400`` reads q literally as per-step at the paper's 400 Hz.
    r_acc_ins : accelerometer variance in "KF INS" (paper: 0.4).
    r_acc_gps : accelerometer variance in "KF1/KF2 INS/GPS" (paper eq. 12: 3.5).
    r_gps : GPS speed variance R22 at zero error and in KF2 (paper eq. 13, 18: 40).
    r_gps_slope : R22 growth per m/s of GPS error E (paper eq. 13: 72).
    e_max : clip of E in m/s (paper: 0..5).
    adaptive : use R22 = r_gps_slope E + r_gps (else r_gps).
    error_mode : "innovation" (default: new fix vs KF2's lagged speed before KF2's update) or
        "states" (paper VI-c: KF2's x3 vs KF2's x1 through the lag model; reacts weakly).
    min_sats : satellite-count gate (paper: 7).
    gain : accelerometer calibration gain.
    pitch_compensation : apply ``pitch_poly`` (deg, highest power first; paper eq. 14, fitted for
        a motorcycle, so off by default).
    offset_estimation : run the drift/offset KF (section VI-b).
    q_drift, q_offset : drift KF process noise intensities, (m/s)^2/s and (m/s^2)^2/s.
    r_drift : drift KF measurement variance (m/s)^2.  p0_offset : initial offset variance.
    p0_speed : initial speed variance (m/s)^2.
    """

    gps_a: tuple[float, ...] = (0.0, 1.0, -1427.2, -114.2)
    gps_b: tuple[float, ...] = (0.0, 1427.2)
    q: tuple[float, ...] = (5.0, 4.0, 1.0, 1.0)
    q_rate: float = 1.0
    r_acc_ins: float = 0.4
    r_acc_gps: float = 3.5
    r_gps: float = 40.0
    r_gps_slope: float = 72.0
    e_max: float = 5.0
    adaptive: bool = True
    error_mode: str = "innovation"
    min_sats: float = 7.0
    gain: float = 1.0
    pitch_compensation: bool = False
    pitch_poly: tuple[float, ...] = (-0.0183, 0.2822, 0.0207)
    offset_estimation: bool = True
    q_drift: float = 1e-3
    q_offset: float = 1e-2
    r_drift: float = 0.1
    p0_offset: float = 0.25
    p0_speed: float = 100.0

    def __post_init__(self) -> None:
        _ = self.lag  # validates the lag model
        if len(self.q) != 4 or min(self.q) < 0:
            raise ParameterError(f"q must be 4 values >= 0, got {self.q}")
        for name in ("q_rate", "r_acc_ins", "r_acc_gps", "r_gps", "r_drift", "p0_offset",
                     "p0_speed", "gain"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("r_gps_slope", "e_max", "q_drift", "q_offset", "min_sats"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.error_mode not in ("innovation", "states"):
            raise ParameterError(
                f"error_mode must be 'innovation' or 'states', got '{self.error_mode}'"
            )
        if len(self.pitch_poly) < 1:
            raise ParameterError("pitch_poly needs at least one coefficient")

    @property
    def lag(self) -> GpsLagModel:
        """The GPS lag model."""
        return GpsLagModel(a=tuple(self.gps_a), b=tuple(self.gps_b))  # type: ignore[arg-type]

    @classmethod
    def with_lag(cls, lag: GpsLagModel, **kw) -> Config:
        """Config using the receiver model ``lag`` (e.g. from :func:`identify_lag`)."""
        return cls(gps_a=tuple(lag.a), gps_b=tuple(lag.b), **kw)

    def _arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = np.array([
            self.q[0], self.q[1], self.q[2], self.q[3], self.q_rate,
            self.r_acc_ins, self.r_acc_gps, self.r_gps, self.r_gps_slope, self.e_max,
            float(self.adaptive), self.min_sats, self.gain, float(self.pitch_compensation),
            float(self.offset_estimation), self.q_drift, self.q_offset, self.r_drift,
            float(self.error_mode == "innovation"),
        ], dtype=np.float64)
        return self.lag.as_array(), p, np.array(self.pitch_poly, dtype=np.float64)


class State(NamedTuple):
    """Filter state after the last sample.

    x, P : (4,), (4, 4) main filter (KF / KF1) mean and covariance.
    x2, P2 : KF2 (fixed weighting) mean and covariance.
    lag : (2,) GPS lag model driven by the KF2 speed, ``[x3, x4]`` predicted from x1.
    od, Pod : (2,), (2, 2) drift filter ``[speed drift, accelerometer offset]``.
    t : time of the last sample (NaN before the first).  err : GPS error E (m/s).
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
        """Fused speed estimate x1 (m/s)."""
        return float(self.x[0])

    @property
    def offset(self) -> float:
        """Accelerometer offset estimate (m/s^2)."""
        return float(self.od[1])


class Output(NamedTuple):
    """Per-sample results of :func:`run` (all (n,) float64 except ``mode`` int8).

    speed, speed_std : fused x1 and sqrt(P11), m/s.  accel : x2, m/s^2.
    gps_model : x3, the filter's idea of what the receiver reports, m/s.
    offset : accelerometer offset estimate, m/s^2.  gps_error : E, m/s.
    r22 : GPS variance used at fixes (NaN elsewhere).  mode : MODE_INS / MODE_GPS / MODE_REJECTED.
    """

    speed: np.ndarray
    speed_std: np.ndarray
    accel: np.ndarray
    gps_model: np.ndarray
    offset: np.ndarray
    gps_error: np.ndarray
    r22: np.ndarray
    mode: np.ndarray


def init(config: Config, v0: float = 0.0, *, offset0: float = 0.0) -> State:
    """State at speed ``v0`` (m/s) with the receiver in steady state (x3 = v0, x4 = 0).

    The speed variance is ``p0_speed``; the other variances start at their per-second process
    noise. ``offset0`` (m/s^2) is the initial accelerometer offset guess.
    """
    v0 = float(v0)
    if not math.isfinite(v0):
        raise ParameterError(f"initial speed must be finite, got {v0}")
    q = np.asarray(config.q, dtype=np.float64)
    P = np.diag([config.p0_speed, q[1] + 1.0, config.p0_speed, q[3] + 1.0])
    x = np.array([v0, 0.0, v0, 0.0])
    od = np.array([0.0, float(offset0)])
    Pod = np.diag([config.r_drift, config.p0_offset])
    return State(x, P, x.copy(), P.copy(), np.array([v0, 0.0]), od, Pod, math.nan, 0.0, v0)


# -- compiled core -----------------------------------------------------------------------------

@njit(cache=True)
def _kf_update(x, P, h_idx, z, r, m):
    """Update with ``m`` direct observations ``z[i] = x[h_idx[i]] + e_i``, var(e_i) = r[i].

    Sequential scalar updates (R is diagonal, so this equals the joint update), Joseph form
    ``P = (I - K H) P (I - K H)' + K r K'``.
    """
    n = x.size
    for i in range(m):
        j = h_idx[i]
        s = P[j, j] + r[i]  # S = H P H' + R
        k = P[:, j] / s  # K = P H' / S
        innov = z[i] - x[j]
        for a in range(n):
            x[a] += k[a] * innov
        # Joseph form with H = e_j
        IKH = np.eye(n)
        for a in range(n):
            IKH[a, j] -= k[a]
        Pn = IKH @ P @ IKH.T
        for a in range(n):
            for b in range(n):
                Pn[a, b] += k[a] * r[i] * k[b]
        for a in range(n):
            for b in range(n):
                P[a, b] = 0.5 * (Pn[a, b] + Pn[b, a])


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
def _step_core(lagp, p, poly, x, P, x2, P2, lz, od, Pod, sc, t, a_raw, gps, sats, out):
    """One sample in place. ``sc = [t_prev, E, v_int]``; ``out`` (7,) receives the results."""
    dt = 0.0 if math.isnan(sc[0]) else t - sc[0]
    sc[0] = t
    q_rate = p[4]
    use_off = p[14] > 0.5
    # 1. accelerometer pre-processing: gain, pitch (paper eq. 14, degrees), offset
    has_a = not math.isnan(a_raw)
    a = p[12] * a_raw
    if has_a and p[13] > 0.5:
        pitch = 0.0
        for c in poly:
            pitch = pitch * a + c
        pr = pitch * math.pi / 180.0
        a = (a - G * math.sin(pr)) / math.cos(pr)
    # drift filter predict (eq. 16) and integral of the pre-processed accelerometer
    if dt > 0.0:
        if has_a:
            sc[2] += dt * a
        else:
            sc[2] += dt * (x[1] + od[1])
        if use_off:
            od[0] += dt * od[1]
            p00 = Pod[0, 0] + dt * (Pod[0, 1] + Pod[1, 0]) + dt * dt * Pod[1, 1] + p[15] * dt
            p01 = Pod[0, 1] + dt * Pod[1, 1]
            Pod[0, 0] = p00
            Pod[0, 1] = p01
            Pod[1, 0] = p01
            Pod[1, 1] += p[16] * dt
    a_c = a - od[1] if use_off else a
    # 2. predict KF / KF1 and KF2 with the exact transition
    qd = np.empty(4)
    for i in range(4):
        qd[i] = p[i] * dt * q_rate
    if dt > 0.0:
        F = transition(lagp, dt)
        # lag model driven by the KF2 speed (for the GPS error E), from KF2's previous posterior
        l3 = F[2, 0] * x2[0] + F[2, 1] * x2[1] + F[2, 2] * lz[0] + F[2, 3] * lz[1]
        l4 = F[3, 0] * x2[0] + F[3, 1] * x2[1] + F[3, 2] * lz[0] + F[3, 3] * lz[1]
        lz[0] = l3
        lz[1] = l4
        _predict(x, P, F, qd)
        _predict(x2, P2, F, qd)
    # 3. gating
    has_fix = not math.isnan(gps)
    valid = has_fix and (math.isnan(sats) or sats >= p[11])
    h_idx = np.empty(2, dtype=np.int64)
    z = np.empty(2)
    r = np.empty(2)
    m = 0
    if has_a:
        h_idx[0] = 1
        z[0] = a_c
        r[0] = p[6] if valid else p[5]
        m = 1
    r22 = math.nan
    if valid:
        h_idx[m] = 2
        z[m] = gps
        r[m] = p[7]
        # 4. KF2 with fixed R (eq. 18), then E and the adaptive R22 (eq. 13)
        if p[18] > 0.5:  # "innovation": fix against the lagged KF2 speed, before the update
            e = abs(gps - lz[0])
            _kf_update(x2, P2, h_idx, z, r, m + 1)
        else:  # "states" (paper VI-c): KF2's x3 against its x1 passed through the lag model
            _kf_update(x2, P2, h_idx, z, r, m + 1)
            e = abs(x2[2] - lz[0])
        sc[1] = min(max(e, 0.0), p[9])
        r22 = p[7] + p[8] * sc[1] if p[10] > 0.5 else p[7]
        r[m] = r22
        _kf_update(x, P, h_idx, z, r, m + 1)
        # 5. drift filter update (eq. 17): observes integral(a) - x1
        if use_off:
            s = Pod[0, 0] + p[17] * (r22 / p[7])  # weighted down like the GPS itself
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
    elif m > 0:
        _kf_update(x2, P2, h_idx, z, r, m)
        _kf_update(x, P, h_idx, z, r, m)
    out[0] = x[0]
    out[1] = math.sqrt(max(P[0, 0], 0.0))
    out[2] = x[1]
    out[3] = x[2]
    out[4] = od[1]
    out[5] = sc[1]
    out[6] = r22
    if valid:
        return 1
    if has_fix:
        return 2
    return 0


@njit(cache=True)
def _run_core(lagp, p, poly, x, P, x2, P2, lz, od, Pod, sc, t, a, gps, sats, out, mode):
    for k in range(t.size):
        mode[k] = _step_core(lagp, p, poly, x, P, x2, P2, lz, od, Pod, sc, t[k], a[k], gps[k],
                             sats[k], out[k])


def _copy_state(state: State):
    return (np.array(state.x, dtype=np.float64), np.array(state.P, dtype=np.float64),
            np.array(state.x2, dtype=np.float64), np.array(state.P2, dtype=np.float64),
            np.array(state.lag, dtype=np.float64), np.array(state.od, dtype=np.float64),
            np.array(state.Pod, dtype=np.float64),
            np.array([state.t, state.err, state.v_int], dtype=np.float64))


def _pack(arrs) -> State:
    x, P, x2, P2, lz, od, Pod, sc = arrs
    return State(x, P, x2, P2, lz, od, Pod, float(sc[0]), float(sc[1]), float(sc[2]))


def step(config: Config, state: State, y: tuple[float, float, float, float]
         ) -> tuple[State, dict[str, float]]:
    """One sample ``y = (t, ax, gps_speed, gps_sats)``; NaN marks "no sample now".

    ``gps_sats`` NaN means "unknown" (the fix counts as valid). Returns the new state and a dict
    with ``speed, speed_std, accel, gps_model, offset, gps_error, r22, mode``.
    """
    t, a, g, s = (float(v) for v in y)
    if not math.isnan(state.t) and not t >= state.t:
        raise InputError(f"time goes backwards at t = {t} s (previous {state.t} s)")
    lagp, p, poly = config._arrays()
    arrs = _copy_state(state)
    out = np.empty(7)
    mode = _step_core(lagp, p, poly, *arrs, t, a, g, s, out)
    names = ("speed", "speed_std", "accel", "gps_model", "offset", "gps_error", "r22")
    est = {k: float(v) for k, v in zip(names, out, strict=True)}
    est["mode"] = int(mode)
    return _pack(arrs), est


def run(config: Config, t, ax, gps_speed, gps_sats=None, *, state: State | None = None
        ) -> tuple[State, Output]:
    """Filter a whole recording; identical numbers to repeated :func:`step`.

    Parameters
    ----------
    t : (n,) s non-decreasing.  ax : (n,) m/s^2 longitudinal accelerometer (NaN = none).
    gps_speed : (n,) m/s, finite only at samples carrying a new fix.
    gps_sats : (n,) satellites, or None (every fix valid).
    state : start state (default ``init(config, first finite GPS speed or 0)``).
    """
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
        fin = np.flatnonzero(np.isfinite(g) & ~(s < config.min_sats))
        state = init(config, float(g[fin[0]]) if fin.size else 0.0)
    lagp, p, poly = config._arrays()
    arrs = _copy_state(state)
    out = np.empty((n, 7))
    mode = np.empty(n, dtype=np.int8)
    _run_core(lagp, p, poly, *arrs, t, ax, g, s, out, mode)
    o = Output(*(np.ascontiguousarray(out[:, i]) for i in range(7)), mode)
    return _pack(arrs), o


_AXIS_CHANNEL = {"x": "ax", "y": "ay", "z": "az"}


def estimate(recording: Recording, *, axis: str = "x", wheel_radius: float | None = None,
             params: dict | None = None, progress: bool = False) -> Track:
    """Fused speed for a recording with an accelerometer channel and ``gps_speed``.

    ``axis`` names the longitudinal accelerometer channel: "x" -> ``ax`` (phones often have "y"
    forward -> ``ay``); a channel name may be given directly. ``params`` overrides :class:`Config`
    fields. The Track's ``speed_std`` is sqrt(P11); extras hold ``offset``, ``gps_error``,
    ``accel``, ``mode``.
    """
    cfg = config_from_params(Config, params)
    ch = _AXIS_CHANNEL.get(axis, axis)
    recording.require(ch, "gps_speed")
    sats = recording.channels.get("gps_sats")
    _, o = run(cfg, recording.t, recording.channel(ch), recording.channel("gps_speed"), sats)
    return Track.from_speed(
        recording.t, o.speed, o.speed_std, wheel_radius=wheel_radius or recording.wheel_radius,
        method="gps-riss", params={k: (list(v) if isinstance(v, tuple) else v)
                                   for k, v in asdict(cfg).items()},
        extras={"offset": o.offset, "gps_error": o.gps_error, "accel": o.accel,
                "gps_model": o.gps_model, "mode": o.mode.astype(np.float64)},
    )


# -- identification ----------------------------------------------------------------------------

def identify_lag(t, gps_speed, speed_ref, *, wn0: float = 10.0, zeta0: float = 0.8,
                 fit_gain: bool = False) -> tuple[GpsLagModel, dict[str, float]]:
    """Fit the second-order receiver model (paper section IV-b) to GPS fixes.

    Simulates ``x3`` driven by the reference speed (taken piecewise linear) for candidate
    ``(wn, zeta[, gain])`` and minimises the squared difference to ``gps_speed`` at its finite
    samples (scipy ``least_squares`` on log-parameters). Returns the model and a dict with
    ``wn, zeta, gain, rmse`` (m/s residual) and ``rmse_identity`` (residual of ``x3 = speed``).

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

    def resid(theta):
        wn, zeta = np.exp(theta[0]), np.exp(theta[1])
        gain = theta[2] if fit_gain else 1.0
        lag = GpsLagModel.from_wn_zeta(wn, zeta, gain)
        return simulate_receiver(t, v, lag)[fix] - g[fix]

    x0 = [np.log(wn0), np.log(zeta0)] + ([1.0] if fit_gain else [])
    lo = [np.log(0.05), np.log(0.05)] + ([0.5] if fit_gain else [])
    hi = [np.log(500.0), np.log(20.0)] + ([1.5] if fit_gain else [])
    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale=1.0)
    wn, zeta = float(np.exp(sol.x[0])), float(np.exp(sol.x[1]))
    gain = float(sol.x[2]) if fit_gain else 1.0
    lag = GpsLagModel.from_wn_zeta(wn, zeta, gain)
    info = {"wn": wn, "zeta": zeta, "gain": gain,
            "rmse": float(np.sqrt(np.mean(sol.fun**2))),
            "rmse_identity": float(np.sqrt(np.mean((v[fix] - g[fix]) ** 2)))}
    return lag, info


def identify_lag_recording(recording: Recording, *, reference: str = "speed_true", **kw
                           ) -> tuple[GpsLagModel, dict[str, float]]:
    """:func:`identify_lag` on a recording's ``gps_speed`` against its ``reference`` channel."""
    recording.require("gps_speed", reference)
    return identify_lag(recording.t, recording.channel("gps_speed"),
                        recording.channel(reference), **kw)
