"""Simulated drives for GPS + single-accelerometer fusion (METHODS.md section 3; the scenarios of
O'Kane & Ringwood's GPS/RISS paper, sections VI-VII: braking and acceleration with a lagging
receiver, a tunnel, a hilly course, a receiver jump, a motorcycle with acceleration-induced pitch).

Every function takes an explicit ``np.random.Generator`` and returns a
:class:`~vibrospeed.types.Recording` on a uniform accelerometer time line with channels

``ax``          (m/s^2) longitudinal specific force ``gain (A cos p + g sin(p + theta)) + b + e``
                with vehicle acceleration A, pitch p, road slope theta (paper eq. 15), bias b;
``gps_speed``   (m/s) receiver speed at fix samples, NaN between fixes; the receiver output is the
                lag model (:class:`~vibrospeed.models.gps_riss.GpsLagModel`) driven by the true
                speed, plus white noise and any scenario error (jump); fixes fall at jittered
                epochs of rate ``gps_rate`` rounded to the nearest accelerometer sample;
``gps_sats``    satellites used (every sample); 0 in a tunnel, where ``gps_speed`` reads 0 as on
                the paper's Fig. 5, so only satellite gating can reject it;
``speed_true``  (m/s) true vehicle speed.

``meta`` holds the truth needed by the evaluation: ``offset_true`` (n,) m/s^2 total accelerometer
offset (bias + g sin theta), ``pitch_deg`` (n,), the lag model, the rates and the seed-free
scenario parameters. This module is self-contained (the general simulator lives elsewhere).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.models.gps_riss import GpsLagModel, simulate_receiver
from vibrospeed.types import Recording

G = 9.80665

#: Paper eq. 14: pitch (deg) = -0.0183 a^2 + 0.2822 a + 0.0207 (motorcycle), highest power first.
PAPER_PITCH_POLY = (-0.0183, 0.2822, 0.0207)


def _smooth_profile(t: np.ndarray, knots: list[tuple[float, float]], rise: float) -> np.ndarray:
    """Acceleration from ``(t_start, level)`` knots, each change smoothed by a raised cosine."""
    a = np.zeros_like(t)
    prev = 0.0
    for t0, level in knots:
        x = np.clip((t - t0) / rise, 0.0, 1.0)
        a += (level - prev) * 0.5 * (1.0 - np.cos(np.pi * x))
        prev = level
    return a


def _integrate(t: np.ndarray, a: np.ndarray, v0: float) -> np.ndarray:
    """Cumulative trapezoid integral of ``a`` starting at ``v0``."""
    v = np.empty_like(a)
    v[0] = v0
    v[1:] = v0 + np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))
    return v


def _fix_indices(t: np.ndarray, rate: float, rng: np.random.Generator, jitter: float) -> np.ndarray:
    """Indices of the accelerometer samples nearest to jittered GPS epochs (unique, sorted)."""
    epochs = t[0] + rng.uniform(0.0, 1.0 / rate) + np.arange(0.0, t[-1] - t[0], 1.0 / rate)
    epochs = epochs + rng.normal(0.0, jitter, epochs.size)
    idx = np.searchsorted(t, epochs)
    idx = np.clip(idx, 0, t.size - 1)
    return np.unique(idx)


def drive(
    t: np.ndarray,
    accel: np.ndarray,
    v0: float,
    *,
    rng: np.random.Generator,
    lag: GpsLagModel | None = None,
    gps_rate: float = 12.5,
    gps_noise: float = 0.1,
    gps_jitter: float = 0.002,
    gps_error: np.ndarray | None = None,
    gps_delay: float = 0.0,
    sats: np.ndarray | None = None,
    acc_noise: float = 0.3,
    acc_bias: float = 0.0,
    acc_gain: float = 1.0,
    slope_rad: np.ndarray | None = None,
    pitch_deg: np.ndarray | None = None,
    source: str = "sim/gps",
    meta: dict | None = None,
) -> Recording:
    """Sensor data for a true acceleration profile ``accel`` (m/s^2) on the uniform line ``t``.

    Parameters
    ----------
    t : (n,) s uniform accelerometer time line.  accel : (n,) m/s^2 vehicle acceleration.
    v0 : initial speed, m/s.  lag : receiver model (default: the paper's, eq. 3-4).
    gps_rate : Hz (paper: 12.5).  gps_noise : m/s white noise std on each fix.
    gps_jitter : s std of the fix epochs.  gps_error : (n,) m/s added to the receiver output.
    gps_delay : s pure delay of the receiver output (exact, on top of ``lag``; time-stamp latency).
    sats : (n,) satellite count (default 9 everywhere).  acc_noise : m/s^2 white noise std.
    acc_bias : m/s^2 constant accelerometer offset.  acc_gain : calibration gain error.
    slope_rad : (n,) road slope theta (uphill +).  pitch_deg : (n,) body pitch (nose up +).
    """
    # the noise levels and rates a user sets (--set): checked here, where they were an
    # internal error of NumPy (a negative std, a zero rate) or a recording of inf
    for name, value, lo in (("gps_rate", gps_rate, 0.0), ("gps_noise", gps_noise, None),
                            ("gps_jitter", gps_jitter, None), ("acc_noise", acc_noise, None),
                            ("acc_bias", acc_bias, -np.inf), ("acc_gain", acc_gain, -np.inf)):
        ok = np.isfinite(value) and (value > lo if lo is not None else value >= 0)
        if not ok:
            need = ("finite" if lo == -np.inf else "> 0" if lo == 0.0 else "finite and >= 0")
            raise ParameterError(f"{source}: {name} must be {need}, got {value}")
    if lag is not None and not isinstance(lag, GpsLagModel):
        raise ParameterError(f"{source}: lag must be a GpsLagModel (Python API; the command "
                             f"line sets gps_delay), got {lag!r}")
    lag = lag or GpsLagModel.paper()
    n = t.size
    speed = _integrate(t, accel, v0)
    if np.any(speed < -1e-9):
        raise ParameterError(f"{source}: speed profile goes negative ({speed.min():.2f} m/s)")
    speed = np.maximum(speed, 0.0)
    theta = np.zeros(n) if slope_rad is None else slope_rad
    pitch = np.zeros(n) if pitch_deg is None else pitch_deg
    p = np.deg2rad(pitch)
    ax = acc_gain * (accel * np.cos(p) + G * np.sin(p + theta)) + acc_bias
    ax = ax + rng.normal(0.0, acc_noise, n)
    if not (np.isfinite(gps_delay) and 0.0 <= gps_delay <= 10.0):
        raise ParameterError(f"{source}: gps_delay must be in 0..10 s, got {gps_delay}")
    if gps_delay > 0:
        lag = GpsLagModel(a=lag.a, b=lag.b, delay=float(gps_delay))
    rx = simulate_receiver(t, speed, lag, exact_delay=True)
    if gps_error is not None:
        rx = rx + gps_error
    sats = np.full(n, 9.0) if sats is None else np.asarray(sats, float)
    idx = _fix_indices(t, gps_rate, rng, gps_jitter)
    gps = np.full(n, np.nan)
    gps[idx] = np.maximum(rx[idx] + rng.normal(0.0, gps_noise, idx.size), 0.0)
    gps[idx[sats[idx] == 0]] = 0.0  # no satellites: receiver reports 0 (paper Fig. 5)
    m = {
        "offset_true": acc_gain * G * np.sin(theta) + acc_bias,
        "pitch_deg": pitch,
        "slope_rad": theta,
        "accel_true": accel,
        "gps_lag": {"a": list(lag.a), "b": list(lag.b), "delay": lag.delay},
        "gps_rate": gps_rate,
        "gps_noise": gps_noise,
        "acc_noise": acc_noise,
        "acc_bias": acc_bias,
        "acc_gain": acc_gain,
    }
    m.update(meta or {})
    return Recording(
        t=t,
        channels={"ax": ax, "gps_speed": gps, "gps_sats": sats, "speed_true": speed},
        source=source,
        notes=[f"simulated ({source}), GPS {gps_rate} Hz, accelerometer {1 / (t[1] - t[0]):g} Hz"],
        meta=m,
    )


def _timeline(duration: float, fs: float, minimum: float = 10.0) -> np.ndarray:
    if not (np.isfinite(duration) and duration >= minimum):
        raise ParameterError(f"duration must be >= {minimum:g} s, got {duration}")
    if not (np.isfinite(fs) and fs > 0):
        raise ParameterError(f"fs must be > 0, got {fs}")
    return np.arange(int(round(duration * fs))) / fs


def braking(
    rng: np.random.Generator,
    *,
    fs: float = 400.0,
    duration: float = 60.0,
    lag: GpsLagModel | None = None,
    overshoot: bool = True,
    **kw,
) -> Recording:
    """Repeated hard braking and acceleration (paper Fig. 4), ``duration`` s (default 60).

    With ``overshoot`` (default) the receiver is underdamped (wn = 6 rad/s, zeta = 0.5: 0.17 s
    ramp lag, 16 % overshoot after braking, as the paper observes on Fig. 4); otherwise the paper's
    overdamped model eq. 3-4. An explicit ``lag`` wins over both.
    """
    t = _timeline(duration, fs)
    knots: list[tuple[float, float]] = [(0.0, 0.0)]
    tc = 2.0 + rng.uniform(0.0, 1.0)
    while tc < duration - 6.0:
        up, hold, brake = rng.uniform(2.0, 3.5), rng.uniform(1.0, 3.0), rng.uniform(1.5, 2.5)
        a_up, a_br = rng.uniform(2.0, 3.5), -rng.uniform(4.0, 7.0)
        knots += [(tc, a_up), (tc + up, 0.0), (tc + up + hold, a_br), (tc + up + hold + brake, 0.0)]
        tc += up + hold + brake + rng.uniform(1.0, 3.0)
    a = _smooth_profile(t, knots, rise=0.3)
    v = _integrate(t, a, 0.0)
    a = _keep_positive(t, a, v, v0=15.0)
    if lag is None:
        lag = GpsLagModel.from_wn_zeta(6.0, 0.5) if overshoot else GpsLagModel.paper()
    return drive(t, a, 15.0, rng=rng, lag=lag, source="sim/gps/braking", **kw)


def _keep_positive(t: np.ndarray, a: np.ndarray, v: np.ndarray, v0: float) -> np.ndarray:
    """Scale the braking phases down where the profile would drive below 3 m/s."""
    speed = v0 + v
    if speed.min() >= 3.0:
        return a
    neg = np.minimum(a, 0.0)
    pos = np.maximum(a, 0.0)
    lo, hi = 0.0, 1.0
    for _ in range(40):
        s = 0.5 * (lo + hi)
        if (v0 + _integrate(t, pos + s * neg, 0.0)).min() >= 3.0:
            lo = s
        else:
            hi = s
    return pos + lo * neg


def tunnel(
    rng: np.random.Generator,
    *,
    fs: float = 400.0,
    duration: float = 60.0,
    lag: GpsLagModel | None = None,
    outage: float = 5.0,
    acc_bias: float = 0.1,
    **kw,
) -> Recording:
    """Drive (``duration`` s, default 60) with a ``outage`` s tunnel at about t = 40 s (paper
    Fig. 5; ends 12-16 s before the end on shorter drives): satellites drop to 0 and the receiver
    reports 0 m/s; the car accelerates steadily on entering, then cruises."""
    t = _timeline(duration, fs, minimum=outage + 20.0)
    t_in = min(38.0, duration - outage - 16.0) + rng.uniform(0.0, 4.0)
    knots = [
        (5.0, rng.uniform(1.0, 2.0)), (9.0, 0.0),
        (18.0, -rng.uniform(1.0, 2.0)), (21.0, 0.0),
        (t_in - 0.5, rng.uniform(1.0, 2.0)), (t_in + 0.6 * outage, 0.0),
    ]
    a = _smooth_profile(t, knots, rise=0.4)
    sats = np.full(t.size, 9.0)
    inside = (t >= t_in) & (t < t_in + outage)
    sats[inside] = 0.0
    return drive(t, a, 14.0, rng=rng, lag=lag, sats=sats, acc_bias=acc_bias,
                 source="sim/gps/tunnel", meta={"tunnel": (t_in, t_in + outage)}, **kw)


def hilly(
    rng: np.random.Generator,
    *,
    fs: float = 400.0,
    duration: float = 180.0,
    lag: GpsLagModel | None = None,
    acc_bias: float = 0.5,
    **kw,
) -> Recording:
    """``duration`` s (default 180) on a hilly course (paper section VI-b, Fig. 3): constant
    ``acc_bias`` plus road grades of up to +-4 % changing every 30-50 s, so the offset is
    ``acc_bias + g sin(theta(t))``."""
    t = _timeline(duration, fs)
    knots: list[tuple[float, float]] = []
    tc = 0.0
    while tc < duration:
        knots.append((tc, float(np.arctan(rng.uniform(-0.04, 0.04)))))
        tc += rng.uniform(30.0, 50.0)
    theta = _smooth_profile(t, knots, rise=8.0)
    akn = [(10.0, 1.0), (14.0, 0.0), (60.0, -1.0), (64.0, 0.0), (110.0, 1.5), (113.0, 0.0),
           (150.0, -1.5), (153.0, 0.0)]
    a = _smooth_profile(t, akn, rise=0.5)
    return drive(t, a, 15.0, rng=rng, lag=lag, slope_rad=theta, acc_bias=acc_bias,
                 source="sim/gps/hilly", **kw)


def gps_jump(
    rng: np.random.Generator,
    *,
    fs: float = 400.0,
    duration: float = 60.0,
    lag: GpsLagModel | None = None,
    size: float = 3.0,
    **kw,
) -> Recording:
    """``duration`` s (default 60) with receiver jumps (paper section VI-c): three times the
    receiver switches solution, its position jumps and the speed it derives is off by about
    ``size`` m/s (random sign) for a 0.4-1 s transient (raised-cosine edges of 0.1 s)."""
    t = _timeline(duration, fs)
    a = _smooth_profile(t, [(8.0, 1.5), (11.0, 0.0), (30.0, -1.5), (33.0, 0.0), (45.0, 1.0),
                            (48.0, 0.0)], rise=0.4)
    err = np.zeros(t.size)
    for t0 in (15.0, 36.0, 52.0):
        t0 = (t0 + rng.uniform(-2.0, 2.0)) * duration / 60.0
        d = rng.uniform(0.4, 1.0)
        amp = size * rng.uniform(0.8, 1.2) * rng.choice([-1.0, 1.0])
        err += amp * (_smooth_profile(t, [(t0, 1.0), (t0 + d, 0.0)], rise=0.1))
    return drive(t, a, 15.0, rng=rng, lag=lag, gps_error=err, source="sim/gps/gps_jump",
                 meta={"gps_error": err}, **kw)


def motorcycle(
    rng: np.random.Generator,
    *,
    fs: float = 400.0,
    duration: float = 60.0,
    lag: GpsLagModel | None = None,
    pitch_poly: tuple[float, ...] = PAPER_PITCH_POLY,
    **kw,
) -> Recording:
    """``duration`` s (default 60) of a motorcycle: hard accelerations (to 6 m/s^2) and braking
    (to -8 m/s^2); the body pitches with acceleration by the paper's polynomial eq. 14 (degrees)
    plus 0.1 deg noise."""
    t = _timeline(duration, fs)
    knots: list[tuple[float, float]] = []
    tc = 2.0 + rng.uniform(0.0, 1.0)
    while tc < duration - 8.0:
        up, brake = rng.uniform(2.0, 4.0), rng.uniform(1.5, 2.5)
        knots += [(tc, rng.uniform(3.0, 6.0)), (tc + up, 0.0),
                  (tc + up + rng.uniform(1.0, 2.0), -rng.uniform(5.0, 8.0)),
                  (tc + up + 2.0 + brake, 0.0)]
        tc += up + 2.0 + brake + rng.uniform(1.0, 2.0)
    a = _smooth_profile(t, knots, rise=0.3)
    a = _keep_positive(t, a, _integrate(t, a, 0.0), v0=20.0)
    pitch = np.polyval(pitch_poly, a) + rng.normal(0.0, 0.1, t.size)
    return drive(t, a, 20.0, rng=rng, lag=lag, pitch_deg=pitch, source="sim/gps/motorcycle",
                 **kw)


#: Scenario name -> generator ``f(rng, **kw) -> Recording`` (for registration by sim/).
SCENARIOS: dict[str, Callable[..., Recording]] = {
    "gps_braking": braking,
    "gps_tunnel": tunnel,
    "gps_hilly": hilly,
    "gps_jump": gps_jump,
    "gps_motorcycle": motorcycle,
}


def scenario(name: str, rng: np.random.Generator, **kw) -> Recording:
    """Recording of scenario ``name`` (a key of :data:`SCENARIOS`)."""
    try:
        f = SCENARIOS[name]
    except KeyError:
        raise ParameterError(
            f"unknown GPS scenario '{name}' (choose from: {', '.join(SCENARIOS)})"
        ) from None
    return f(rng, **kw)


# -- outages, receiver jumps and weak sky for any simulated drive --------------------------------

def outage_gps(
    *,
    lag: GpsLagModel | None = None,
    rate: float = 10.0,
    noise: float = 0.1,
    tunnels: int = 1,
    tunnel_duration: tuple[float, float] = (30.0, 180.0),
    tunnel_speed: tuple[float, float] = (10.0, 30.0),
    tunnel_after: float = 60.0,
    jumps: int = 2,
    jump_size: tuple[float, float] = (2.0, 5.0),
    low_sats: int = 2,
    low_duration: tuple[float, float] = (5.0, 20.0),
    low_noise: float = 0.5,
):
    """A ``gps_model`` for :func:`vibrospeed.sim.simulate` (e.g. ``simulate("random", seed=N,
    gps_model=outage_gps())``): the receiver of this module (lag model ``lag``, default the
    paper's eq. 3-4, fixes at ``rate`` Hz, white noise ``noise`` m/s) with

    * ``tunnels`` outages of ``tunnel_duration`` s (uniform) starting where the true speed lies
      in ``tunnel_speed`` m/s, no earlier than ``tunnel_after`` s into the drive (anywhere after
      it if the drive never reaches that speed): no fix, 0 satellites;
    * ``jumps`` receiver jumps (paper section VI-c): the reported speed is off by
      ``jump_size`` m/s (uniform, random sign) for 0.4-1 s, raised-cosine edges of 0.1 s;
    * ``low_sats`` weak-sky periods of ``low_duration`` s with 4-6 satellites (below the usual
      gate of 7) and ``low_noise`` m/s extra noise.

    ``gps_sats`` is given on every sample (8-12 with a clear sky), ``gps_speed`` at fixes only.
    The draws come from the simulator's own GPS stream, so the rest of the drive is the same
    recording as without GPS. Tunnels do not overlap each other (a tunnel that cannot be placed
    is left out).
    """
    lag = lag or GpsLagModel.paper()

    def gps_model(t: np.ndarray, speed: np.ndarray, rng: np.random.Generator):
        n = t.size
        rx = simulate_receiver(t, speed, lag)
        idx = _fix_indices(t, rate, rng, 0.002)
        sats = np.round(rng.uniform(8.0, 12.0) + np.clip(
            np.cumsum(rng.normal(0.0, 0.02, n)), -2.0, 2.0))
        err = np.zeros(n)
        extra = np.zeros(n)
        blocked = np.zeros(n, dtype=bool)
        for _ in range(tunnels):
            d = float(rng.uniform(*tunnel_duration))
            ok = ((speed >= tunnel_speed[0]) & (speed <= tunnel_speed[1])
                  & (t >= t[0] + tunnel_after) & (t + d <= t[-1]))
            cand = np.flatnonzero(ok & ~blocked)
            if cand.size == 0:
                cand = np.flatnonzero((t >= t[0] + tunnel_after) & (t + d <= t[-1]) & ~blocked)
            if cand.size == 0:
                continue
            t0 = float(t[cand[rng.integers(cand.size)]])
            inside = (t >= t0) & (t < t0 + d)
            if np.any(blocked & inside):
                continue
            blocked |= inside
        for _ in range(jumps):
            t0 = float(rng.uniform(t[0], t[-1]))
            d = float(rng.uniform(0.4, 1.0))
            amp = float(rng.uniform(*jump_size)) * float(rng.choice([-1.0, 1.0]))
            err += amp * _smooth_profile(t, [(t0, 1.0), (t0 + d, 0.0)], rise=0.1)
        for _ in range(low_sats):
            t0 = float(rng.uniform(t[0], t[-1]))
            d = float(rng.uniform(*low_duration))
            weak = (t >= t0) & (t < t0 + d)
            sats[weak] = rng.integers(4, 7)
            extra[weak] = low_noise
        sats[blocked] = 0.0
        gps = np.full(n, np.nan)
        keep = idx[~blocked[idx]]
        gps[keep] = np.maximum(rx[keep] + err[keep] + rng.normal(0.0, 1.0, keep.size)
                               * np.hypot(noise, extra[keep]), 0.0)
        return gps, sats

    gps_model.__name__ = "outage_gps"
    return gps_model
