"""Running-RMS normalisation: makes tracker parameters independent of the sensor's scale.

``y_n[k] = y[k] / sqrt(s[k])`` with ``s[k] = s[k-1] + (y[k]^2 - s[k-1]) * dt / tau`` (exponential
moving mean square, time constant ``tau`` s), started from the mean square of the first ``tau``
seconds. Causal, so the streaming and batch versions agree; NaN samples stay NaN and do not move
``s``. A cart's 0.05 m/s^2 and a car's 2 m/s^2 vibrations both become unit-RMS signals, so one
set of noise parameters (``r``, ``q_amp`` relative to unit power) serves both.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _running_rms(y, alpha, s0, floor):
    out = np.empty_like(y)
    s = s0
    for k in range(y.size):
        v = y[k]
        if np.isfinite(v):
            s += (v * v - s) * alpha
            out[k] = v / np.sqrt(max(s, floor))
        else:
            out[k] = np.nan
    return out


def running_rms_normalize(y: np.ndarray, dt: float, tau: float = 5.0) -> np.ndarray:
    """Divide ``y`` by its exponential running RMS (time constant ``tau`` s)."""
    y = np.ascontiguousarray(y, dtype=np.float64)
    n0 = max(1, int(round(tau / dt)))
    head = y[:n0][np.isfinite(y[:n0])]
    s0 = float(np.mean(head**2)) if head.size else 1.0
    fin = y[np.isfinite(y)]
    floor = max(1e-12 * (float(np.mean(fin**2)) if fin.size else 1.0), 1e-300)
    return _running_rms(y, min(1.0, dt / tau), max(s0, floor), floor)
