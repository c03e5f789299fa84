"""Reading and checking ``-p NAME=VALUE`` values against the table of every name a method
takes (:func:`vibrospeed.estimators.parameters`): a value none of its name's types reads or a
name only the other tracker takes is refused with one line (:func:`check_values`), spellings
of one value give one text (:func:`canonical_params`), and the note that names the wheel
speeds searched where no range was given (:func:`range_note`). ``vibrospeed estimate`` and
``vibrospeed batch`` both use them, so they refuse, store and note alike."""

from __future__ import annotations

from typing import Any

from vibrospeed.errors import ParameterError


def _trackers(method: str) -> tuple[str | None, list[tuple[str, tuple[str, ...], set[str]]]]:
    """For a method that hands its ``-p`` names to one of several trackers: the default
    ``tracker`` value and each tracker as (how a message names it, the ``tracker`` values that
    pick it, the names it takes); ``(None, [])`` for the others. ``aided``
    (:func:`vibrospeed.estimators.aided.estimate`): the thesis' EKF (``aided.Config``, with its
    model's fields, and the names ``aided.estimate`` reads itself on that path: the plain names
    of its entry in ``estimators._BESIDES_CONFIG``) or a grid tracker (``grid`` / ``rbpmf``:
    ``aided_grid.Config`` with the grid tracker's and comb's fields, and its input names)."""
    if method != "aided":
        return None, []
    from vibrospeed import estimators
    from vibrospeed.config import flat_names
    from vibrospeed.estimators import aided, aided_grid

    default = aided.DEFAULT_TRACKER
    own = {ref for ref in estimators._BESIDES_CONFIG[method]
           if ":" not in ref and ref not in estimators.METHODS}
    grid = "-p tracker=grid" + (", the default" if default == "grid" else "")
    ekf = "-p tracker=ekf" + (", the default" if default == "ekf" else "")
    return default, [
        (f"the EKF tracker's ({ekf})", ("ekf",), flat_names(aided.Config) | own),
        (f"the grid tracker's ({grid})", ("grid", "rbpmf"),
         flat_names(aided_grid.Config) | set(aided_grid.INPUT_PARAMS) | {"tracker"}),
    ]


def other_trackers_name(method: str, name: str,
                        params: dict[str, Any] | None = None) -> ParameterError | None:
    """The error for ``-p`` ``name`` where the tracker in use does not take it and exactly one
    other tracker of ``method`` does (``-m aided -p amp0=1`` with the grid tracker:
    ``unknown parameter 'amp0' for method 'aided' with this tracker: it is the EKF tracker's
    (-p tracker=ekf)``; the method's merged names hold it, so it was "did you mean 'amp0'");
    else None. The tracker in use is ``params``' ``tracker`` (else the default); without
    ``params``, the one that refused ``name`` (``vibrospeed estimate``'s error). A ``tracker``
    that is none of them is left to the estimator, which says so."""
    default, trackers = _trackers(method)
    if params is not None and trackers:
        chosen = str(params.get("tracker", default))
        picked = [t for t in trackers if chosen in t[1]]
        if not picked or name in picked[0][2]:
            return None
        trackers = [t for t in trackers if chosen not in t[1]]
    owners = [who for who, _, names in trackers if name in names]
    if len(owners) != 1:
        return None
    return ParameterError(f"unknown parameter '{name}' for method '{method}' with this "
                          f"tracker: it is {owners[0]}")


def check_values(method: str, params: dict[str, Any]) -> None:
    """Refuse a ``-p`` value that none of its name's types reads
    (:func:`vibrospeed.estimators.parameters`, :func:`read_param`: ``-p omega_max=abc``,
    ``-p comb=1.0``, ``-p tracker=bogus``), or a name only the tracker not chosen takes
    (``-m aided -p amp0=1`` with the grid one), with the estimator's one line; a name the
    method does not take is left to the caller. ``vibrospeed estimate`` and ``batch`` both
    call it before any recording is read, so they refuse the same values with the same line."""
    from vibrospeed import estimators

    names = estimators.parameters(method)
    for name, value in params.items():
        if name not in names:
            continue
        refusal = other_trackers_name(method, name, params)
        if refusal is not None:
            raise refusal
        read_param(name, value, names[name])


def read_param(name: str, value: Any, types: list[Any], stored: bool = False) -> Any:
    """``value`` read as the first of ``types`` that reads it
    (:func:`vibrospeed.config.parse_value`), else the first type's one-line
    :class:`ParameterError`. ``stored``: the value is from a sidecar, where a switch
    (``bool``) may be ``1.0`` / ``0.0``, as sidecars stored ``true`` / ``false`` before the
    switches the estimators read themselves had a type."""
    from vibrospeed.config import parse_value

    errors = []
    for typ in types:
        try:
            return parse_value(value, typ, name)
        except ParameterError as exc:
            if stored and typ is bool and value in ("1.0", "0.0"):
                return value == "1.0"
            errors.append(exc)
    if errors:
        raise errors[0]
    return value


def canonical_params(method: str, params: dict[str, Any], *,
                     stored: bool = False) -> dict[str, str]:
    """``params`` (``-p`` text or values) as one text per value, by name: each value read as
    its type the way the estimator reads it (:func:`vibrospeed.config.parse_value` with the
    types of :func:`vibrospeed.estimators.parameters`, a switch such as ``comb`` as ``bool``,
    as :func:`vibrospeed.config.parse_flag` reads it) and written back
    (:func:`vibrospeed.config.format_value`), so spellings of one value (``30``, ``30.0``,
    ``3e1``; ``1``, ``yes``, ``on``, ``true``; ``1, 2``, ``1,2``) give one text. A value its
    types cannot read is kept as given (``comb=1.0``: :func:`check_values` refuses it before a
    batch starts). ``stored``: ``params`` of a sidecar
    (:meth:`vibrospeed.batch.EstimateOptions.same_as`; a switch stored as ``1.0`` is
    ``true``)."""
    from vibrospeed import estimators
    from vibrospeed.config import format_value

    types = estimators.parameters(method)
    out = {}
    for name, value in sorted(params.items()):
        text = value if isinstance(value, str) else format_value(value)
        try:
            text = format_value(read_param(name, text, types.get(name, []), stored))
        except ParameterError:
            pass
        out[str(name)] = text
    return out


#: the methods that search a range of wheel speeds (``omega_min`` .. ``omega_max``)
RANGE_METHODS = ("grid", "rbpmf", "rbpf", "shs", "aided")


def range_note(method: str, given: dict, params: dict, radius: float | None) -> str | None:
    """The note that names the wheel speeds searched where the user gave no range: a grid
    tracker finds no line outside ``omega_min`` .. ``omega_max`` (rad/s), and the default
    10-120 rad/s is a car's wheels, so a cart or forklift (about 2-30 rad/s) run without its
    range gets an estimate sitting at the bottom edge or no claimed line, and nothing else
    says why. ``given``: the -p and preset parameters; ``params``: those the estimate ran
    with (its sidecar's); ``radius``: the wheel radius in m, where known (the range in m/s,
    ``v = r omega``). None where the user set either end, or the method searches none.
    ``vibrospeed estimate`` prints it, ``vibrospeed batch`` puts it in the summary's note."""
    if method not in RANGE_METHODS or "omega_min" in given or "omega_max" in given:
        return None
    if params.get("tracker", "grid") != "grid":
        return None  # aided's EKF (no range) and rbpmf (0-40 rad/s, omega_min 0 required)
    lo, hi = params.get("omega_min"), params.get("omega_max")
    if not (isinstance(lo, (int, float)) and isinstance(hi, (int, float))):
        return None  # the aided EKF: omega clipped, no range searched
    speeds = (f" ({radius * lo:.2g}-{radius * hi:.2g} m/s at wheel radius {radius:.3g} m)"
              if radius else "")
    return (f"searched wheel speeds {lo:g}-{hi:g} rad/s{speeds}, the default: for another "
            "vehicle give its range, v / r (a cart or forklift on r = 0.08 m: -p omega_min=2 "
            "-p omega_max=30)")
