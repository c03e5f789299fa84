"""The randomised family of drives ``random``: vehicle, mount and road drawn per seed.

``simulate("random", seed=N)`` draws, from ``numpy.random.default_rng(N)`` alone:

* the vehicle: a car (wheel radius 0.28-0.36 m, 3-35 m/s, engine with gear shifts), a
  forklift (0.15-0.3 m, 0.5-5 m/s, electric or combustion) or a cart (0.05-0.1 m, 0.3-1.6 m/s);
* the wheel comb: which harmonics are there (all three falling, the fundamental alone, a
  missing fundamental, the 2nd strongest), the speed law ``A ~ omega^gamma`` (gamma 0-2), an
  overall level log-uniform over a decade each side of the calibration point, independent
  fades, phase jitter;
* the road and body: broadband floor, 0-3 body resonances anywhere in the wheel's search band,
  body motion below ~2 Hz on every axis, turns and braking;
* the sensor: sample rate 50-400 Hz, anti-alias filter or none (aliased engine orders and
  harmonics), mount orientation (near the vehicle frame or anywhere), quantisation, range.

Calibration (``benchmarks/calibration``, ``docs/robustness.md``): a phone in a car at 20-30 m/s
shows wheel harmonic peaks of ~0.09, 0.05, 0.02 m/s^2 (harmonics 1-3), a local floor of
~0.01 m/s^2 in a 4 s Hann spectrum and 0.2-1.5 m/s^2 std of body motion and manoeuvres below
2 Hz on the horizontal axes. Here the comb's level at the calibration speed (car: 25 m/s) is
that figure times a factor log-uniform in [0.1, 10], the floor that figure times log-uniform
[0.5, 2], the body motion 0.1-1.0 m/s^2 std per horizontal axis (car) on top of the turns and
braking of the profile.
The drawn values are in ``recording.meta["drawn"]``; ``meta["omega_range"]`` is the search
range a user would give for that vehicle class (car 10-120 rad/s, slow vehicles 2-30 rad/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim.scenarios import _drive, random_segments, register
from vibrospeed.sim.sensors import G0, ImuConfig
from vibrospeed.sim.vibration import EngineConfig, VibrationConfig
from vibrospeed.types import Recording

#: calibration point: harmonic peak amplitudes (m/s^2) of a car at 20-30 m/s, 4 s spectrum floor
REAL_HARMONICS = (0.09, 0.05, 0.02)
REAL_FLOOR = 0.01

#: comb shapes: relative amplitudes of harmonics 1..3
COMB_SHAPES = {
    "all": (1.0, 0.55, 0.22),
    "fundamental": (1.0, 0.08, 0.03),
    "missing_fundamental": (0.05, 1.0, 0.5),
    "second_strongest": (0.5, 1.0, 0.3),
}

#: per vehicle class: wheel radius (m), cruise speeds (m/s), the user's search range (rad/s)
VEHICLES = {
    "car": dict(radius=(0.28, 0.36), speed=(3.0, 35.0), omega_range=(10.0, 120.0)),
    "forklift": dict(radius=(0.15, 0.30), speed=(0.5, 5.0), omega_range=(2.0, 30.0)),
    "cart": dict(radius=(0.05, 0.10), speed=(0.3, 1.6), omega_range=(2.0, 30.0)),
}

#: body motion below 2 Hz relative to a car's (car: 0.1-1.0 m/s^2 std per horizontal axis)
LOWFREQ_SCALE = {"car": 1.0, "forklift": 0.4, "cart": 0.2}


@dataclass(frozen=True)
class RandomConfig:
    """Knobs of the randomised family (everything else is drawn per seed, module docstring)."""

    duration: float = 240.0
    """s, length of the recording."""
    fs: float = 0.0
    """Hz, sample rate; 0 draws it from 50, 100, 200, 400 Hz."""
    vehicle: str = "any"
    """``car``, ``forklift``, ``cart`` or ``any`` (car 1/2, forklift 1/4, cart 1/4)."""
    level: float = 0.0
    """Comb level relative to the calibration point; 0 draws it log-uniform in [0.1, 10]."""
    p_stop: float = 0.35
    """Probability that a cruise ends in a stop."""

    def __post_init__(self) -> None:
        # an unknown vehicle was a KeyError deep in draw(); an infinite level a recording of
        # NaN and inf; a negative fs or level, a p_stop outside [0, 1] silently meant something
        if self.vehicle != "any" and self.vehicle not in VEHICLES:
            raise ParameterError(f"random: vehicle must be any, {', '.join(VEHICLES)}, got "
                                 f"'{self.vehicle}'")
        if not (self.duration > 0 and np.isfinite(self.duration)):
            raise ParameterError(f"random: duration must be > 0 s, got {self.duration}")
        for name, unit in (("fs", " Hz"), ("level", "")):
            v = getattr(self, name)
            if not (v >= 0 and np.isfinite(v)):
                raise ParameterError(f"random: {name} must be 0 (drawn) or finite and > 0{unit}, "
                                     f"got {v}")
        if not 0 <= self.p_stop <= 1:
            raise ParameterError(f"random: p_stop must be in [0, 1], got {self.p_stop}")


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def floor_std(floor_amp: float, fs: float) -> float:
    """White-noise std (m/s^2) whose 4 s Hann amplitude spectrum sits at ``floor_amp``: the
    amplitude-scaled spectrum of white noise of std s over N samples is ``s sqrt(6 / N)``."""
    return floor_amp / np.sqrt(6.0 / (4.0 * fs))


def draw(cfg: RandomConfig, rng: np.random.Generator) -> dict:
    """Every random choice of one drive, as plain numbers (the builder's input)."""
    kinds = ("car", "forklift", "cart")
    kind = cfg.vehicle if cfg.vehicle != "any" else str(rng.choice(kinds, p=[0.5, 0.25, 0.25]))
    veh = VEHICLES[kind]
    fs = cfg.fs if cfg.fs > 0 else float(rng.choice([50.0, 100.0, 200.0, 400.0],
                                                    p=[0.15, 0.45, 0.2, 0.2]))
    radius = float(rng.uniform(*veh["radius"]))
    shape = str(rng.choice(list(COMB_SHAPES), p=[0.45, 0.2, 0.15, 0.2]))
    level = cfg.level if cfg.level > 0 else _loguniform(rng, 0.1, 10.0)
    v_lo, v_hi = veh["speed"]
    # the comb's level holds at the calibration speed (car: 25 m/s), else at a typical speed
    v_cal = 25.0 if kind == "car" else float(np.sqrt(v_lo * v_hi))
    omega_ref = v_cal / radius
    gamma = float(rng.uniform(0.0, 2.0))
    om_lo, om_hi = veh["omega_range"]
    band = (om_lo / (2 * np.pi), min(3 * om_hi / (2 * np.pi), 0.45 * fs))
    n_res = int(rng.integers(0, 4))
    res_freqs = tuple(float(rng.uniform(max(band[0], 1.0), band[1])) for _ in range(n_res))
    d = dict(
        vehicle=kind, fs=fs, wheel_radius=radius, comb_shape=shape, level=level,
        harmonic_amps=tuple(level * a * s for a, s in
                            zip(REAL_HARMONICS[:1] * 3, COMB_SHAPES[shape], strict=True)),
        omega_ref=omega_ref, v_cal=v_cal, gamma=gamma,
        axis_gain=tuple(float(g) for g in rng.uniform(0.2, 1.0, 3)),
        amp_log_std=float(rng.uniform(0.1, 0.5)), amp_tau=float(rng.uniform(2.0, 10.0)),
        fade_rate=float(rng.uniform(0.0, 2.0)), fundamental_fade_rate=float(rng.uniform(0, 2.0)),
        phase_jitter=float(_loguniform(rng, 1e-3, 0.5)),
        floor=REAL_FLOOR * _loguniform(rng, 0.5, 2.0),
        resonance_freqs=res_freqs, resonance_q=float(rng.uniform(5.0, 30.0)),
        resonance_rel=float(_loguniform(rng, 0.3, 3.0)),
        lowfreq_std=tuple(float(x) * LOWFREQ_SCALE[kind] for x in (
            rng.uniform(0.1, 1.0), rng.uniform(0.1, 1.0), rng.uniform(0.05, 0.4))),
        lowfreq_cutoff=float(rng.uniform(0.5, 2.0)),
        anti_alias=bool(rng.uniform() < 0.6),
        turn_rate=float(rng.uniform(0.5, 3.0)),
        lat_accel_max=float(rng.uniform(1.0, 4.0) if kind == "car" else rng.uniform(0.3, 1.5)),
        speed=veh["speed"], omega_range=veh["omega_range"],
    )
    d["engine"] = None
    d["idle_rel"] = 0.0
    if kind == "car" or (kind == "forklift" and rng.uniform() < 0.5):
        # an idling engine shakes the body broadband too: standing 2.5-10x below the road at
        # the calibration speed (a phone in a car: 0.2 vs 0.5 m/s^2 above 2 Hz standing vs
        # moving at ~11 m/s, benchmarks/calibration)
        d["idle_rel"] = float(rng.uniform(0.1, 0.4))
        d["engine"] = dict(amp=float(REAL_FLOOR * _loguniform(rng, 0.5, 5.0)),
                           order=float(rng.choice([1.0, 2.0])),
                           extra=((2.0 if rng.uniform() < 0.5 else 4.0,
                                   float(rng.uniform(0.2, 1.5))),),
                           final_drive=float(rng.uniform(3.0, 4.5)) if kind == "car" else
                           float(rng.uniform(10.0, 20.0)),
                           gamma=float(rng.uniform(0.0, 1.0)))
    if rng.uniform() < 0.5:  # mount near the vehicle's axes
        mount = tuple(float(x) for x in rng.normal(0.0, 0.1, 3))
    else:  # anywhere: the user's --axis is any mix of the vehicle's axes
        mount = tuple(float(x) for x in (rng.uniform(-np.pi, np.pi), rng.uniform(-1.2, 1.2),
                                         rng.uniform(-np.pi, np.pi)))
    d["mount"] = mount
    d["accel_lsb"] = float(rng.choice([0.0, 0.0006, 0.0024, 0.0096]))
    d["accel_range"] = float(rng.choice([2.0, 4.0, 8.0, 16.0])) * G0
    d["accel_noise"] = float(_loguniform(rng, 0.002, 0.012))
    return d


def build_vibration(d: dict) -> VibrationConfig:
    """The vibration model of one drawn drive."""
    fs = d["fs"]
    floor = floor_std(d["floor"], fs)
    eng = None
    if d["engine"] is not None:
        e = d["engine"]
        eng = EngineConfig(amp=e["amp"], order=e["order"], extra_orders=e["extra"],
                           final_drive=e["final_drive"], gamma=e["gamma"])
    return VibrationConfig(
        harmonic_amps=d["harmonic_amps"], omega_ref=d["omega_ref"], gamma=d["gamma"],
        axis_gain=d["axis_gain"], amp_log_std=d["amp_log_std"], amp_tau=d["amp_tau"],
        fade_rate=d["fade_rate"], fundamental_fade_rate=d["fundamental_fade_rate"],
        fade_duration=(2.0, 10.0), fade_depth=0.0,
        resonance_freqs=d["resonance_freqs"] or (min(13.0, 0.4 * fs),),
        resonance_q=d["resonance_q"],
        resonance_amp=(d["resonance_rel"] * floor if d["resonance_freqs"] else 0.0),
        road_noise=floor, v_ref=d["v_cal"], road_gamma=1.0, road_floor=0.1, engine=eng,
        aa_order=4 if d["anti_alias"] else 0, phase_jitter=d["phase_jitter"],
        idle_noise=d["idle_rel"] * floor,
        lowfreq_std=d["lowfreq_std"], lowfreq_cutoff=d["lowfreq_cutoff"],
        lowfreq_v=min(5.0, d["v_cal"]),
    )


@dataclass(frozen=True)
class _DriveKnobs:
    """What :func:`vibrospeed.sim.scenarios._drive` reads from a scenario config."""

    duration: float
    fs: float
    wheel_radius: float
    jerk_time: float
    turn_rate: float
    turn_duration: tuple[float, float]
    lat_accel_max: float
    curvature_max: float
    vibration: VibrationConfig
    imu: ImuConfig
    ticks: None = None
    wheels: None = None
    gps: None = None


@register("random", RandomConfig)
def _random(cfg: RandomConfig, rng: np.random.Generator, *, gps_model=None) -> Recording:
    """Randomised family: vehicle, comb, road, mount and sensor drawn per seed."""
    draw_rng, seg_rng, drive_rng = rng.spawn(3)
    d = draw(cfg, draw_rng)
    car = d["vehicle"] == "car"
    v_lo, v_hi = d["speed"]
    segs = random_segments(
        seg_rng, duration=cfg.duration, speed_range=(v_lo, v_hi),
        cruise_time=(8.0, 40.0), stop_time=(3.0, 15.0), p_stop=cfg.p_stop,
        initial_stop=float(seg_rng.uniform(2.0, 8.0)),
        accel=(0.8, 2.5) if car else (0.2, 0.8), decel=(1.0, 4.0) if car else (0.3, 1.2),
        wander=0.3 if car else 0.03, wander_accel=0.2 if car else 0.05)
    imu = ImuConfig(accel_noise=d["accel_noise"], mount=d["mount"], accel_lsb=d["accel_lsb"],
                    accel_range=d["accel_range"])
    knobs = _DriveKnobs(
        duration=cfg.duration, fs=d["fs"], wheel_radius=d["wheel_radius"],
        jerk_time=0.6 if car else 0.4, turn_rate=d["turn_rate"], turn_duration=(3.0, 8.0),
        lat_accel_max=d["lat_accel_max"], curvature_max=0.1 if car else 1.0,
        vibration=build_vibration(d), imu=imu)
    rec = _drive(knobs, drive_rng, gps_model, segs, "random")
    rec.meta["drawn"] = d
    rec.meta["omega_range"] = list(d["omega_range"])
    rec.notes.append(f"random family: {d['vehicle']}, r = {d['wheel_radius']:.3f} m, "
                     f"{d['fs']:g} Hz, comb '{d['comb_shape']}' at {d['level']:.2g} x the "
                     f"calibration level, mount {np.round(d['mount'], 2).tolist()} rad")
    return rec
