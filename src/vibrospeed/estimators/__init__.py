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
from typing import Any, Literal

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


#: Names a method's ``estimate()`` reads from ``params`` besides its ``Config``'s fields, by
#: where it takes them: ``"module:NAME"`` is a tuple or set of names in that module, another
#: method's name is every name that method takes (the method hands the rest on to it), other
#: text a name popped literally (the module named in the comment).
_BESIDES_CONFIG: dict[str, tuple[str, ...]] = {
    "ekf": ("prefilter", "normalize_tau", "comb"),  # ekf._settings
    "rbpmf": ("improved",),  # rbpmf._with_improved
    "grid": ("improved",),  # grid.method._prepare (the grid filter is the improved one)
    "aided": (  # aided.method.estimate; tracker=grid / rbpmf: aided_grid.estimate
        "tracker", "prefilter", "lp_cutoff", "normalize_tau", "omega_min", "comb",
        "comb_clarity", "reference", "wheelbase", "accel_detrend", "causal", "accel_offset",
        "accel_axis", "vibrospeed.estimators.aided_grid:Config",
        "vibrospeed.estimators.aided_grid:INPUT_PARAMS"),
    "gps-riss": ("preset",),  # gps_riss.method.estimate: preset=paper
    "fuse": ("vibrospeed.estimators.fuse.method:_TRACKER_OWN", "grid"),  # fuse.method._split
}

#: ``-p tracker=`` of ``aided``: the vibration tracker it aids; :func:`vibrospeed.estimators.
#: aided.estimate` reads the value as this type, so a batch refuses another with its line
TRACKER = Literal["grid", "ekf", "rbpmf"]

#: ``-p accel_offset=`` of ``aided``, either tracker: 'standstill' removes the aiding
#: acceleration's mean while standing from it, 'none' keeps it as it is; every tracker reads
#: the value as this type (:func:`vibrospeed.config.parse_value`), so they and a batch refuse
#: another alike
ACCEL_OFFSET = Literal["standstill", "none"]

#: The type each name of :data:`_BESIDES_CONFIG` (and of a module's set named there) is read
#: as by the ``estimate()`` that takes it, for :func:`parameters`: ``bool`` for a switch read
#: with :func:`vibrospeed.config.parse_flag` (the text ``bool`` reads: ``true/false, yes/no,
#: on/off, 1/0``), ``float`` for ``float(value)``, ``float | None`` where ``none`` (or empty)
#: is None, ``str`` for a name (a pre-filter, an axis, a file) the estimator checks itself.
_READ_AS: dict[str, Any] = {
    "comb": bool, "causal": bool, "improved": bool, "online": bool,
    "normalize_tau": float, "comb_clarity": float, "accel_detrend": float,
    "lp_cutoff": float | None, "omega_min": float | None, "wheelbase": float | None,
    "tracker": TRACKER, "prefilter": str, "reference": str, "accel_offset": ACCEL_OFFSET,
    "accel_axis": str, "preset": str, "radius_from": str, "vib_method": str, "lag": float,
}


def parameters(method: str) -> dict[str, list]:
    """Every name ``-p`` may give ``method``, each with the types its value is read as.

    The names are the method's ``Config`` fields (:func:`vibrospeed.config.flat_fields`: with
    its nested model's and tracker's), the names its ``estimate()`` takes besides them (with
    the type it reads each as, :data:`_READ_AS`: ``ekf``'s ``prefilter``, ``normalize_tau``
    and ``comb``, ``rbpmf``'s ``improved``, ``aided``'s ``tracker`` and the aided grid tracker's
    names, ``gps-riss``'s ``preset``, ``fuse``'s own names and its grid tracker's) and those of
    its presets (:mod:`vibrospeed.presets`). Nothing is read or estimated, so a batch refuses a
    name no method call would take, or a value its types cannot read, before it reads a
    recording (:func:`vibrospeed.batch.run`).
    """
    import dataclasses

    from vibrospeed import presets
    from vibrospeed.config import flat_fields

    out: dict[str, list] = {}

    def add(names) -> None:
        for name, typs in names.items():
            out.setdefault(name, []).extend(t for t in typs if t not in out.get(name, []))

    cfg = getattr(get(method), "Config", None)
    if dataclasses.is_dataclass(cfg):
        add(flat_fields(cfg))
    for ref in _BESIDES_CONFIG.get(method, ()):
        if ref in METHODS:
            add(parameters(ref))
        elif ":" in ref:
            modname, _, attr = ref.partition(":")
            obj = getattr(importlib.import_module(modname), attr)
            add(flat_fields(obj) if dataclasses.is_dataclass(obj)
                else {n: [_READ_AS[n]] for n in obj})
        else:
            add({ref: [_READ_AS[ref]]})
    add({name: [] for name in presets.PARAMETERS.get(method, {})})
    add({name: [] for p in presets.PRESETS.get(method, {}).values() for name in p.params})
    return out
