"""Seeded, deterministic simulator of drives with ground truth.

Entry point::

    from vibrospeed.sim import simulate, SCENARIOS
    rec = simulate("car", seed=3, duration=120, **{"gps.rate_hz": 1})

Every scenario returns a :class:`~vibrospeed.types.Recording` with IMU channels ``ax ay az gx gy
gz``, truth ``omega_true`` (rad/s), ``speed_true`` (m/s) and the extra truth ``accel_true``
(m/s^2), ``yaw_rate_true`` (rad/s); optionally ``gps_speed``/``gps_sats``, ``wheel_omega_*`` and
the event stream ``wss_ticks``. ``wheel_radius`` is set and ``meta`` holds the scenario name,
seed, full configuration and drawn quantities (segments, turns, biases, fades, gear changes,
GPS outages).

Modules: :mod:`.profile` (exact jerk-limited speed profiles and turns), :mod:`.vibration`
(harmonics, resonances, engine order, road noise), :mod:`.sensors` (IMU, ticks, wheels, simple
GPS and the :class:`GpsModel` hook), :mod:`.drive` (assembly), :mod:`.scenarios` (configs and
registry; add scenarios with :func:`register`), :mod:`.validation` (thesis eq. 2.6).
Randomness only through ``np.random.default_rng(seed)`` split into fixed per-component streams.
"""

import inspect

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim import family  # noqa: F401  (registers the "random" scenario)
from vibrospeed.sim.drive import EXTRA_TRUTH_UNITS, simulate_drive
from vibrospeed.sim.profile import Segment, SpeedProfile, Turn, build_profile
from vibrospeed.sim.scenarios import (
    CONFIGS,
    DESCRIPTIONS,
    SCENARIOS,
    CarConfig,
    CartConfig,
    ValidationConfig,
    describe_doc,
    make_config,
    register,
    simulate,
)
from vibrospeed.sim.sensors import (
    G0,
    GpsConfig,
    GpsModel,
    ImuConfig,
    TickConfig,
    WheelConfig,
    gps_with_lag,
)
from vibrospeed.sim.validation import ValidationSignal, validation_signal
from vibrospeed.sim.vibration import EngineConfig, VibrationConfig

__all__ = [
    "CONFIGS",
    "DESCRIPTIONS",
    "describe",
    "EXTRA_TRUTH_UNITS",
    "G0",
    "SCENARIOS",
    "CarConfig",
    "CartConfig",
    "EngineConfig",
    "GpsConfig",
    "GpsModel",
    "ImuConfig",
    "Segment",
    "SpeedProfile",
    "TickConfig",
    "Turn",
    "ValidationConfig",
    "ValidationSignal",
    "VibrationConfig",
    "WheelConfig",
    "build_profile",
    "gps_with_lag",
    "make_config",
    "register",
    "simulate",
    "simulate_drive",
    "validation_signal",
]


def describe() -> dict[str, str]:
    """Scenario name -> one-line description, for ``vibrospeed simulate --list``."""
    return {name: DESCRIPTIONS.get(name, "") for name in sorted(SCENARIOS)}


# scenarios of other modules register themselves on import
from vibrospeed.sim import aided as _aided  # noqa: E402,F401
from vibrospeed.sim.vehicle import scenarios as _vehicle  # noqa: E402,F401


def _gps_knob(build, name: str, value):
    """A ``--set`` text value of a GPS scenario's knob, read as the type of the knob's default
    (in the builder's or :func:`vibrospeed.sim.gps.drive`'s signature); a knob without a typed
    default is read as a number where it is one."""
    from vibrospeed.config import parse_value
    from vibrospeed.sim import gps as _gps

    if not isinstance(value, str):
        return value
    for fn in (build, _gps.drive):
        par = inspect.signature(fn).parameters.get(name)
        if par is None or par.default is inspect.Parameter.empty or par.default is None:
            continue
        d = par.default
        typ = tuple[float, ...] if isinstance(d, tuple) else type(d)
        if typ in (bool, int, float, str, tuple[float, ...]):
            return parse_value(value, typ, name)
    try:
        return float(value)
    except ValueError:
        return value


def _gps_scenario(name: str, build):
    """Adapt a :mod:`vibrospeed.sim.gps` builder ``f(rng, **kw)`` to the registry's signature."""

    def scenario(*, seed: int = 0, duration: float | None = None, fs: float | None = None,
                 gps_model=None, **overrides):
        kw = {k: _gps_knob(build, k, v) for k, v in overrides.items()}
        # duration and fs typed as the other knobs: `simulate --set fs=200` reaches here as
        # the text "200" (simulate's own fs argument), which the builder's checks choked on
        if duration is not None:
            kw["duration"] = _gps_knob(build, "duration", duration)
        if fs is not None:
            kw["fs"] = _gps_knob(build, "fs", fs)
        try:
            rec = build(np.random.default_rng(seed), **kw)
        except TypeError as exc:
            if "unexpected keyword argument" not in str(exc):
                raise
            bad = str(exc).split("argument", 1)[1].strip(" '\"")
            known = [a for a in inspect.signature(build).parameters if a not in ("rng", "kw")]
            raise ParameterError(f"scenario '{name}' has no knob '{bad}' "
                                 f"(it has: {', '.join(known)}, ...)") from None
        rec.meta.update(scenario=name, seed=seed)
        rec.source = f"sim:{name}(seed={seed})"
        return rec

    scenario.__doc__ = build.__doc__
    return scenario


def _register_gps() -> None:
    from vibrospeed.sim import gps as _gps

    for name, build in _gps.SCENARIOS.items():
        SCENARIOS[name] = _gps_scenario(name, build)
        DESCRIPTIONS[name] = describe_doc(build.__doc__)


_register_gps()
