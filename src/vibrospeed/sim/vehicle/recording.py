"""A noisy :class:`~vibrospeed.types.Recording` from the vehicle model of
:mod:`vibrospeed.sim.vehicle`: :func:`measure` adds the sensors' white noise and biases
to the model's outputs, :func:`simulate` runs a manoeuvre (or given controls) and
:func:`simulate_random` one drive of the randomised family.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim.vehicle.manoeuvres import random_config, scenario
from vibrospeed.sim.vehicle.model import WHEELS, Config, init, run
from vibrospeed.types import Recording


def measure(config: Config, outs: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Noisy sensor channels from the outputs of :func:`run` (white Gaussian noise, biases)."""
    n = outs.shape[0]
    ch = {
        "gz": outs[:, 2] + config.bias_gz + config.sd_gz * rng.standard_normal(n),
        "ax": outs[:, 3] + config.bias_ax + config.sd_acc * rng.standard_normal(n),
        "ay": outs[:, 4] + config.bias_ay + config.sd_acc * rng.standard_normal(n),
    }
    for i, w in enumerate(WHEELS):
        ch[f"wheel_omega_{w}"] = outs[:, 5 + i] + config.sd_omega * rng.standard_normal(n)
    return ch


def simulate(
    config: Config,
    rng: np.random.Generator,
    *,
    name: str = "braking",
    controls: np.ndarray | None = None,
    v0: float | None = None,
    seed: int | None = None,
) -> Recording:
    """Run a scenario (or explicit ``controls`` from ``v0``) and return a noisy :class:`Recording`.

    Sample ``k`` holds the state at ``t_k = (k + 1) dt`` after applying ``controls[k]``.
    ``seed`` draws the events of ``name = "random"`` (:func:`simulate_random` also draws the car).
    """
    if not isinstance(rng, np.random.Generator):
        raise ParameterError("rng must be a numpy.random.Generator (np.random.default_rng(seed))")
    if controls is None:
        v0_s, controls = scenario(name, config, seed=seed)
        v0 = v0_s if v0 is None else v0
        source = f"sim.vehicle:{name}"
    else:
        if v0 is None:
            raise ParameterError("v0 is required with explicit controls")
        source = "sim.vehicle:custom"
    _, outs = run(config, init(config, v0), controls)
    ch = measure(config, outs, rng)
    ch["speed_true"] = outs[:, 0].copy()
    ch["vy_true"] = outs[:, 1].copy()
    return Recording(
        t=outs[:, 13].copy(),
        channels=ch,
        source=source,
        wheel_radius=config.R,
        notes=[f"simulated, mu = {config.mu}, noise sd gz {config.sd_gz} rad/s, "
               f"acc {config.sd_acc} m/s^2, omega {config.sd_omega} rad/s"],
        meta={
            "L1": config.L1,
            "wheel_radius": config.R,
            "mu": config.mu,
            "scenario": name if source != "sim.vehicle:custom" else "custom",
            "seed": seed,
            "config": asdict(config),
            "slip": outs[:, 9:13].copy(),
            "yaw_rate_true": outs[:, 2].copy(),
            "ax_true": outs[:, 3].copy(),
            "ay_true": outs[:, 4].copy(),
            "omega_true": outs[:, 5:9].copy(),
            "controls": np.asarray(controls, dtype=np.float64).copy(),
        },
    )


def simulate_random(seed: int, **overrides) -> Recording:
    """One drive of the randomised family: :func:`random_config` (``overrides`` replace its
    fields, e.g. ``mu=0.5``) driven by :func:`random_controls`; sensor noise from ``seed``."""
    cfg = random_config(seed)
    if overrides:
        cfg = Config(**{**asdict(cfg), **overrides})
    return simulate(cfg, np.random.default_rng([int(seed), 2]), name="random", seed=seed)
