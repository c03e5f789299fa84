"""Scale invariance for the harmonic trackers: causal running-RMS normalisation.

The paper's Table I noise intensities (``var(v^alpha) = 0.001``, ``var(alpha_0) = 0.1``) and any
measurement variance ``r`` only mean something relative to the amplitude of the pre-filtered
signal, which differs by orders of magnitude between a car's sensor cluster (m/s^2), a phone and
an int16 GoPro stream (raw counts). The trackers therefore see

    y_k' = s * y_k / rms_k,     rms_k^2 = sum_j a^(k-j) y_j^2 / sum_j a^(k-j),   a = exp(-T / tau)

an exponentially weighted RMS over the last ``tau`` seconds (bias-corrected, so it is the plain
RMS of the samples seen while ``k * T << tau``), with ``s`` the signal RMS the parameters are
tuned for (:data:`DEFAULT_SIGNAL_RMS`). Equivalently: the model's ``r`` and ``q_amp`` are read as
fractions of the running signal power (a data-driven ``R``). The normalisation is causal and
streaming (:class:`RmsState`), NaN samples pass as NaN and leave the state unchanged, and the
scale is recorded so that amplitudes can be mapped back (multiply by ``rms_k / s``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import ParameterError

#: RMS (in the filters' units) that the Table I parameters are applied to. Table I's
#: var(alpha_0) = var(beta_0) = 0.1 means a harmonic of variance 0.1, i.e. RMS ~0.55 for
#: three harmonics; 0.5 keeps that scale.
DEFAULT_SIGNAL_RMS = 0.5
#: time constant of the running RMS in s: long against a harmonic period (> 0.05 s at
#: omega >= 10 rad/s... 0.6 s), short against changes of road surface.
DEFAULT_TAU = 5.0
#: absolute floor on the RMS (signal units), so a zero signal does not divide by zero
RMS_FLOOR = 1e-12


class RmsState(NamedTuple):
    """Running sums: ``s`` = EMA of y^2, ``w`` = EMA of 1 (bias correction); both 0 at start."""

    s: float
    w: float


def init() -> RmsState:
    """Empty state (no sample seen)."""
    return RmsState(0.0, 0.0)


def decay(dt: float, tau: float) -> float:
    """Per-sample forgetting factor ``a = exp(-dt / tau)``."""
    if not tau > 0 or not dt > 0:
        raise ParameterError(f"running RMS needs tau > 0 and dt > 0, got tau={tau}, dt={dt}")
    return float(np.exp(-dt / tau))


@njit(cache=True)
def _rms_run(y, a, s, w, target, out_y, out_rms):
    for k in range(y.size):
        v = y[k]
        if np.isfinite(v):
            s = a * s + (1.0 - a) * v * v
            w = a * w + (1.0 - a)
            rms = np.sqrt(s / w)
            if rms < 1e-12:
                rms = 1e-12
            out_rms[k] = rms
            out_y[k] = target * v / rms
        else:
            out_rms[k] = np.sqrt(s / w) if w > 0.0 else np.nan
            out_y[k] = np.nan
    return s, w


def step(state: RmsState, y: float, a: float, target: float = DEFAULT_SIGNAL_RMS):
    """One sample: returns ``(state, y_scaled, rms)``; identical to :func:`run`."""
    oy = np.empty(1)
    orms = np.empty(1)
    s, w = _rms_run(np.array([float(y)]), a, state.s, state.w, target, oy, orms)
    return RmsState(s, w), float(oy[0]), float(orms[0])


def run(
    y: np.ndarray,
    a: float,
    target: float = DEFAULT_SIGNAL_RMS,
    state: RmsState | None = None,
) -> tuple[np.ndarray, np.ndarray, RmsState]:
    """Normalise a whole signal: ``(y_scaled (n,), rms (n,), final state)``."""
    st = init() if state is None else state
    y = np.ascontiguousarray(y, dtype=np.float64)
    oy = np.empty_like(y)
    orms = np.empty_like(y)
    s, w = _rms_run(y, a, st.s, st.w, target, oy, orms)
    return oy, orms, RmsState(s, w)


def normalise(
    y: np.ndarray, dt: float, *, tau: float = DEFAULT_TAU, target: float = DEFAULT_SIGNAL_RMS
) -> tuple[np.ndarray, np.ndarray]:
    """``(y_scaled, rms)`` with the causal running RMS of time constant ``tau`` s."""
    oy, orms, _ = run(y, decay(dt, tau), target)
    return oy, orms
