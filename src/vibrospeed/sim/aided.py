"""Simulator scenarios that stress inertial-aided tracking (thesis ch. 3, 4.2.4).

Shelf-cart drives in the thesis' setting (wheel radius 0.08 m, about 10 rad/s, 100 Hz, the
vibrations on the lateral axis y, the speed changes on the longitudinal axis x), built from the
simulator's blocks (:func:`vibrospeed.sim.profile.build_profile`,
:func:`vibrospeed.sim.drive.simulate_drive`):

=================== ============================================================================
``start_from_rest`` standstill, push to cruise speed, cruise
``stop_and_go``     repeated start -> cruise -> brake -> stop
``sudden_change``   cruise, a quick speed change in the middle of the drive (up, later down),
                    brake to a stop at the end (thesis fig. 3.1c)
``bumpy_floor``     cruise over floor bumps: each bump hits ``az`` twice, front axle then rear
                    axle ``wheelbase / v`` later (thesis 4.2.4, eq. 4.2); bump times in ``meta``
``turns``           cruise with steady turns: ``ay = v * yaw_rate``, ``gz = yaw_rate``
                    (thesis eq. 4.3)
=================== ============================================================================

Every function has the signature ``f(seed=0, duration=None, fs=100.0, **overrides) ->
Recording`` (overrides name :class:`AidedConfig` fields, dotted for nested sensor configs, as
:func:`vibrospeed.sim.scenarios.make_config`); the Recording carries ``ax ay az gx gy gz``,
truth ``omega_true``, ``speed_true``, ``accel_true``, ``yaw_rate_true``, the cog ticks
``wss_ticks`` (thesis appendix B: 12 cogs, 0.0625 m) and ``meta`` with the segments, the stop
intervals (``stops``: list of [t_start, t_end]) and the bumps/turns.

IMU noise defaults to 0.01 m/s^2 per axis (a phone accelerometer of about 100 ug/sqrt(Hz) at
100 Hz), the level at which the thesis' standstill threshold mu = 0.019 m/s^2 works.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim.drive import simulate_drive
from vibrospeed.sim.knobs import check
from vibrospeed.sim.profile import Segment, SpeedProfile, Turn, build_profile
from vibrospeed.sim.scenarios import SCENARIOS as SIM_SCENARIOS
from vibrospeed.sim.scenarios import register
from vibrospeed.sim.sensors import ImuConfig, TickConfig
from vibrospeed.sim.vibration import VibrationConfig
from vibrospeed.types import Recording


def _vibration() -> VibrationConfig:
    return VibrationConfig(
        harmonic_amps=(0.25, 0.2, 0.1), omega_ref=10.0, gamma=1.0, axis_gain=(0.3, 1.0, 0.5),
        amp_log_std=0.2, amp_tau=5.0, fade_rate=0.0, fundamental_fade_rate=0.0,
        resonance_freqs=(13.0,), resonance_q=20.0, resonance_amp=0.03, road_noise=0.05,
        v_ref=0.8, road_gamma=1.0, road_floor=0.0, engine=None,
    )


@dataclass(frozen=True)
class AidedConfig:
    """Knobs of the aided-tracking scenarios (SI units)."""

    duration: float = 90.0
    """s, length of the recording."""
    fs: float = 100.0
    """Hz, IMU sample rate."""
    wheel_radius: float = 0.08
    """m, wheel radius (thesis cart)."""
    omega_cruise: float = 10.0
    """rad/s, mean cruise wheel speed; each cruise draws from omega_cruise +- omega_spread."""
    omega_spread: float = 1.5
    """rad/s, spread of the cruise speeds."""
    omega_change: float = 6.0
    """rad/s, size of the sudden speed change (``sudden_change``)."""
    accel: tuple[float, float] = (0.4, 0.8)
    """m/s^2, range of pushing accelerations."""
    decel: tuple[float, float] = (0.5, 1.0)
    """m/s^2, range of braking decelerations."""
    change_accel: float = 1.2
    """m/s^2, acceleration of the sudden speed change."""
    jerk_time: float = 0.3
    """s, ramp time of every acceleration change."""
    cruise_time: tuple[float, float] = (8.0, 15.0)
    """s, range of a cruise's length."""
    stop_time: tuple[float, float] = (3.0, 6.0)
    """s, range of a stop's length."""
    initial_stop: float = 3.0
    """s, standstill at the start."""
    wheelbase: float = 0.6
    """m, distance L between the axles (bump crossings)."""
    bump_interval: tuple[float, float] = (4.0, 8.0)
    """s, range of the time between two bumps (``bumpy_floor``)."""
    bump_amp: float = 1.5
    """m/s^2, peak of a bump's vertical response."""
    bump_freq: float = 18.0
    """Hz, ringing frequency of a bump's vertical response."""
    bump_decay: float = 0.03
    """s, decay time constant of a bump's vertical response."""
    turn_interval: tuple[float, float] = (6.0, 10.0)
    """s, range of the straight stretch between turns (``turns``)."""
    turn_duration: tuple[float, float] = (4.0, 7.0)
    """s, range of a turn's length (sin^2 curvature window)."""
    turn_curvature: tuple[float, float] = (0.4, 0.8)
    """1/m, range of the peak curvature of a turn (radius 1.25..2.5 m)."""
    vibration: VibrationConfig = field(default_factory=_vibration)
    """Vibration model (cart: 3 harmonics on y, shelf resonance 13 Hz, no fades)."""
    imu: ImuConfig = field(default_factory=lambda: ImuConfig(accel_noise=0.01))
    """IMU noise and biases."""
    ticks: TickConfig | None = field(default_factory=lambda: TickConfig(n_cogs=12, radius=0.0625))
    """Cog-wheel ticks (thesis appendix B); None: off."""

    def __post_init__(self) -> None:
        check(self, positive=("omega_cruise", "change_accel", "wheelbase", "bump_freq",
                              "bump_decay"),
              nonnegative=("omega_spread", "omega_change", "initial_stop", "bump_amp",
                           "jerk_time"),
              intervals=("accel", "decel", "cruise_time", "stop_time", "bump_interval",
                         "turn_interval", "turn_duration", "turn_curvature"))


def _speed(cfg: AidedConfig, rng: np.random.Generator) -> float:
    lo = cfg.omega_cruise - cfg.omega_spread
    if not lo > 0:
        raise ParameterError("aided scenario: need omega_cruise - omega_spread > 0")
    return float(rng.uniform(lo, cfg.omega_cruise + cfg.omega_spread) * cfg.wheel_radius)


def _stops(profile: SpeedProfile, t: np.ndarray) -> list[list[float]]:
    """[start, end] intervals (s) where the true speed is 0, within ``t``."""
    still = profile.speed(t) == 0.0
    edges = np.flatnonzero(np.diff(still.astype(np.int8)))
    starts = ([0] if still[0] else []) + [int(i) + 1 for i in edges if not still[i]]
    ends = [int(i) for i in edges if still[i]] + ([t.size - 1] if still[-1] else [])
    return [[float(t[a]), float(t[b])] for a, b in zip(starts, ends, strict=True)]


def _simulate(cfg: AidedConfig, rng: np.random.Generator, segments: list[Segment], name: str,
              turns: tuple[Turn, ...] = ()) -> tuple[Recording, SpeedProfile]:
    profile = build_profile(segments, jerk_time=cfg.jerk_time, turns=turns)
    rec = simulate_drive(profile, rng, duration=cfg.duration, fs=cfg.fs,
                         wheel_radius=cfg.wheel_radius, vibration_cfg=cfg.vibration, imu=cfg.imu,
                         ticks=cfg.ticks, source=f"sim:{name}")
    rec.meta["stops"] = _stops(profile, rec.t)
    return rec, profile


def _fill(segs: list[Segment], cfg: AidedConfig, t: float) -> list[Segment]:
    """Pad with a final cruise so the profile covers the duration."""
    if t < cfg.duration:
        segs.append(Segment("cruise", duration=cfg.duration - t + 1.0))
    return segs


def start_from_rest(cfg: AidedConfig, rng: np.random.Generator) -> Recording:
    """Standstill for ``initial_stop`` s, push to a cruise speed, cruise to the end."""
    seg_rng, sim_rng = rng.spawn(2)
    v = _speed(cfg, seg_rng)
    a = float(seg_rng.uniform(*cfg.accel))
    segs = [Segment("stop", duration=cfg.initial_stop), Segment("start", speed=v, accel=a)]
    return _simulate(cfg, sim_rng, _fill(segs, cfg, cfg.initial_stop + v / a),
                     "start_from_rest")[0]


def stop_and_go(cfg: AidedConfig, rng: np.random.Generator) -> Recording:
    """Repeated start -> cruise -> brake -> stop until ``duration``."""
    seg_rng, sim_rng = rng.spawn(2)
    segs = [Segment("stop", duration=cfg.initial_stop)]
    t = cfg.initial_stop
    while t < cfg.duration:
        v = _speed(cfg, seg_rng)
        a = float(seg_rng.uniform(*cfg.accel))
        d = float(seg_rng.uniform(*cfg.decel))
        c = float(seg_rng.uniform(*cfg.cruise_time))
        s = float(seg_rng.uniform(*cfg.stop_time))
        segs += [Segment("start", speed=v, accel=a), Segment("cruise", duration=c),
                 Segment("brake", speed=0.0, accel=d), Segment("stop", duration=s)]
        t += v / a + c + v / d + s
    return _simulate(cfg, sim_rng, segs, "stop_and_go")[0]


def sudden_change(cfg: AidedConfig, rng: np.random.Generator) -> Recording:
    """Start, cruise, quick speed-up by ``omega_change`` in the middle, cruise, quick slow-down,
    cruise, brake to a stop near the end."""
    seg_rng, sim_rng = rng.spawn(2)
    r = cfg.wheel_radius
    v = _speed(cfg, seg_rng)
    a = float(seg_rng.uniform(*cfg.accel))
    dv = cfg.omega_change * r
    d = float(seg_rng.uniform(*cfg.decel))
    t_start = cfg.initial_stop + v / a
    t_brake = cfg.duration - 6.0 - (v / d)  # stop ~6 s before the end
    rest = t_brake - t_start - 2 * dv / cfg.change_accel
    if rest < 6.0:
        raise ParameterError(f"sudden_change: duration {cfg.duration} s is too short")
    c1, c2, c3 = rest * np.array([0.4, 0.3, 0.3]) * seg_rng.uniform(0.9, 1.1, 3)
    c3 = rest - c1 - c2
    segs = [Segment("stop", duration=cfg.initial_stop), Segment("start", speed=v, accel=a),
            Segment("cruise", duration=float(c1)),
            Segment("accelerate", speed=v + dv, accel=cfg.change_accel),
            Segment("cruise", duration=float(c2)),
            Segment("brake", speed=v, accel=cfg.change_accel),
            Segment("cruise", duration=float(c3)), Segment("brake", speed=0.0, accel=d),
            Segment("stop", duration=7.0)]
    return _simulate(cfg, sim_rng, segs, "sudden_change")[0]


def bump_response(t: np.ndarray, t_hits: np.ndarray, amp: float, freq: float,
                  decay: float) -> np.ndarray:
    """Vertical acceleration of axle hits: ``amp exp(-s / decay) sin(2 pi freq s)``, s >= 0."""
    out = np.zeros_like(t)
    for th in t_hits:
        i0 = np.searchsorted(t, th)
        i1 = np.searchsorted(t, th + 8 * decay)
        s = t[i0:i1] - th
        out[i0:i1] += amp * np.exp(-s / decay) * np.sin(2 * np.pi * freq * s + np.pi / 2)
    return out


def bumpy_floor(cfg: AidedConfig, rng: np.random.Generator) -> Recording:
    """Cruise over bumps; ``meta['bumps']`` lists [t_front, t_rear, speed at the middle]."""
    seg_rng, bump_rng, sim_rng = rng.spawn(3)
    v = _speed(cfg, seg_rng)
    a = float(seg_rng.uniform(*cfg.accel))
    segs = [Segment("stop", duration=cfg.initial_stop), Segment("start", speed=v, accel=a),
            Segment("cruise", duration=cfg.duration * 0.5)]
    v2 = _speed(cfg, seg_rng)
    segs.append(Segment("accelerate" if v2 >= v else "brake", speed=v2, accel=0.5))
    segs = _fill(segs, cfg, cfg.initial_stop + v / a + cfg.duration * 0.5)
    rec, prof = _simulate(cfg, sim_rng, segs, "bumpy_floor")
    t = rec.t
    # bump positions along the path (m), spaced by bump_interval at cruise speed; the reference
    # point (speed_true) is the rear axle, the front axle is wheelbase ahead of it.
    x_end = float(prof.distance(t[-1:])[0])
    x0 = float(prof.distance(np.array([cfg.initial_stop + v / a]))[0]) + cfg.wheelbase + 0.5
    pos = []
    x = x0
    while x < x_end - 0.5:
        pos.append(x)
        x += float(bump_rng.uniform(*cfg.bump_interval)) * v
    pos = np.array(pos)
    t_front = prof.crossing_times(pos - cfg.wheelbase, t)
    t_rear = prof.crossing_times(pos, t)
    k = min(t_front.size, t_rear.size)
    t_front, t_rear = t_front[:k], t_rear[:k]
    hits = np.concatenate([t_front, t_rear])
    az = rec.channels["az"] + bump_response(t, hits, cfg.bump_amp, cfg.bump_freq, cfg.bump_decay)
    rec.channels["az"] = az
    mid_speed = prof.speed(0.5 * (t_front + t_rear))
    rec.meta["bumps"] = [[float(a_), float(b_), float(c_)]
                         for a_, b_, c_ in zip(t_front, t_rear, mid_speed, strict=True)]
    rec.meta["wheelbase"] = cfg.wheelbase
    return rec


def turns(cfg: AidedConfig, rng: np.random.Generator) -> Recording:
    """Cruise with left and right turns; ``meta['turns']`` from the simulator."""
    seg_rng, turn_rng, sim_rng = rng.spawn(3)
    v = _speed(cfg, seg_rng)
    a = float(seg_rng.uniform(*cfg.accel))
    t0 = cfg.initial_stop + v / a
    segs = _fill([Segment("stop", duration=cfg.initial_stop), Segment("start", speed=v, accel=a)],
                 cfg, t0)
    tr = []
    t = t0 + 2.0
    while True:
        d = float(turn_rng.uniform(*cfg.turn_duration))
        if t + d > cfg.duration - 1.0:
            break
        k = float(turn_rng.uniform(*cfg.turn_curvature)) * float(turn_rng.choice([-1.0, 1.0]))
        tr.append(Turn(t, d, k))
        t += d + float(turn_rng.uniform(*cfg.turn_interval))
    return _simulate(cfg, sim_rng, segs, "turns", turns=tuple(tr))[0]


_BUILDERS: dict[str, Callable[[AidedConfig, np.random.Generator], Recording]] = {
    "start_from_rest": start_from_rest,
    "stop_and_go": stop_and_go,
    "sudden_change": sudden_change,
    "bumpy_floor": bumpy_floor,
    "turns": turns,
}


def _register_all() -> dict[str, Callable[..., Recording]]:
    """Register every builder in the simulator's registry (``vibrospeed.sim.simulate``)."""
    out = {}
    for name, build in _BUILDERS.items():

        def builder(cfg, rng, *, gps_model=None, _build=build):
            return _build(cfg, rng)

        builder.__doc__ = build.__doc__
        out[name] = register(name, AidedConfig)(builder)
        out[name] = SIM_SCENARIOS[name]
    return out


#: scenario name -> ``f(seed=0, duration=None, fs=100.0, **overrides) -> Recording``
SCENARIOS: dict[str, Callable[..., Recording]] = _register_all()
