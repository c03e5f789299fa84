"""How speed is inferred. Each estimator module offers the same interface:

* ``Config``: frozen dataclass of parameters (unknown fields are an error);
* ``State``: small immutable record (NamedTuple) of the filter state;
* ``init(config, ...) -> State``, ``step(config, state, y) -> (State, estimate)``: online use;
* ``run(config, y, ...) -> arrays``: batch over a whole recording, same numbers as ``step``;
* ``estimate(recording, *, axis, wheel_radius, params, progress) -> Track``: the entry point used
  by the CLI and :mod:`vibrospeed.eval`. ``params`` maps ``Config`` field names to values.

:func:`get` finds the module of a method by its CLI name.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from vibrospeed.errors import ParameterError

#: CLI method name -> (module, one-line description)
METHODS: dict[str, tuple[str, str]] = {
    "ekf": ("vibrospeed.estimators.ekf", "harmonic EKF on one vibration axis (thesis ch. 2)"),
    "rbpmf": (
        "vibrospeed.estimators.rbpmf",
        "Rao-Blackwellized point-mass filter over an omega grid (paper III-D)",
    ),
    "grid": (
        "vibrospeed.estimators.grid",
        "best vibration tracker: improved grid filter + harmonic-comb evidence, smoothed "
        "offline (-p smooth=none: causal)",
    ),
    "rbpf": ("vibrospeed.estimators.rbpf", "Rao-Blackwellized particle filter (paper III-C)"),
    "shs": ("vibrospeed.estimators.shs", "subharmonic summation per batch (Hermes 1988)"),
    "aided": (
        "vibrospeed.estimators.aided",
        "vibration tracker aided by longitudinal acceleration, standstill detection (thesis ch. 3)",
    ),
    "gps-riss": (
        "vibrospeed.estimators.gps_riss",
        "GPS speed + one accelerometer Kalman fusion with GPS lag model",
    ),
    "fuse": (
        "vibrospeed.estimators.fuse",
        "one speed from vibration + acceleration + GPS (where present), wheel radius learned "
        "(-p radius_from=est.csv.json reuses it)",
    ),
    "algebraic": (
        "vibrospeed.estimators.algebraic",
        "Vx/Vy from yaw rate, accelerations and wheel speeds, algebraic differentiation",
    ),
}


def get(method: str) -> ModuleType:
    """Module implementing ``method`` (a key of :data:`METHODS`)."""
    try:
        modname = METHODS[method][0]
    except KeyError:
        raise ParameterError(
            f"unknown method '{method}' (choose from: {', '.join(available())})"
        ) from None
    try:
        return importlib.import_module(modname)
    except ModuleNotFoundError as exc:
        if exc.name == modname:
            raise ParameterError(f"method '{method}' is not available in this build") from None
        raise


def available() -> list[str]:
    """Method names whose implementation is installed."""
    out = []
    for name, (modname, _) in METHODS.items():
        if importlib.util.find_spec(modname) is not None:
            out.append(name)
    return out
