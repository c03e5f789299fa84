"""Typed parameters: ``NAME=VALUE`` text from the command line into frozen Config dataclasses.

Every estimator and simulated scenario is configured by a frozen dataclass. The command line
gives its fields as text (``-p q_omega=4``, ``--set vibration.harmonic_amps=0.1,0.05``); the
text is parsed once, here, against the field's annotated type:

=====================  ======================================  ============================
field type             text                                    value
=====================  ======================================  ============================
``float``              ``4``, ``1e-3``, ``-0.5``, ``inf``      ``4.0`` ...
``int``                ``200``, ``2.0``                        ``200``, ``2``
``bool``               ``true/false, yes/no, on/off, 1/0``     ``True`` / ``False``
``str``                anything, commas included               the text
``X | None``           ``none`` (or ``null``, empty), else X   ``None`` or X
``tuple[X, ...]``      ``a,b,c`` (``a:b:c`` also read)         ``(a, b, c)``; empty: ``()``
``tuple[X, Y]``        ``a,b``: exactly two items              ``(a, b)``
``list[X]``            as a tuple                              ``[a, b, c]``
=====================  ======================================  ============================

On the command line a comma followed by another ``NAME=`` starts the next parameter
(``-p q_omega=2,omega_max=100``); any other comma belongs to the value
(``-p comb_rates=-0.1,0.1``, ``-p fit=q_omega,r``), so lists need no quoting.
Errors are one line: an unknown name with the closest valid names, a bad value with the
parameter's name and expected type.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
import re
import types
import typing
from typing import Any, TypeVar

import numpy as np

from vibrospeed.errors import ParameterError

C = TypeVar("C")

_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off")
_NONE = ("none", "null", "")
#: ``NAME=`` at the start of a comma-separated part: a new parameter (dotted names reach
#: nested Configs of a simulated scenario)
_NAME_EQ = re.compile(r"^\s*[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\s*=")


def type_name(typ: Any) -> str:
    """A short readable name of a field type, for messages and the reference pages
    (``float``, ``int | None``, ``tuple[float, ...]``)."""
    if isinstance(typ, str):
        return typ
    if typ is type(None):
        return "None"
    origin = typing.get_origin(typ)
    args = typing.get_args(typ)
    if origin in (typing.Union, types.UnionType):
        return " | ".join(type_name(a) for a in args)
    if origin in (tuple, list):
        name = origin.__name__
        if not args:
            return name
        if len(args) == 2 and args[1] is Ellipsis:
            return f"{name}[{type_name(args[0])}, ...]"
        return f"{name}[{', '.join(type_name(a) for a in args)}]"
    if origin is typing.Literal:
        return " | ".join(repr(a) for a in args)
    if origin is not None:
        return str(typ).replace("typing.", "")
    return getattr(typ, "__name__", str(typ))


def _bad(name: str, text: str, typ: Any, why: str = "") -> ParameterError:
    extra = f" ({why})" if why else ""
    return ParameterError(f"parameter '{name}': cannot read {text!r} as {type_name(typ)}{extra}")


def _split_items(text: str, numeric: bool) -> list[str]:
    """Items of a list value: comma-separated; a numeric list without commas may also use
    ``:`` (the older ``-0.1:0:0.1`` form)."""
    if not text.strip():
        return []
    sep = ":" if numeric and "," not in text and ":" in text else ","
    return [s.strip() for s in text.split(sep)]


def _kind_ok(value: Any, typ: Any) -> bool:
    """Whether a value given as itself (not text) is of the kind ``typ`` wants: a real number
    (not a bool) for ``float`` / ``int`` (a whole one for ``int``), a bool or a number for a
    switch, a sequence of such items for a tuple, a member of a ``Literal``, None only where
    ``typ`` admits it. Types beyond these (a nested Config, ``Any``) take anything."""
    origin, args = typing.get_origin(typ), typing.get_args(typ)
    real = isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)
    if typ is Any:
        return True
    if origin in (typing.Union, types.UnionType):
        return any(_kind_ok(value, a) for a in args)
    if typ is type(None):
        return value is None
    if origin is typing.Literal:
        return value in args
    if typ is float:
        return real
    if typ is int:
        return real and float(value).is_integer()
    if typ is bool:
        return isinstance(value, bool | np.bool_) or real
    if typ is str:
        return isinstance(value, str)
    if origin in (tuple, list) or typ in (tuple, list):
        if not isinstance(value, tuple | list | np.ndarray):
            return False
        if not args:
            return all(_kind_ok(v, float) for v in value)
        if (len(args) == 2 and args[1] is Ellipsis) or (origin or typ) is list:
            return all(_kind_ok(v, args[0]) for v in value)
        return len(value) == len(args) and all(_kind_ok(v, a) for v, a in zip(value, args,
                                                                             strict=True))
    return True


def parse_value(text: str, typ: Any, name: str = "value") -> Any:
    """``text`` read as a value of type ``typ`` (see the module docstring's table).

    Raises :class:`ParameterError` naming ``name`` and the expected type when ``text`` cannot
    be read. Types the table does not cover (a nested Config, a dict) cannot be given as text.
    """
    if not isinstance(text, str):
        if not _kind_ok(text, typ):
            raise ParameterError(f"parameter '{name}': cannot use {text!r} as "
                                 f"{type_name(typ)}")
        return text
    origin = typing.get_origin(typ)
    args = typing.get_args(typ)
    if typ is Any:
        return text
    if origin in (typing.Union, types.UnionType):
        if type(None) in args and text.strip().lower() in _NONE:
            return None
        options = [a for a in args if a is not type(None)]
        # a str member takes anything, so it is tried last
        options.sort(key=lambda a: a is str)
        for a in options:
            try:
                return parse_value(text, a, name)
            except ParameterError:
                continue
        why = ""
        if options and all(a in (float, int) for a in options):  # float | None: say what fits
            why = ("a number" if float in options else "a whole number") + \
                (", or none" if type(None) in args else "")
        raise _bad(name, text, typ, why)
    if origin is typing.Literal:
        for a in args:
            if str(a) == text.strip():
                return a
        raise _bad(name, text, typ, "choose from " + ", ".join(str(a) for a in args))
    s = text.strip()
    if typ is float:
        try:
            return float(s)
        except ValueError:
            raise _bad(name, text, typ, "a number") from None
    if typ is int:
        try:
            return int(s)
        except ValueError:
            pass
        try:
            x = float(s)
        except ValueError:
            raise _bad(name, text, typ, "a whole number") from None
        if not (math.isfinite(x) and x.is_integer()):
            raise _bad(name, text, typ, "a whole number")
        return int(x)
    if typ is bool:
        if s.lower() in _TRUE:
            return True
        if s.lower() in _FALSE:
            return False
        raise _bad(name, text, typ, "true or false")
    if typ is str:
        return text
    if origin in (tuple, list) or typ in (tuple, list):
        seq = origin or typ
        if not args:
            item_types: list[Any] = []
            variadic: Any = float
        elif (len(args) == 2 and args[1] is Ellipsis) or seq is list:
            item_types, variadic = [], args[0]
        else:
            item_types, variadic = list(args), None
        numeric = all(a in (float, int) for a in (item_types or [variadic]))
        items = _split_items(text, numeric)
        if variadic is None and len(items) != len(item_types):
            raise _bad(name, text, typ, f"{len(item_types)} comma-separated items, "
                       f"got {len(items)}")
        out = [parse_value(v, variadic if variadic is not None else item_types[k],
                           f"{name}[{k}]") for k, v in enumerate(items)]
        return seq(out)
    raise ParameterError(f"parameter '{name}': a {type_name(typ)} cannot be given as text "
                         f"('{text}')")


def parse_flag(value: Any, name: str) -> bool:
    """A switch given as bool, number or text (``true/false``, ``1/0``, ``yes/no``, ``on/off``);
    other text is a :class:`ParameterError` naming ``name``."""
    return bool(parse_value(value, bool, name))


def parse_number(value: Any, name: str, *, optional: bool = False) -> float | None:
    """A number an estimator reads itself (not a Config field), given as a number or text
    (``4``, ``1e-3``, ``inf``; with ``optional`` also ``none`` or empty: None), as
    :func:`parse_value` reads a ``float`` (``float | None``) field; other text is a
    :class:`ParameterError` naming ``name``."""
    x = parse_value(value, float | None if optional else float, name)
    return None if x is None else float(x)


def format_value(value: Any) -> str:
    """``value`` as the text :func:`parse_value` reads back to an equal value (floats by
    ``repr``, so the round trip is exact; sequences comma-separated; None as ``none``)."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float | int):
        return repr(value)
    if isinstance(value, tuple | list):
        return ",".join(format_value(v) for v in value)
    return str(value)


def suggest(name: str, valid: typing.Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest valid names, else a short hint."""
    close = difflib.get_close_matches(name, list(valid), n=3, cutoff=0.6)
    if close:
        return " (did you mean " + " or ".join(f"'{c}'" for c in close) + "?)"
    return ""


def unknown(name: str, owner: str, valid: typing.Iterable[str], *,
            near: str | None = None) -> ParameterError:
    """The one-line error for an unknown parameter ``name`` of ``owner``: the valid names
    closest to ``near`` (default ``name``), else the first valid names."""
    valid = sorted(valid)
    hint = suggest(name if near is None else near, valid)
    if not hint:
        shown = ", ".join(valid[:12]) + (", ..." if len(valid) > 12 else "")
        hint = f" (valid: {shown})"
    return ParameterError(f"unknown parameter '{name}' for {owner}{hint}")


def field_types(cls: type) -> dict[str, Any]:
    """Field name -> resolved annotated type of dataclass ``cls``."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls)}


def flat_fields(cls: type) -> dict[str, list[Any]]:
    """The names ``-p`` reaches through dataclass ``cls``, each with its field types: its
    fields, with a field that holds a dataclass (a model, a tracker) replaced by that
    dataclass' fields (estimators split one flat parameter set between nested Configs, which
    may share a name)."""
    out: dict[str, list[Any]] = {}
    for name, typ in field_types(cls).items():
        sub = typ if dataclasses.is_dataclass(typ) else next(
            (a for a in typing.get_args(typ) if dataclasses.is_dataclass(a)), None)
        if sub is None:
            out.setdefault(name, []).append(typ)
        else:
            for k, v in flat_fields(sub).items():
                out.setdefault(k, []).extend(v)
    return out


def flat_names(cls: type) -> set[str]:
    """The names ``-p`` reaches through dataclass ``cls`` (:func:`flat_fields`)."""
    return set(flat_fields(cls))


def is_count(value: Any, least: int = 1) -> bool:
    """``value`` is a whole number of an integer type (not a bool, not 3.0) and ``>= least``:
    array sizes and seeds, which numpy takes as integers only."""
    import numbers

    return isinstance(value, numbers.Integral) and not isinstance(value, bool) and value >= least


def check_state(method: str, config_says: str, *says: Any, **fields: tuple[Any, Any]) -> None:
    """:class:`ParameterError` unless each state array ``name=(array, wanted_shape)`` has its
    wanted shape (``None`` for an absent array, and a wanted ``None`` for one that must be
    absent). A state made for another config (another ``M``, grid, particle count or window)
    would otherwise be read past its end by compiled code, or run with the state's sizes
    instead of the config's. ``config_says``: what of the config sets the shapes; with
    ``says``, a format string they complete (:meth:`str.format`), formatted only when a shape
    is wrong (``check_state("ekf", "M = {}", M, ...)``: a ``step`` that calls this for every
    sample makes no text while the state fits)."""
    for a, w in fields.values():  # the fast path: step() calls this for every sample
        if (None if a is None else getattr(a, "shape", None)) != w:
            break
    else:
        return
    import numpy as np

    got = tuple(None if a is None else np.shape(a) for a, _ in fields.values())
    want = tuple(w for _, w in fields.values())
    if got != want:
        text = config_says.format(*says) if says else config_says
        raise ParameterError(f"{method} state: {', '.join(fields)} {got} do not match the "
                             f"config's {text} (wanted {want})")


def config_from_params(cls: type[C], params: dict[str, Any] | None = None, **defaults: Any) -> C:
    """Instantiate dataclass ``cls`` from ``defaults`` overridden by ``params``.

    Text values are read as the field's annotated type (:func:`parse_value`); other values are
    passed as given. An unknown name raises :class:`ParameterError` with the closest names.
    """
    typs = field_types(cls)
    kw = dict(defaults)
    for name, value in (params or {}).items():
        if name not in typs:
            raise unknown(name, cls.__name__, flat_names(cls))
        kw[name] = parse_value(value, typs[name], name)
    return cls(**kw)


def parse_params(items: list[str] | None) -> dict[str, str]:
    """``['q_omega=4', 'fit=q_omega,r', 'M=2,omega_max=100']`` -> ``{'q_omega': '4', 'fit':
    'q_omega,r', 'M': '2', 'omega_max': '100'}``: text values, read later against the field
    types. A comma starts a new parameter only when ``NAME=`` follows it."""
    out: dict[str, str] = {}
    for item in items or []:
        last: str | None = None
        for part in item.split(","):
            if _NAME_EQ.match(part):
                k, v = part.split("=", 1)
                last = k.strip()
                out[last] = v.strip()
            elif last is not None:
                out[last] = f"{out[last]},{part.strip()}"
            elif part.strip():
                raise ParameterError(f"parameter '{part.strip()}' must be written NAME=VALUE")
    return out


def flat_dict(config: Any) -> dict[str, Any]:
    """A Config dataclass as a flat dict: the fields of its ``model`` (which must have
    ``to_dict()``) followed by its own fields (for JSON sidecars and Track params)."""
    out = dict(config.model.to_dict())
    for f in dataclasses.fields(config):
        if f.name != "model":
            out[f.name] = getattr(config, f.name)
    return out
