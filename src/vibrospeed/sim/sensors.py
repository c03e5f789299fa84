"""Sensor models of the simulator: IMU, wheel-speed cog ticks, four wheel speeds, a simple GPS.

GPS hook
--------
Any callable with the :class:`GpsModel` signature can replace the built-in
:func:`simple_gps` (``simulate(..., gps_model=f)``; e.g. the paper's second-order lag model of
``vibrospeed.sim.gps``)::

    f(t, speed_true, rng) -> (gps_speed, gps_sats)

``t`` (n,) s, ``speed_true`` (n,) m/s, ``rng`` a :class:`numpy.random.Generator` reserved for the
GPS; both outputs (n,) float64, NaN on samples without a fix.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import signal as sps

from vibrospeed.errors import ParameterError
from vibrospeed.sim.knobs import check

G0 = 9.80665  # m/s^2, standard gravity


class GpsModel(Protocol):
    """Signature of a GPS simulator plugged into :func:`vibrospeed.sim.simulate`."""

    def __call__(
        self, t: np.ndarray, speed: np.ndarray, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class ImuConfig:
    """Accelerometer and gyroscope errors. Biases are constant over a recording."""

    accel_noise: float = 0.02
    """m/s^2, white noise std on each accelerometer axis."""
    accel_bias: tuple[float, float, float] | None = None
    """m/s^2, fixed bias (x, y, z); None draws each from N(0, accel_bias_std^2)."""
    accel_bias_std: float = 0.05
    """m/s^2, std of the drawn accelerometer biases."""
    gyro_noise: float = 0.002
    """rad/s, white noise std on each gyro axis."""
    gyro_bias: tuple[float, float, float] | None = None
    """rad/s, fixed bias (x, y, z); None draws each from N(0, gyro_bias_std^2)."""
    gyro_bias_std: float = 0.002
    """rad/s, std of the drawn gyro biases."""
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """rad, roll, pitch, yaw of the sensor against the vehicle (x-y-z Euler angles): a phone of
    unknown orientation sees every vehicle axis mixed into each of its own."""
    accel_lsb: float = 0.0
    """m/s^2, accelerometer resolution (quantisation step); 0: none."""
    accel_range: float = float("inf")
    """m/s^2, accelerometer full scale: readings are clipped to +-accel_range."""

    def __post_init__(self) -> None:
        # a negative std was NumPy's "scale < 0" deep in the draw; a negative step or full
        # scale silently quantised or clipped every reading to nonsense
        for name in ("accel_noise", "accel_bias_std", "gyro_noise", "gyro_bias_std",
                     "accel_lsb"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"imu.{name} must be finite and >= 0, got {v}")
        if not self.accel_range > 0:
            raise ParameterError(f"imu.accel_range must be > 0 m/s^2 (inf: no clipping), got "
                                 f"{self.accel_range}")


@dataclass(frozen=True)
class TickConfig:
    """Cog-wheel (wheel-speed sensor) tick stream ``wss_ticks``: one event per cog passage."""

    n_cogs: int = 48
    """Cogs per revolution (thesis appendix B: 12; car ABS tone rings: ~48)."""
    radius: float | None = None
    """m, rolling radius of the wheel carrying the cog ring; None: the vehicle's wheel radius.
    The thesis' cart had the cog wheel on a separate 0.0625 m wheel."""
    jitter: float = 0.0
    """s, std of Gaussian timestamp noise added to each tick (0: exact)."""

    def __post_init__(self) -> None:
        check(self, "ticks.", nonnegative=("jitter",))
        if self.radius is not None:
            check(self, "ticks.", positive=("radius",))


@dataclass(frozen=True)
class WheelConfig:
    """Four wheel-speed channels ``wheel_omega_fl/fr/rl/rr`` (rad/s), rigid-body kinematics.

    The reference point (``speed_true``) is the middle of the rear axle. With yaw rate ``psi'``:
    rear wheels ``(v -+ psi' b/2) / r``; front wheels ``sqrt((v -+ psi' b/2)^2 + (psi' L)^2) / r``
    (left -, right +; a left turn has psi' > 0 and the right wheels faster).
    """

    track: float = 1.55
    """m, distance b between left and right wheels."""
    wheelbase: float = 2.7
    """m, distance L between the axles."""
    noise: float = 0.0
    """rad/s, white noise std on each wheel channel."""

    def __post_init__(self) -> None:
        check(self, "wheels.", positive=("track", "wheelbase"), nonnegative=("noise",))


@dataclass(frozen=True)
class GpsConfig:
    """Built-in simple GPS: lagged speed at fixes, noise, outages, satellite count.

    Lag: ``lag_order`` 1: ``tau v_g' = v - v_g``; 2: ``v_g'' = wn^2 (v - v_g) - 2 zeta wn v_g'``
    (zeta < 1 overshoots), discretised by zero-order hold at the IMU rate and started in steady
    state. Fixes at ``rate_hz`` are put on the nearest IMU samples.
    """

    rate_hz: float = 10.0
    """Fix rate (Hz), 1..20 typical."""
    lag_order: int = 1
    """0: no lag; 1: first-order lag (tau); 2: second-order lag (wn, zeta)."""
    tau: float = 0.4
    """s, first-order lag time constant."""
    wn: float = 4.0
    """rad/s, natural frequency of the second-order lag."""
    zeta: float = 0.7
    """Damping ratio of the second-order lag."""
    noise: float = 0.1
    """m/s, white noise std of the reported speed."""
    sats_mean: float = 10.0
    """Mean number of satellites in use with a clear sky."""
    outages: tuple[float, ...] = ()
    """Explicit outages as flat pairs (start, end, start, end, ...) in s: no fix, 0..3 sats."""
    outage_rate: float = 0.0
    """Random outages per minute (Poisson)."""
    outage_duration: tuple[float, float] = (3.0, 15.0)
    """s, uniform range of a random outage's length."""

    def __post_init__(self) -> None:
        if not self.rate_hz > 0:
            raise ParameterError(f"gps.rate_hz must be > 0, got {self.rate_hz}")
        if self.lag_order not in (0, 1, 2):
            raise ParameterError(f"gps.lag_order must be 0, 1 or 2, got {self.lag_order}")
        # a negative noise std was NumPy's "scale < 0"; a negative tau or wn an unstable or
        # frozen receiver; negative counts and rates silently nonsense
        for name, need, ok in (
            ("noise", "finite and >= 0", np.isfinite(self.noise) and self.noise >= 0),
            ("tau", "finite and > 0", self.lag_order != 1 or (np.isfinite(self.tau)
                                                               and self.tau > 0)),
            ("wn", "finite and > 0", self.lag_order != 2 or (np.isfinite(self.wn)
                                                              and self.wn > 0)),
            ("zeta", "finite and >= 0", self.lag_order != 2 or (np.isfinite(self.zeta)
                                                                 and self.zeta >= 0)),
            ("sats_mean", "finite and >= 0",
             np.isfinite(self.sats_mean) and self.sats_mean >= 0),
            ("outage_rate", "finite and >= 0",
             np.isfinite(self.outage_rate) and self.outage_rate >= 0)):
            if not ok:
                raise ParameterError(f"gps.{name} must be {need}, got {getattr(self, name)}")
        if len(self.outages) % 2:
            raise ParameterError("gps.outages: need (start, end) pairs")
        check(self, "gps.", intervals=("outage_duration",))


# -- IMU ---------------------------------------------------------------------------------------
def draw_biases(cfg: ImuConfig, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Constant (3,) accelerometer (m/s^2) and gyro (rad/s) biases, given or drawn."""
    ab = rng.normal(0.0, cfg.accel_bias_std, 3)
    gb = rng.normal(0.0, cfg.gyro_bias_std, 3)
    if cfg.accel_bias is not None:
        ab = np.asarray(cfg.accel_bias, dtype=np.float64)
    if cfg.gyro_bias is not None:
        gb = np.asarray(cfg.gyro_bias, dtype=np.float64)
    return ab, gb


def mount_matrix(mount: tuple[float, float, float]) -> np.ndarray:
    """(3, 3) rotation taking vehicle-frame vectors to the sensor frame, ``R^T`` of
    ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the sensor's axes in vehicle coordinates)."""
    r, p, y = mount
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return (rz @ ry @ rx).T


def digitise(a: np.ndarray, lsb: float, full_scale: float) -> np.ndarray:
    """Readings clipped to ``+-full_scale`` and rounded to multiples of ``lsb`` (0: no rounding)."""
    out = np.clip(a, -full_scale, full_scale)
    if lsb > 0:
        out = np.round(out / lsb) * lsb
    return out


# -- wheels ------------------------------------------------------------------------------------
def wheel_speeds(speed: np.ndarray, yaw_rate: np.ndarray, r: float, cfg: WheelConfig,
                 rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The four ``wheel_omega_*`` channels (rad/s), see :class:`WheelConfig`."""
    half = 0.5 * cfg.track * yaw_rate
    lat = cfg.wheelbase * yaw_rate
    vl, vr = speed - half, speed + half
    out = {
        "wheel_omega_fl": np.hypot(vl, lat) / r,
        "wheel_omega_fr": np.hypot(vr, lat) / r,
        "wheel_omega_rl": vl / r,
        "wheel_omega_rr": vr / r,
    }
    if cfg.noise > 0:
        out = {k: v + rng.normal(0.0, cfg.noise, v.size) for k, v in out.items()}
    return out


def cog_ticks(profile, t: np.ndarray, cfg: TickConfig, wheel_radius: float,
              rng: np.random.Generator) -> np.ndarray:
    """Tick times (s): the cog-ring angle ``x(t) / r_tick`` crosses ``2 pi (k + phi0) / n_cogs``.

    ``profile`` provides the exact distance ``x(t)`` and speed (see
    :meth:`SpeedProfile.crossing_times`); ``phi0 ~ U(0, 1)`` is the ring's initial position.
    """
    if int(cfg.n_cogs) != cfg.n_cogs or cfg.n_cogs < 1:
        raise ParameterError(f"ticks.n_cogs must be a positive integer, got {cfg.n_cogs}")
    r_tick = cfg.radius if cfg.radius is not None else wheel_radius
    step = 2.0 * np.pi * r_tick / cfg.n_cogs  # m travelled between two ticks
    phi0 = rng.uniform()
    x = profile.distance(t[[0, -1]])
    k = np.arange(np.floor(x[0] / step - phi0), np.ceil(x[1] / step - phi0) + 1)
    ticks = profile.crossing_times((k + phi0) * step, t)
    if cfg.jitter > 0:
        ticks = np.sort(ticks + rng.normal(0.0, cfg.jitter, ticks.size))
    return ticks


# -- GPS -----------------------------------------------------------------------------------------
def _lag(t: np.ndarray, v: np.ndarray, cfg: GpsConfig) -> np.ndarray:
    """Receiver speed lag on the IMU sample grid (zero-order hold), steady state at v[0]."""
    if cfg.lag_order == 0:
        return v.copy()
    dt = float(np.median(np.diff(t)))
    if cfg.lag_order == 1:
        A, B = np.array([[-1.0 / cfg.tau]]), np.array([[1.0 / cfg.tau]])
        C = np.array([[1.0]])
    else:
        w2 = cfg.wn**2
        A = np.array([[0.0, 1.0], [-w2, -2.0 * cfg.zeta * cfg.wn]])
        B = np.array([[0.0], [w2]])
        C = np.array([[1.0, 0.0]])
    Ad, Bd, Cd, Dd, _ = sps.cont2discrete((A, B, C, np.zeros((1, 1))), dt, method="zoh")
    b, a = sps.ss2tf(Ad, Bd, Cd, Dd)
    b = np.atleast_1d(np.squeeze(b))
    zi = sps.lfilter_zi(b, a) * v[0]
    return sps.lfilter(b, a, v, zi=zi)[0]


def outage_mask(t: np.ndarray, cfg: GpsConfig, rng: np.random.Generator) -> tuple[np.ndarray,
                                                                                     list]:
    """Boolean (n,) True inside an outage, and the list of (start, end) intervals."""
    spans = [(cfg.outages[i], cfg.outages[i + 1]) for i in range(0, len(cfg.outages), 2)]
    count = rng.poisson(cfg.outage_rate * (t[-1] - t[0]) / 60.0) if cfg.outage_rate > 0 else 0
    starts = rng.uniform(t[0], t[-1], count)
    lengths = rng.uniform(cfg.outage_duration[0], cfg.outage_duration[1], count)
    spans += [(float(s), float(s + d)) for s, d in zip(starts, lengths, strict=True)]
    mask = np.zeros(t.size, dtype=bool)
    for s, e in spans:
        mask |= (t >= s) & (t < e)
    return mask, sorted(spans)


def simple_gps(cfg: GpsConfig, t: np.ndarray, speed: np.ndarray,
               rng: np.random.Generator,
               lag: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
               ) -> tuple[np.ndarray, np.ndarray, list]:
    """Built-in GPS: ``(gps_speed, gps_sats, outages)``; NaN where there is no fix.

    Fix times ``t0 + (k + u) / rate_hz`` (random phase ``u``) go to the nearest samples; the
    reported speed is the lagged true speed plus N(0, noise^2) noise, clipped at 0 (a receiver
    reports a magnitude); ``lag(t, speed) -> lagged speed`` replaces the built-in lag.
    Satellites: a rounded AR(1) walk around ``sats_mean`` (4..20); inside outages 0..3
    satellites and no speed.
    """
    n = t.size
    lagged = _lag(t, speed, cfg) if lag is None else np.asarray(lag(t, speed), dtype=np.float64)
    u = rng.uniform()
    t_fix = t[0] + (np.arange(int(np.floor((t[-1] - t[0]) * cfg.rate_hz)) + 1) + u) / cfg.rate_hz
    t_fix = t_fix[t_fix <= t[-1]]
    idx = np.clip(np.searchsorted(t, t_fix), 1, n - 1)
    idx = np.where(t_fix - t[idx - 1] < t[idx] - t_fix, idx - 1, idx)
    idx = np.unique(idx)
    nf = idx.size
    noise = rng.normal(0.0, cfg.noise, nf)
    walk = sps.lfilter([1.0], [1.0, -0.98], rng.normal(0.0, 0.3, nf))
    sats = np.clip(np.round(cfg.sats_mean + walk), 4, 20)
    mask, spans = outage_mask(t, cfg, rng)
    low = rng.integers(0, 4, nf).astype(np.float64)
    out_fix = mask[idx]
    gps_speed = np.full(n, np.nan)
    gps_sats = np.full(n, np.nan)
    gps_speed[idx] = np.where(out_fix, np.nan, np.maximum(lagged[idx] + noise, 0.0))
    gps_sats[idx] = np.where(out_fix, low, sats)
    return gps_speed, gps_sats, spans


def gps_with_lag(lag: Callable[[np.ndarray, np.ndarray], np.ndarray],
                 cfg: GpsConfig | None = None) -> GpsModel:
    """A :class:`GpsModel`: the built-in fixes/noise/outages/satellites around your own lag.

    Example (the paper's second-order receiver model)::

        from vibrospeed.models.gps_riss import GpsLagModel, simulate_receiver
        model = gps_with_lag(lambda t, v: simulate_receiver(t, v, GpsLagModel.paper()))
        rec = simulate("car", seed=1, gps_model=model)
    """
    cfg = GpsConfig() if cfg is None else cfg

    def gps_model(t: np.ndarray, speed: np.ndarray, rng: np.random.Generator):
        gs, sats, _ = simple_gps(cfg, t, speed, rng, lag=lag)
        return gs, sats

    gps_model.__name__ = f"gps_with_lag({getattr(lag, '__name__', 'lag')})"
    return gps_model
