"""How speed is inferred. Each method module (:data:`METHODS`) offers the same protocol:

* ``Config``: frozen dataclass of parameters (an unknown field is a
  :class:`~vibrospeed.errors.ParameterError` through :func:`vibrospeed.config.config_from_params`);
* ``State``: small immutable record (NamedTuple) of the filter state, picklable;
* ``init(config) -> State``: the prior before the first sample;
* ``step(config, state, y) -> (State, Estimate)``: one sample ``y`` (a float, or the
  method's ``Sample`` record of several inputs), the shared :class:`vibrospeed.types.Estimate`
  (omega, its std and band, ``has_signal``, ``standstill``, method-specific ``extras``);
* ``run(config, y, state=None) -> Result``: a whole signal (arrays, or a ``Sample`` of
  arrays) from ``state``; the same numbers as repeated ``step`` from that state (columns named
  as the Estimate's fields and extras), ``Result.final`` the state after the last sample, so
  chunked runs equal one run. ``state=None`` is ``init(config)`` (``gps-riss``: started at
  the first GPS fix's speed);
* ``estimate(recording, *, axis, wheel_radius, params, progress, return_posterior) -> Track``:
  the entry point of the CLI and :mod:`vibrospeed.eval`; ``params`` maps ``Config`` field names
  to values (text or typed), ``return_posterior`` adds a grid method's posterior to the extras
  (other methods have none and ignore it).

``tests/test_conformance.py`` checks the protocol for every method. The grid tracker and the
paper's filter share the package :mod:`vibrospeed.estimators.grid`; :func:`get` finds the
module of a method by its CLI name.
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
        "offline (-p smooth=none: causal); the default without GPS speed",
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
        "(-p radius_from=est.csv.json reuses it); the default where a recording has GPS speed",
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
