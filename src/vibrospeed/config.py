"""Build frozen parameter dataclasses from user-supplied ``NAME=VALUE`` overrides."""

from __future__ import annotations

import dataclasses
import typing
from typing import Any, TypeVar

from vibrospeed.errors import ParameterError

C = TypeVar("C")


def _convert(value: Any, typ: Any, name: str) -> Any:
    if not isinstance(value, str):
        return value
    origin = typing.get_origin(typ)
    args = typing.get_args(typ)
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        if value.lower() in ("none", "null", "") and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(value, a, name)
            except ParameterError:
                continue
        raise ParameterError(f"parameter '{name}': cannot read '{value}'")
    try:
        if typ in (float, "float"):
            return float(value)
        if typ in (int, "int"):
            return int(float(value)) if float(value).is_integer() else int(value)
        if typ in (bool, "bool"):
            if value.lower() in ("1", "true", "yes", "on"):
                return True
            if value.lower() in ("0", "false", "no", "off"):
                return False
            raise ValueError(value)
        if origin is tuple or typ is tuple:
            inner = args[0] if args else float
            return tuple(_convert(v, inner, name) for v in value.split(":") if v)
    except ValueError:
        raise ParameterError(f"parameter '{name}': cannot read '{value}' as {typ}") from None
    return value


def config_from_params(cls: type[C], params: dict[str, Any] | None = None, **defaults: Any) -> C:
    """Instantiate dataclass ``cls`` from ``defaults`` overridden by ``params``.

    String values are converted to the field's annotated type; unknown names raise
    :class:`ParameterError` listing the valid ones.
    """
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    hints = typing.get_type_hints(cls)
    kw = dict(defaults)
    for name, value in (params or {}).items():
        if name not in fields:
            raise ParameterError(
                f"unknown parameter '{name}' for {cls.__name__} "
                f"(valid: {', '.join(sorted(fields))})"
            )
        kw[name] = _convert(value, hints.get(name, type(value)), name)
    return cls(**kw)


def parse_params(items: list[str] | None) -> dict[str, str]:
    """``['q_omega=4', 'M=2']`` -> ``{'q_omega': '4', 'M': '2'}``."""
    out: dict[str, str] = {}
    for item in items or []:
        for part in item.split(","):
            part = part.strip()
            if not part:
                continue
            if "=" not in part:
                raise ParameterError(f"parameter '{part}' must be written NAME=VALUE")
            k, v = part.split("=", 1)
            out[k.strip()] = v.strip()
    return out


def flat_dict(config: Any) -> dict[str, Any]:
    """A Config dataclass as a flat dict: the fields of its ``model`` (which must have
    ``to_dict()``) followed by its own fields (for JSON sidecars and Track params)."""
    out = dict(config.model.to_dict())
    for f in dataclasses.fields(config):
        if f.name != "model":
            out[f.name] = getattr(config, f.name)
    return out
