"""Scenario registry and the built-in scenarios ``cart``, ``car`` and ``validation``.

A scenario is a frozen ``Config`` dataclass (every knob documented, SI units) plus a builder
``build(cfg, rng, *, gps_model) -> Recording``, registered with :func:`register`::

    @register("stop_and_go", StopAndGoConfig)
    def _stop_and_go(cfg, rng, *, gps_model=None):
        profile = build_profile([...], jerk_time=cfg.jerk_time)
        return simulate_drive(profile, rng, duration=cfg.duration, ...)

after which ``simulate("stop_and_go", seed=3, **overrides)`` works and the CLI lists it.
Overrides name ``Config`` fields; nested sensor configs are reached with dots
(``gps.rate_hz=1``, ``vibration.engine.amp=0.1``) and switched with ``gps=off`` / ``gps=on``.
String values (from the command line) are converted to the field's type.
"""

from __future__ import annotations

import dataclasses
import math
import re
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vibrospeed.config import config_from_params, unknown
from vibrospeed.errors import ParameterError
from vibrospeed.sim.drive import simulate_drive
from vibrospeed.sim.knobs import check
from vibrospeed.sim.profile import Segment, SpeedProfile, Turn, build_profile
from vibrospeed.sim.sensors import GpsConfig, GpsModel, ImuConfig, TickConfig, WheelConfig
from vibrospeed.sim.validation import AMPLITUDES, W0, validation_signal
from vibrospeed.sim.vibration import EngineConfig, VibrationConfig
from vibrospeed.types import Recording

Builder = Callable[..., Recording]
#: scenario name -> ``f(*, seed=0, duration=None, fs=100.0, gps_model=None, **overrides)``
SCENARIOS: dict[str, Callable[..., Recording]] = {}
#: scenario name -> its Config dataclass
CONFIGS: dict[str, type] = {}
#: scenario name -> one-line description (first paragraph of the builder's docstring)
DESCRIPTIONS: dict[str, str] = {}

_OFF = ("none", "off", "false", "no", "0", "")
_ON = ("on", "true", "yes", "1", "default")


# -- configuration with nested overrides -----------------------------------------------------
def _sub_type(hint: Any) -> type | None:
    """The dataclass type inside ``X`` or ``X | None``, else None."""
    if dataclasses.is_dataclass(hint):
        return hint
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        for a in typing.get_args(hint):
            if dataclasses.is_dataclass(a):
                return a
    return None


def make_config(cls: type, params: dict[str, Any] | None = None, base: Any = None, *,
                prefix: str = "") -> Any:
    """Instance of dataclass ``cls`` from ``base`` (default ``cls()``) with overrides ``params``.

    Dotted names reach nested dataclass fields; a nested field set to ``off``/``None`` becomes
    None, ``on`` restores its default; unknown names raise :class:`ParameterError`.
    """
    base = cls() if base is None else base
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    plain: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for key, value in (params or {}).items():
        head, _, rest = key.partition(".")
        if head not in names:
            raise unknown(f"{prefix}{key}", cls.__name__, names, near=head)
        sub = _sub_type(hints[head])
        if sub is None:
            if rest:
                raise ParameterError(f"parameter '{prefix}{key}': '{head}' has no sub-parameters")
            plain[head] = value
        elif rest:
            nested.setdefault(head, {})[rest] = value
        else:
            nested.setdefault(head, {})[""] = value
    kw = {f.name: getattr(base, f.name) for f in dataclasses.fields(cls)}
    for head, sub_params in nested.items():
        sub = _sub_type(hints[head])
        current = kw[head]
        if "" in sub_params:
            switch = sub_params.pop("")
            if isinstance(switch, sub):
                current = switch
            elif switch is None or (isinstance(switch, str | bool) and str(switch).lower() in _OFF):
                if type(None) not in typing.get_args(hints[head]):
                    raise ParameterError(f"parameter '{prefix}{head}' cannot be switched off")
                current = None
            elif isinstance(switch, str | bool) and str(switch).lower() in _ON:
                default = getattr(cls(), head)
                current = default if default is not None else sub()
            else:
                raise ParameterError(f"parameter '{prefix}{head}': use on/off or sub-parameters")
        if sub_params:
            current = make_config(sub, sub_params, current if current is not None else sub(),
                                  prefix=f"{prefix}{head}.")
        kw[head] = current
    try:
        cfg = config_from_params(cls, plain, **kw)
    except ParameterError as exc:  # name the knob as it was given: vibration.harmonic_amps
        msg, head = str(exc), "parameter '"
        if prefix and msg.startswith(head):
            raise ParameterError(head + prefix + msg[len(head):]) from None
        raise
    for name in plain:  # NaN is no knob's value: it was NumPy's "lam is NaN" deep in a draw,
        # or silently a NaN segment or rate
        value = getattr(cfg, name)
        items = value if isinstance(value, tuple | list) else (value,)
        if any(isinstance(v, float) and math.isnan(v) for v in items):
            raise ParameterError(f"parameter '{prefix}{name}': NaN is not a value, got "
                                 f"{plain[name]!r}")
    return cfg


def _jsonable(cfg: Any) -> dict:
    return dataclasses.asdict(cfg)


def describe_doc(doc: str | None) -> str:
    """A docstring's first paragraph as one line: its lines joined with single spaces, with
    ``literal`` written `literal` (read in a terminal and as Markdown alike)."""
    para = re.split(r"\n\s*\n", (doc or "").strip(), maxsplit=1)[0]
    return " ".join(para.split()).replace("``", "`")


def _check_common(name: str, cfg: Any) -> None:
    """Refuse a ``wheel_radius``, ``fs`` or ``duration`` field that is not finite and > 0
    before the builder draws the profile from it: a negative radius made the cart scenarios'
    segment loop run forever (a negative cruise speed) and the car's draw fail inside NumPy
    (``high - low < 0``); :func:`~vibrospeed.sim.drive.simulate_drive` checks them only after
    the profile is built. ``fs`` = 0 means "drawn" where the scenario says so (``random``)."""
    for knob, unit, zero_ok in (("wheel_radius", "m", False), ("duration", "s", False),
                                ("fs", "Hz", name == "random")):
        v = getattr(cfg, knob, None)
        if v is None or (zero_ok and v == 0):
            continue
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(f"sim:{name}: {knob} must be > 0 {unit}, got {v}")


def register(name: str, config_cls: type) -> Callable[[Builder], Builder]:
    """Decorator adding a scenario builder to :data:`SCENARIOS` (see module docstring)."""

    def deco(build: Builder) -> Builder:
        def scenario(
            *,
            seed: int = 0,
            duration: float | None = None,
            fs: float | None = None,
            gps_model: GpsModel | None = None,
            **overrides: Any,
        ) -> Recording:
            params = dict(overrides)
            if fs is not None:
                params["fs"] = fs
            if duration is not None:
                params["duration"] = duration
            cfg = make_config(config_cls, params)
            _check_common(name, cfg)
            rec = build(cfg, np.random.default_rng(seed), gps_model=gps_model)
            rec.meta.update(scenario=name, seed=seed, config=_jsonable(cfg))
            rec.source = f"sim:{name}(seed={seed})"
            return rec

        DESCRIPTIONS[name] = describe_doc(build.__doc__ or config_cls.__doc__)
        scenario.__name__ = f"scenario_{name}"
        scenario.__doc__ = f"Simulate scenario '{name}'; knobs: :class:`{config_cls.__name__}`."
        SCENARIOS[name] = scenario
        CONFIGS[name] = config_cls
        return build

    return deco


def simulate(
    name: str,
    *,
    seed: int = 0,
    duration: float | None = None,
    fs: float | None = None,
    gps_model: GpsModel | None = None,
    **overrides: Any,
) -> Recording:
    """Simulate the registered scenario ``name`` -> :class:`~vibrospeed.types.Recording`.

    ``seed`` fixes every random draw (same seed, same recording); ``duration`` (s) defaults to
    the scenario's; ``fs`` Hz (None: the scenario's, 100 Hz for most); ``gps_model`` replaces
    the built-in GPS; ``overrides`` set fields
    of the scenario's Config (see :data:`CONFIGS`), dotted for nested ones.

    Examples
    --------
    >>> rec = simulate("cart", seed=1, duration=20)
    >>> rec.wheel_radius, round(rec.fs)
    (0.08, 100)
    """
    try:
        fn = SCENARIOS[name]
    except KeyError:
        raise ParameterError(
            f"unknown scenario '{name}' (choose from: {', '.join(sorted(SCENARIOS))})"
        ) from None
    kw = {} if fs is None else {"fs": fs}
    return fn(seed=seed, duration=duration, gps_model=gps_model, **kw, **overrides)


# -- random drive helpers -------------------------------------------------------------------
def random_turns(profile: SpeedProfile, rng: np.random.Generator, *, duration: float,
                 rate_per_min: float, turn_duration: tuple[float, float], lat_accel_max: float,
                 curvature_max: float) -> tuple[Turn, ...]:
    """Poisson-placed turns; peak curvature limited so that ``kappa v^2 <= lat_accel_max``."""
    if rate_per_min <= 0:
        return ()
    count = rng.poisson(rate_per_min * duration / 60.0)
    starts = np.sort(rng.uniform(profile.t0, profile.t0 + duration, count))
    lengths = rng.uniform(turn_duration[0], turn_duration[1], count)
    signs = rng.choice([-1.0, 1.0], count)
    turns = []
    for t_s, d, sg in zip(starts, lengths, signs, strict=True):
        vmax = float(np.max(profile.speed(np.linspace(t_s, t_s + d, 50))))
        if vmax <= 0:
            continue
        kappa = min(curvature_max, lat_accel_max / vmax**2)
        turns.append(Turn(float(t_s), float(d), float(sg * kappa)))
    return tuple(turns)


def random_segments(rng: np.random.Generator, *, duration: float, speed_range: tuple[float, float],
                    cruise_time: tuple[float, float], stop_time: tuple[float, float],
                    p_stop: float, initial_stop: float, accel: tuple[float, float],
                    decel: tuple[float, float], wander: float = 0.0,
                    wander_accel: float = 0.2) -> list[Segment]:
    """Random stop / start / cruise / accelerate / brake sequence covering ``duration`` s.

    With ``wander`` > 0 (m/s) a cruise is split into holds of 2..5 s joined by small speed
    changes (target = cruise speed + N(0, wander^2), at ``wander_accel`` m/s^2), as a driver
    never holds a speed exactly.
    """
    segs: list[Segment] = []
    t = 0.0
    if initial_stop > 0:
        segs.append(Segment("stop", duration=initial_stop))
        t += initial_stop
    v = rng.uniform(*speed_range)
    a = rng.uniform(*accel)
    segs.append(Segment("start", speed=v, accel=a))
    t += v / a
    while t < duration:
        c = rng.uniform(*cruise_time)
        if wander > 0:
            base, left = v, c
            while left > 0:
                hold = min(left, rng.uniform(2.0, 5.0))
                segs.append(Segment("cruise", duration=hold))
                left -= hold
                if left <= 0:
                    break
                target = max(base + rng.normal(0.0, wander), 0.5 * base)
                kind = "accelerate" if target >= v else "brake"
                segs.append(Segment(kind, speed=target, accel=wander_accel))
                left -= abs(target - v) / wander_accel
                v = target
        else:
            segs.append(Segment("cruise", duration=c))
        t += c
        if t >= duration:
            break
        if rng.uniform() < p_stop:
            d = rng.uniform(*decel)
            s = rng.uniform(*stop_time)
            v_new = rng.uniform(*speed_range)
            a = rng.uniform(*accel)
            segs += [Segment("brake", speed=0.0, accel=d), Segment("stop", duration=s),
                     Segment("start", speed=v_new, accel=a)]
            t += v / d + s + v_new / a
        else:
            v_new = rng.uniform(*speed_range)
            if v_new >= v:
                a = rng.uniform(*accel)
                segs.append(Segment("accelerate", speed=v_new, accel=a))
            else:
                a = rng.uniform(*decel)
                segs.append(Segment("brake", speed=v_new, accel=a))
            t += abs(v_new - v) / a
        v = v_new
    return segs


# -- cart -----------------------------------------------------------------------------------
def _cart_vibration() -> VibrationConfig:
    return VibrationConfig(
        harmonic_amps=(0.25, 0.2, 0.1), omega_ref=10.0, gamma=1.0, axis_gain=(0.3, 1.0, 0.5),
        amp_log_std=0.2, amp_tau=5.0, fade_rate=0.3, fundamental_fade_rate=0.5,
        fade_duration=(2.0, 6.0), fade_depth=0.0, resonance_freqs=(13.0,), resonance_q=20.0,
        resonance_amp=0.03, road_noise=0.05, v_ref=0.8, road_gamma=1.0, road_floor=0.0,
        engine=None,
    )


@dataclass(frozen=True)
class CartConfig:
    """Thesis-like shelf cart pushed along a corridor (thesis ch. 3: ~10 rad/s, r = 0.08 m).

    The lateral axis y carries the wheel vibrations (M = 3 harmonics, the first two strong).
    """

    duration: float = 120.0
    """s, length of the recording."""
    fs: float = 100.0
    """Hz, IMU sample rate (thesis: 100 Hz)."""
    wheel_radius: float = 0.08
    """m, cart wheel radius (thesis: 0.08 m)."""
    omega_cruise: float = 10.0
    """rad/s, mean cruise wheel speed (thesis: about 10 rad/s)."""
    omega_spread: float = 1.0
    """rad/s, cruise wheel speeds are drawn from omega_cruise +- omega_spread."""
    cruise_time: tuple[float, float] = (8.0, 20.0)
    """s, uniform range of a cruise segment's length."""
    stop_time: tuple[float, float] = (2.0, 5.0)
    """s, uniform range of a stop's length."""
    p_stop: float = 0.5
    """Probability that a cruise ends in a stop (else a small speed change)."""
    initial_stop: float = 3.0
    """s, standstill at the beginning."""
    accel: tuple[float, float] = (0.3, 0.6)
    """m/s^2, range of the magnitude of pushing accelerations."""
    decel: tuple[float, float] = (0.4, 0.8)
    """m/s^2, range of the magnitude of braking decelerations."""
    jerk_time: float = 0.4
    """s, ramp time of every acceleration change (jerk = delta a / jerk_time)."""
    speed_wander: float = 0.02
    """m/s, std of the small speed changes within a cruise (0: constant cruise speed)."""
    wander_accel: float = 0.05
    """m/s^2, acceleration of those small changes."""
    turn_rate: float = 0.0
    """Turns per minute (0: straight corridor)."""
    turn_duration: tuple[float, float] = (2.0, 5.0)
    """s, uniform range of a turn's length."""
    lat_accel_max: float = 0.5
    """m/s^2, peak lateral acceleration in turns."""
    curvature_max: float = 1.0
    """1/m, sharpest turn (radius 1 m)."""
    vibration: VibrationConfig = field(default_factory=_cart_vibration)
    """Vibration model (harmonics on y, shelf resonance at 13 Hz, no engine)."""
    imu: ImuConfig = field(default_factory=ImuConfig)
    """IMU noise and biases."""
    ticks: TickConfig | None = field(default_factory=lambda: TickConfig(n_cogs=12, radius=0.0625))
    """Cog-wheel ticks (thesis appendix B: 12 cogs on a 0.0625 m wheel); None: off."""
    wheels: WheelConfig | None = None
    """Four wheel-speed channels; None: off."""
    gps: GpsConfig | None = None
    """Built-in GPS; None: off (indoors)."""

    def __post_init__(self) -> None:
        check_drive(self)


def check_drive(cfg: Any) -> None:
    """The knobs the cart and car scenarios share (:func:`vibrospeed.sim.knobs.check`)."""
    check(cfg, positive=("wander_accel", "lat_accel_max", "curvature_max"),
          nonnegative=("initial_stop", "speed_wander", "turn_rate", "jerk_time"),
          fractions=("p_stop",),
          intervals=("cruise_time", "stop_time", "accel", "decel", "turn_duration"))


def _drive(cfg, rng: np.random.Generator, gps_model, segments: list[Segment], name: str,
           grade=None) -> Recording:
    prof_rng, turn_rng, sensor_rng = rng.spawn(3)
    profile = build_profile(segments, jerk_time=cfg.jerk_time)
    turns = random_turns(profile, turn_rng, duration=cfg.duration, rate_per_min=cfg.turn_rate,
                         turn_duration=cfg.turn_duration, lat_accel_max=cfg.lat_accel_max,
                         curvature_max=cfg.curvature_max)
    profile = profile.with_turns(turns)
    return simulate_drive(
        profile, sensor_rng, duration=cfg.duration, fs=cfg.fs, wheel_radius=cfg.wheel_radius,
        vibration_cfg=cfg.vibration, imu=cfg.imu, ticks=cfg.ticks, wheels=cfg.wheels,
        gps=cfg.gps, gps_model=gps_model, grade=grade, source=f"sim:{name}",
    )


@register("cart", CartConfig)
def _cart(cfg: CartConfig, rng: np.random.Generator, *, gps_model=None) -> Recording:
    seg_rng, drive_rng = rng.spawn(2)
    r = cfg.wheel_radius
    lo, hi = cfg.omega_cruise - cfg.omega_spread, cfg.omega_cruise + cfg.omega_spread
    if not 0 < lo <= hi:
        raise ParameterError("cart: need 0 < omega_cruise - omega_spread")
    segs = random_segments(seg_rng, duration=cfg.duration, speed_range=(lo * r, hi * r),
                           cruise_time=cfg.cruise_time, stop_time=cfg.stop_time,
                           p_stop=cfg.p_stop, initial_stop=cfg.initial_stop, accel=cfg.accel,
                           decel=cfg.decel, wander=cfg.speed_wander,
                           wander_accel=cfg.wander_accel)
    return _drive(cfg, drive_rng, gps_model, segs, "cart")


# -- car ------------------------------------------------------------------------------------
def _car_vibration() -> VibrationConfig:
    return VibrationConfig(
        harmonic_amps=(0.08, 0.06, 0.04), omega_ref=60.0, gamma=1.0, axis_gain=(0.5, 1.0, 0.8),
        amp_log_std=0.3, amp_tau=4.0, fade_rate=0.5, fundamental_fade_rate=1.0,
        fade_duration=(2.0, 10.0), fade_depth=0.0, resonance_freqs=(11.5, 14.0, 16.5),
        resonance_q=15.0, resonance_amp=0.03, road_noise=0.08, v_ref=20.0, road_gamma=1.0,
        road_floor=0.1, engine=EngineConfig(),
    )


@dataclass(frozen=True)
class CarConfig:
    """Passenger car on roads: starts, accelerations, braking, stops and turns.

    Wheel speeds 10..120 rad/s (3..37 m/s) while moving; lateral axis y carries the vibrations
    (as in the chassis-vibration paper); engine-order line with gear shifts; 4 wheel speeds, cog
    ticks and GPS on by default.
    """

    duration: float = 300.0
    """s, length of the recording."""
    fs: float = 100.0
    """Hz, IMU sample rate (paper: 100 Hz)."""
    wheel_radius: float = 0.31
    """m, tyre rolling radius."""
    omega_range: tuple[float, float] = (10.0, 120.0)
    """rad/s, range from which cruise wheel speeds are drawn."""
    cruise_time: tuple[float, float] = (5.0, 30.0)
    """s, uniform range of a cruise segment's length."""
    stop_time: tuple[float, float] = (3.0, 12.0)
    """s, uniform range of a stop's length."""
    p_stop: float = 0.25
    """Probability that a cruise ends in a stop (else a change of speed)."""
    initial_stop: float = 5.0
    """s, standstill at the beginning (engine idling)."""
    accel: tuple[float, float] = (0.8, 2.5)
    """m/s^2, range of acceleration magnitudes."""
    decel: tuple[float, float] = (1.0, 4.0)
    """m/s^2, range of braking magnitudes."""
    jerk_time: float = 0.6
    """s, ramp time of every acceleration change."""
    speed_wander: float = 0.3
    """m/s, std of the small speed changes within a cruise (0: constant cruise speed)."""
    wander_accel: float = 0.2
    """m/s^2, acceleration of those small changes."""
    turn_rate: float = 1.5
    """Turns per minute of recording."""
    turn_duration: tuple[float, float] = (3.0, 8.0)
    """s, uniform range of a turn's length."""
    lat_accel_max: float = 3.0
    """m/s^2, peak lateral acceleration in turns."""
    curvature_max: float = 0.1
    """1/m, sharpest turn (radius 10 m)."""
    vibration: VibrationConfig = field(default_factory=_car_vibration)
    """Vibration model (3 harmonics, body resonances 11.5/14/16.5 Hz, engine order 1)."""
    imu: ImuConfig = field(default_factory=lambda: ImuConfig(accel_noise=0.03))
    """IMU noise and biases."""
    ticks: TickConfig | None = field(default_factory=lambda: TickConfig(n_cogs=48))
    """Wheel-speed sensor tone ring on the reference wheel; None: off."""
    wheels: WheelConfig | None = field(default_factory=WheelConfig)
    """Four wheel-speed channels; None: off."""
    gps: GpsConfig | None = field(default_factory=GpsConfig)
    """Built-in GPS (10 Hz, 0.4 s first-order lag); None: off."""

    def __post_init__(self) -> None:
        check_drive(self)


@register("car", CarConfig)
def _car(cfg: CarConfig, rng: np.random.Generator, *, gps_model=None) -> Recording:
    seg_rng, drive_rng = rng.spawn(2)
    r = cfg.wheel_radius
    lo, hi = cfg.omega_range
    if not 0 < lo <= hi:
        raise ParameterError("car: need 0 < omega_range[0] <= omega_range[1]")
    segs = random_segments(seg_rng, duration=cfg.duration, speed_range=(lo * r, hi * r),
                           cruise_time=cfg.cruise_time, stop_time=cfg.stop_time,
                           p_stop=cfg.p_stop, initial_stop=cfg.initial_stop, accel=cfg.accel,
                           decel=cfg.decel, wander=cfg.speed_wander,
                           wander_accel=cfg.wander_accel)
    return _drive(cfg, drive_rng, gps_model, segs, "car")


# -- validation -----------------------------------------------------------------------------
@dataclass(frozen=True)
class ValidationConfig:
    """Thesis eq. 2.6 benchmark signal on ``ay`` with constant truth ``omega_true = omega0``."""

    duration: float = 60.0
    """s, length of the signal."""
    fs: float = 100.0
    """Hz, sample rate (thesis: 100 Hz)."""
    omega0: float = W0
    """rad/s, fundamental (thesis eq. 2.2: 1.45 * 2 pi = 9.11 rad/s)."""
    amplitudes: tuple[float, ...] = AMPLITUDES
    """Amplitudes A_n (thesis eq. 2.4: 0.4 + n/10)."""
    amp_noise: float = 0.2
    """Half-width of the uniform amplitude noise e_k1."""
    phase_var: float = 0.01
    """Variance of the phase noise e_k2 (rad^2)."""
    noise_var: float = 0.04
    """Variance of the additive noise e_k3."""
    shared_noise: bool = True
    """One e_k1, e_k2 per sample for all harmonics (the thesis' indexing)."""
    wheel_radius: float = 0.08
    """m, nominal radius used for speed_true (the thesis cart's)."""


@register("validation", ValidationConfig)
def _validation(cfg: ValidationConfig, rng: np.random.Generator, *, gps_model=None) -> Recording:
    if gps_model is not None:
        raise ParameterError("validation: scenario has no GPS")
    n = int(round(cfg.duration * cfg.fs))
    t, y = validation_signal(n, rng, cfg.fs, omega0=cfg.omega0, amplitudes=cfg.amplitudes,
                             amp_noise=cfg.amp_noise, phase_var=cfg.phase_var,
                             noise_var=cfg.noise_var, shared_noise=cfg.shared_noise)
    omega = np.full(n, float(cfg.omega0))
    return Recording(t=t, channels={"ay": y, "omega_true": omega,
                                    "speed_true": cfg.wheel_radius * omega},
                     source="sim:validation", wheel_radius=float(cfg.wheel_radius),
                     notes=["thesis eq. 2.6 validation signal on ay"])
