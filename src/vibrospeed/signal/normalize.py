"""Running-RMS normalisation: makes tracker parameters independent of the sensor's scale.

``y_n[k] = y[k] / sqrt(s[k])`` with ``s[k] = s[k-1] + (y[k]^2 - s[k-1]) * dt / tau`` (exponential
moving mean square, time constant ``tau`` s); during the first ``tau`` seconds the weight is
``1/(k+1)`` (a plain running mean), so the start needs no look-ahead. Causal: streaming and batch
agree; NaN samples stay NaN and do not move
``s``. A cart's 0.05 m/s^2 and a car's 2 m/s^2 vibrations both become unit-RMS signals, so one
set of noise parameters (``r``, ``q_amp`` relative to unit power) serves both.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


@njit(cache=True)
def _running_rms(y, alpha, floor):
    out = np.empty_like(y)
    s = 0.0
    count = 0.0
    for k in range(y.size):
        v = y[k]
        if np.isfinite(v):
            count += 1.0
            s += (v * v - s) * max(alpha, 1.0 / count)
            out[k] = v / np.sqrt(max(s, floor))
        else:
            out[k] = np.nan
    return out


def running_rms_normalize(
    y: np.ndarray, dt: float, tau: float = 5.0, floor: float = 1e-300
) -> np.ndarray:
    """Divide ``y`` by its exponential running RMS (time constant ``tau`` s).

    ``floor``: smallest mean square used (in squared signal units), guards exact zeros.
    """
    y = np.ascontiguousarray(y, dtype=np.float64)
    return _running_rms(y, min(1.0, dt / tau), floor)


class NormalizerState(NamedTuple):
    """Streaming state of :func:`running_rms_normalize`: mean square ``s`` and sample count."""

    s: float
    count: float


def init() -> NormalizerState:
    """Empty state."""
    return NormalizerState(0.0, 0.0)


def step(
    state: NormalizerState, y: float, dt: float, tau: float = 5.0, floor: float = 1e-300
) -> tuple[NormalizerState, float]:
    """One sample of :func:`running_rms_normalize` (same arithmetic, same numbers; plain
    float operations, IEEE as the compiled batch loop's)."""
    y = float(y)
    if not math.isfinite(y):
        return state, math.nan
    count = state.count + 1.0
    s = state.s + (y * y - state.s) * max(min(1.0, dt / tau), 1.0 / count)
    return NormalizerState(s, count), y / math.sqrt(max(s, floor))
