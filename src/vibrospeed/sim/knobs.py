"""Checks of a scenario's knobs, shared by its configuration records.

A knob outside its domain (a negative probability, duration, rate or std) used to be taken
silently: a ``p_stop`` of -1 meant "never stop", a negative ``speed_wander`` or ``jitter`` the
same drive as 0, a negative interval a loop or NumPy's "high - low < 0". Each record's
``__post_init__`` calls :func:`check` so that such a value is one line naming the knob.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from vibrospeed.errors import ParameterError


def check(obj: Any, prefix: str = "", *, positive: Iterable[str] = (),
          nonnegative: Iterable[str] = (), fractions: Iterable[str] = (),
          intervals: Iterable[str] = (), nonnegative_each: Iterable[str] = (),
          counts: Iterable[str] = ()) -> None:
    """Raise :class:`ParameterError` for the first field of ``obj`` outside its domain.

    ``positive``: finite and > 0; ``nonnegative``: finite and >= 0; ``fractions``: in [0, 1];
    ``intervals``: a ``(min, max)`` pair with ``0 < min <= max``, both finite;
    ``nonnegative_each``: a tuple of finite values >= 0; ``counts``: an integer >= 0.
    ``prefix`` names the record in the message (``"vibration."``). NaN is left to
    :func:`vibrospeed.sim.scenarios.make_config`, which refuses it quoting the value given."""

    def fail(name: str, need: str) -> None:
        v = getattr(obj, name)
        if any(isinstance(x, float) and math.isnan(x) for x in (v if isinstance(v, tuple)
                                                                  else (v,))):
            return
        raise ParameterError(f"{prefix}{name} must be {need}, got {getattr(obj, name)!r}")

    for name in positive:
        v = getattr(obj, name)
        if not (math.isfinite(v) and v > 0):
            fail(name, "finite and > 0")
    for name in nonnegative:
        v = getattr(obj, name)
        if not (math.isfinite(v) and v >= 0):
            fail(name, "finite and >= 0")
    for name in fractions:
        if not 0 <= getattr(obj, name) <= 1:
            fail(name, "in [0, 1]")
    for name in intervals:
        v = tuple(getattr(obj, name))
        if len(v) != 2 or not all(math.isfinite(x) for x in v) or not 0 < v[0] <= v[1]:
            fail(name, "a pair (min, max) with 0 < min <= max")
    for name in nonnegative_each:
        if not all(math.isfinite(x) and x >= 0 for x in getattr(obj, name)):
            fail(name, "finite values >= 0")
    for name in counts:
        v = getattr(obj, name)
        if int(v) != v or v < 0:
            fail(name, "an integer >= 0")
