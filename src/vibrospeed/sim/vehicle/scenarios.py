"""The two-track vehicle's manoeuvres as ``vibrospeed simulate`` scenarios (``vehicle_braking``,
``vehicle_combined``, ``vehicle_slalom``, ``vehicle_gradual``, ``vehicle_random``): the
braking with ABS and wheel spin of the algebraic Vx / Vy estimator's tests, reachable from the
command line (they were only in the Python API, :func:`vibrospeed.sim.vehicle.simulate`).
Registered with :func:`vibrospeed.sim.scenarios.register` when :mod:`vibrospeed.sim` is
imported."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim.scenarios import register
from vibrospeed.sim.vehicle.manoeuvres import SCENARIOS as MANOEUVRES
from vibrospeed.sim.vehicle.manoeuvres import random_config, random_controls
from vibrospeed.sim.vehicle.model import Config
from vibrospeed.sim.vehicle.recording import simulate
from vibrospeed.types import Recording


@dataclass(frozen=True)
class VehicleScenarioConfig:
    """Planar two-track car with wheel dynamics and a friction-limited tyre (sim.vehicle).

    vehicle : the car, its tyres, ABS and sensor noise (`--set vehicle.mu=0.5`); its
        `dt` is `1 / fs`.
    fs : Hz, sample rate of every channel (None: 100 Hz, the random drive's drawn rate).
    duration : s; the named manoeuvres have their own length (12 s braking) and are cut to
        `duration` where it is shorter; the random drive lasts `duration` (default 20 s,
        then the drive of `--seed N` is :func:`vibrospeed.sim.vehicle.simulate_random`'s).
    """

    vehicle: Config = field(default_factory=Config)
    fs: float | None = None
    duration: float | None = None


def _build(name: str):
    def build(cfg: VehicleScenarioConfig, rng: np.random.Generator, *,
              gps_model=None) -> Recording:
        if gps_model is not None:
            raise ParameterError(f"sim:vehicle_{name}: the vehicle model has no GPS")
        if cfg.fs is not None and not 1.0 <= cfg.fs <= 10_000.0:  # the model's dt
            raise ParameterError(f"sim:vehicle_{name}: fs must be in [1, 10000] Hz, got "
                                 f"{cfg.fs}")
        if name == "random":  # the family's drive of --seed N (simulate_random(N)), with the
            # vehicle knobs given away from their defaults replacing the drawn car's
            seed = int(rng.bit_generator.seed_seq.entropy)
            car = random_config(seed)
            given = {f.name: getattr(cfg.vehicle, f.name) for f in dataclasses.fields(Config)
                     if getattr(cfg.vehicle, f.name) != getattr(Config(), f.name)}
            car = dataclasses.replace(car, **given)
            if cfg.fs is not None:
                car = dataclasses.replace(car, dt=1.0 / cfg.fs)
            v0, controls = random_controls(car, seed, 20.0 if cfg.duration is None
                                           else cfg.duration)
            rec = simulate(car, np.random.default_rng([seed, 2]), controls=controls, v0=v0)
        else:
            car = dataclasses.replace(cfg.vehicle, dt=1.0 / (cfg.fs or 100.0))
            rec = simulate(car, rng, name=name)
            if cfg.duration is not None:  # the sample at t = duration kept
                rec = rec.slice_time(None, cfg.duration + 1e-9)
        # arrays per sample (slip, controls, true omegas) stay in the Python API's meta
        rec.meta = {k: v for k, v in rec.meta.items() if not isinstance(v, np.ndarray)}
        rec.meta["manoeuvre"] = name
        rec.meta["car"] = rec.meta.pop("config")  # the car driven (the random one's is drawn)
        return rec

    what = MANOEUVRES[name].replace(" (needs seed=)", "")
    build.__doc__ = (f"Two-track car (sim.vehicle), {what}; channels gz, ax, ay, four wheel "
                     "speeds, truth speed_true (Vx) and vy_true; meta L1 and the wheel radius.")
    return build


for _name in MANOEUVRES:
    register(f"vehicle_{_name}", VehicleScenarioConfig)(_build(_name))
