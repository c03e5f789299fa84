"""Planar two-track vehicle simulator with wheel dynamics and a friction-limited tyre model.

Ground truth for the algebraic Vx / Vy estimator (METHODS.md section 4; the seed used a 14-DOF
simulator, section V). Self-contained: it returns a :class:`vibrospeed.types.Recording` with
``gz`` (yaw rate), ``ax``, ``ay`` (accelerations in the rotating body frame at the centre of
gravity), ``wheel_omega_fl/fr/rl/rr``, truth ``speed_true`` (= Vx) and ``vy_true``, and
``meta`` holding ``L1`` (CG to front axle, m), the wheel radius and the true slip ratios.

Modules, each importing only the ones before it:

* :mod:`~vibrospeed.sim.vehicle.model`: :class:`Config`, :class:`State`, the equations of
  motion and the tyre model in one compiled sub-step, ``init`` / ``step`` / ``run``;
* :mod:`~vibrospeed.sim.vehicle.manoeuvres`: the named manoeuvres (:data:`SCENARIOS`) and
  the randomised family's cars and drives (:data:`RANDOM_RANGES`);
* :mod:`~vibrospeed.sim.vehicle.recording`: sensor noise (:func:`measure`) and the
  recording (:func:`simulate`, :func:`simulate_random`).

Every name of these modules is re-exported here, so ``from vibrospeed.sim import vehicle``
then ``vehicle.simulate(vehicle.Config(), rng, name="braking")`` is all a user needs.
"""

from __future__ import annotations

from vibrospeed.sim.vehicle.manoeuvres import (
    RANDOM_RANGES,
    SCENARIOS,
    _knots,
    _random_attempt,
    random_config,
    random_controls,
    scenario,
)
from vibrospeed.sim.vehicle.model import (
    _NO,
    _NS,
    WHEELS,
    Config,
    G,
    State,
    _check_u,
    _pack,
    _run,
    _sample,
    _substep,
    _unpack,
    init,
    run,
    step,
)
from vibrospeed.sim.vehicle.recording import (
    measure,
    simulate,
    simulate_random,
)

__all__ = [
    "G",
    "WHEELS",
    "Config",
    "State",
    "init",
    "step",
    "run",
    "_NO",
    "_NS",
    "_pack",
    "_unpack",
    "_run",
    "_sample",
    "_substep",
    "_check_u",
    "RANDOM_RANGES",
    "SCENARIOS",
    "random_config",
    "random_controls",
    "scenario",
    "_knots",
    "_random_attempt",
    "measure",
    "simulate",
    "simulate_random",
]
