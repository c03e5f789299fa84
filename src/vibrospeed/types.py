"""Shared value types: :class:`Recording` (sensor data), :class:`Track` (an estimate over
time) and :class:`Estimate` (every estimator's ``step`` output for one sample).

Canonical channel names and their units are fixed here (pyins-style column constants); readers
map whatever a file calls its columns onto these names and convert to SI.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any, NamedTuple

import numpy as np

from vibrospeed.errors import InputError, ParameterError

#: Canonical channels and their SI units. ``t`` (s) is the time line itself, not a channel.
CHANNEL_UNITS: dict[str, str] = {
    "ax": "m/s^2",  # longitudinal acceleration (forward +)
    "ay": "m/s^2",  # lateral acceleration
    "az": "m/s^2",  # vertical acceleration (up +, includes +g when at rest)
    "gx": "rad/s",  # roll rate
    "gy": "rad/s",  # pitch rate
    "gz": "rad/s",  # yaw rate
    "gps_speed": "m/s",  # ground speed from GNSS, NaN where no fix
    "gps_sats": "1",  # satellites used in the fix
    "wheel_omega_fl": "rad/s",
    "wheel_omega_fr": "rad/s",
    "wheel_omega_rl": "rad/s",
    "wheel_omega_rr": "rad/s",
    "omega_true": "rad/s",  # ground-truth wheel angular speed
    "speed_true": "m/s",  # ground-truth vehicle speed
    "vy_true": "m/s",  # ground-truth lateral velocity (vehicle simulator)
    "accel_true": "m/s^2",  # ground-truth longitudinal acceleration (simulator)
    "yaw_rate_true": "rad/s",  # ground-truth yaw rate (simulator)
    "grade_true": "rad",  # ground-truth road grade (simulator)
    "speed_pose": "m/s",  # speed from a localisation pose (reference, not truth-grade)
    "speed_odom": "m/s",  # odometry speed reported by the vehicle
}
#: Irregular event streams (timestamps in s) kept beside the sampled channels.
EVENT_UNITS: dict[str, str] = {"wss_ticks": "s"}

ACCEL_CHANNELS = ("ax", "ay", "az")
GYRO_CHANNELS = ("gx", "gy", "gz")
WHEEL_CHANNELS = ("wheel_omega_fl", "wheel_omega_fr", "wheel_omega_rl", "wheel_omega_rr")
TRUTH_CHANNELS = (
    "omega_true", "speed_true", "vy_true", "accel_true", "yaw_rate_true", "grade_true",
)


@dataclass
class Recording:
    """Time-stamped sensor channels on one time line.

    Attributes
    ----------
    t : (n,) float64, s, strictly increasing (not necessarily uniform).
    channels : name -> (n,) float64 in SI units; NaN marks a missing sample.
    units : name -> unit string (defaults from :data:`CHANNEL_UNITS`).
    events : name -> (k,) float64 event times in s (e.g. ``wss_ticks`` cog timestamps).
    source : file or scenario the data came from.
    wheel_radius : m, if known.
    axes : description of the axis convention (e.g. "x fwd, y left, z up").
    notes : human-readable list of what readers / pre-processing did (resampling, gaps...).
    meta : free-form extra metadata (simulator parameters, reader options...).
    """

    t: np.ndarray
    channels: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    events: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    wheel_radius: float | None = None
    axes: str = "x longitudinal (forward +), y lateral, z vertical (up +)"
    notes: list[str] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.t = np.ascontiguousarray(self.t, dtype=np.float64)
        if self.t.ndim != 1:
            raise InputError(f"{self.source or 'recording'}: time must be 1-D")
        n = self.t.size
        chans = {}
        for name, x in self.channels.items():
            x = np.ascontiguousarray(x, dtype=np.float64)
            if x.shape != (n,):
                raise InputError(
                    f"{self.source or 'recording'}: channel '{name}' has shape {x.shape}, "
                    f"expected ({n},) like t"
                )
            chans[name] = x
            self.units.setdefault(name, CHANNEL_UNITS.get(name, ""))
        self.channels = chans
        self.events = {k: np.sort(np.asarray(v, dtype=np.float64)) for k, v in self.events.items()}

    # -- basic properties -------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.t.size)

    def __contains__(self, name: str) -> bool:
        return name in self.channels

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channel(name)

    @property
    def duration(self) -> float:
        """Time span in s."""
        return float(self.t[-1] - self.t[0]) if self.t.size > 1 else 0.0

    @property
    def dt(self) -> float:
        """Median sample period in s (robust to jitter and gaps)."""
        if self.t.size < 2:
            raise InputError(f"{self.source or 'recording'}: fewer than 2 samples")
        return float(np.median(np.diff(self.t)))

    @property
    def fs(self) -> float:
        """Sample rate in Hz from the median period."""
        return 1.0 / self.dt

    def is_uniform(self, rtol: float = 1e-3) -> bool:
        """True if every period is within ``rtol`` of the median period."""
        d = np.diff(self.t)
        return bool(d.size == 0 or np.all(np.abs(d - np.median(d)) <= rtol * np.median(d)))

    def channel(self, name: str) -> np.ndarray:
        """Channel by canonical name, with a clear error naming the file if it is missing."""
        try:
            return self.channels[name]
        except KeyError:
            have = ", ".join(sorted(self.channels)) or "none"
            raise InputError(
                f"{self.source or 'recording'}: channel '{name}' is missing (have: {have})"
            ) from None

    def require(self, *names: str, allow_nan: bool = True) -> None:
        """Raise :class:`InputError` unless every named channel exists and is not all-NaN."""
        for name in names:
            x = self.channel(name)
            if x.size and not np.any(np.isfinite(x)):
                raise InputError(f"{self.source or 'recording'}: channel '{name}' is all NaN")
            if not allow_nan and not np.all(np.isfinite(x)):
                bad = int(np.flatnonzero(~np.isfinite(x))[0])
                raise InputError(
                    f"{self.source or 'recording'}: channel '{name}' has NaN at sample {bad}"
                )

    def with_channels(self, **channels: np.ndarray) -> Recording:
        """Copy with channels added or replaced."""
        new = dict(self.channels)
        new.update(channels)
        return replace(self, channels=new, units=dict(self.units), notes=list(self.notes))

    def slice_time(self, t0: float | None = None, t1: float | None = None) -> Recording:
        """Copy restricted to ``t0 <= t < t1``."""
        lo = -np.inf if t0 is None else t0
        hi = np.inf if t1 is None else t1
        keep = (self.t >= lo) & (self.t < hi)
        return replace(
            self,
            t=self.t[keep],
            channels={k: v[keep] for k, v in self.channels.items()},
            units=dict(self.units),
            events={k: v[(v >= lo) & (v < hi)] for k, v in self.events.items()},
            notes=list(self.notes),
        )


def check_wheel_radius(value: Any, name: str = "wheel_radius") -> float | None:
    """``value`` as a wheel radius in m: None (not known) passes; a finite number > 0 is
    returned as float; anything else (nan, inf, 0, a negative number, text that is not a
    number) is a :class:`ParameterError` naming ``name`` and the value. ``speed = r * omega``
    needs ``r > 0``, and the sidecar's JSON cannot hold nan or inf; the estimate entry points
    (:class:`vibrospeed.batch.EstimateOptions`, the streamed grid estimate) call this before
    they read or write anything, :func:`vibrospeed.io.write_track` before it writes."""
    if value is None:
        return None
    try:
        r = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number in m, got {value!r}") from None
    if not (math.isfinite(r) and r > 0):
        raise ParameterError(f"{name} must be a finite number > 0 m, got {r:g}")
    return r


def _radius(wheel_radius) -> float:
    """m, the radius a Track converts with: NaN where it is not known (None or 0), else
    :func:`check_wheel_radius` (nan, inf or a negative radius is a ParameterError)."""
    return check_wheel_radius(wheel_radius) if wheel_radius else np.nan


def _with_band(x, std, lo, hi, level: float):
    """Arrays ``(x, std, lo, hi)``; a missing band is ``x -+ z std`` for the level's quantile."""
    x = np.asarray(x, float)
    std = np.full_like(x, np.nan) if std is None else np.asarray(std, float)
    from statistics import NormalDist  # here: `import vibrospeed` stays light

    z = NormalDist().inv_cdf(0.5 + level / 2.0)  # the standard normal quantile
    # omega and speed are magnitudes: a Gaussian band is cut at 0 below an estimate >= 0
    lo = np.where(x >= 0, np.maximum(x - z * std, 0.0), x - z * std) if lo is None \
        else np.asarray(lo, float)
    hi = x + z * std if hi is None else np.asarray(hi, float)
    return x, std, lo, hi


@dataclass
class Track:
    """An estimator's output over time.

    Attributes
    ----------
    t : (n,) s
    omega : (n,) rad/s point estimate (posterior mean unless the method says otherwise).
    omega_std : (n,) rad/s standard deviation (NaN if the method has none).
    omega_lo, omega_hi : (n,) rad/s credible band at probability ``level``.
    speed, speed_lo, speed_hi, speed_std : (n,) m/s; NaN when the wheel radius is unknown and
        the method estimates omega only.
    method : estimator name; params : its parameters (JSON-serialisable).
    extras : name -> (n,) diagnostics (amplitudes, NIS, mode flags...).
    """

    t: np.ndarray
    omega: np.ndarray
    omega_std: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    speed: np.ndarray
    speed_std: np.ndarray
    speed_lo: np.ndarray
    speed_hi: np.ndarray
    method: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    level: float = 0.98
    wheel_radius: float | None = None
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @classmethod
    def from_omega(cls, t, omega, omega_std=None, *, lo=None, hi=None, level: float = 0.98,
                   wheel_radius: float | None = None, **kw) -> Track:
        """Build from an omega estimate (rad/s); the band defaults to ``mean +- z std`` (Gaussian
        quantile for ``level``), its lower edge cut at 0 where the estimate is >= 0 (omega and
        speed are magnitudes); speed = r omega where the radius is known."""
        x, std, lo, hi = _with_band(omega, omega_std, lo, hi, level)
        r = _radius(wheel_radius)
        return cls(np.asarray(t, float), x, std, lo, hi, r * x, r * std, r * lo, r * hi,
                   level=level, wheel_radius=wheel_radius or None, **kw)

    @classmethod
    def from_speed(cls, t, speed, speed_std=None, *, lo=None, hi=None, level: float = 0.98,
                   wheel_radius: float | None = None, **kw) -> Track:
        """Build from a speed estimate (m/s), the band as :meth:`from_omega`'s; omega = speed /
        r where the radius is known."""
        v, std, lo, hi = _with_band(speed, speed_std, lo, hi, level)
        r = _radius(wheel_radius)
        return cls(np.asarray(t, float), v / r, std / r, lo / r, hi / r, v, std, lo, hi,
                   level=level, wheel_radius=wheel_radius or None, **kw)

    def __len__(self) -> int:
        return int(self.t.size)


_NO_EXTRAS: Mapping[str, Any] = MappingProxyType({})


class Estimate(NamedTuple):
    """One sample's estimate: what every estimator's ``step(config, state, sample)`` returns
    (with the next state), the same record for every method.

    omega, omega_std : rad/s, the wheel angular speed and its standard deviation;
    omega_lo, omega_hi : rad/s, the credible band at the method's ``level``;
    speed, speed_std : m/s, for the methods that estimate the vehicle's speed itself
        (``gps-riss``, ``algebraic``);
    has_signal : 1.0 where the method sees a wheel line, 0.0 where it does not;
    standstill : 1.0 where the method decides the vehicle stands, else 0.0;
    extras : method-specific values by name (e.g. the grid's ``p_null``, ``posterior``), also
        readable as attributes (``est.p_null``).

    A quantity the method does not provide is NaN (``extras``: absent). Each name matches the
    column of the method's ``run`` result or Track of the same name.
    """

    omega: float = math.nan
    omega_std: float = math.nan
    omega_lo: float = math.nan
    omega_hi: float = math.nan
    speed: float = math.nan
    speed_std: float = math.nan
    has_signal: float = math.nan
    standstill: float = math.nan
    extras: Mapping[str, Any] = _NO_EXTRAS

    def __getattr__(self, name: str) -> Any:
        # only called for names that are not fields: the method-specific extras
        if name.startswith("__"):
            raise AttributeError(name)
        try:
            return tuple.__getitem__(self, 8)[name]
        except KeyError:
            raise AttributeError(f"Estimate has no field or extra '{name}'") from None
