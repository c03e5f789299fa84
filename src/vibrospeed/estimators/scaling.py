"""Scale invariance for the harmonic trackers: the lead's causal running-RMS normaliser
(:mod:`vibrospeed.signal.normalize`) times a target RMS.

The paper's Table I noise intensities (``var(v^alpha) = 0.001``, ``var(alpha_0) = 0.1``) and any
measurement variance ``r`` only mean something relative to the amplitude of the pre-filtered
signal, which differs by orders of magnitude between a car's sensor cluster (m/s^2), a phone and
an int16 GoPro stream (raw counts). The trackers therefore see::

    y_k' = s * y_k / rms_k

with ``rms_k`` the running RMS of :func:`vibrospeed.signal.normalize.running_rms_normalize`
(exponential mean square, time constant ``tau``, a plain running mean during the first ``tau``
seconds) and ``s`` the signal RMS the parameters are tuned for (:data:`DEFAULT_SIGNAL_RMS`).
Equivalently: the model's ``r`` and ``q_amp`` are fractions of the running signal power.
Causal and streaming (:func:`step` with :class:`vibrospeed.signal.normalize.NormalizerState`);
NaN samples pass as NaN and leave the state unchanged; the scale ``rms_k`` is returned so that
amplitudes can be mapped back (multiply by ``rms_k / s``). There is no second implementation of
the running mean square here: this module only multiplies by ``s`` and recovers ``rms_k``.
"""

from __future__ import annotations

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.signal import normalize as _norm
from vibrospeed.signal.normalize import NormalizerState

#: RMS (in the filters' units) that the Table I parameters are applied to. Table I's
#: var(alpha_0) = var(beta_0) = 0.1 means a harmonic of variance 0.1, i.e. RMS ~0.55 for
#: three harmonics; 0.5 keeps that scale.
DEFAULT_SIGNAL_RMS = 0.5
#: time constant of the running RMS in s: long against a harmonic period, short against changes
#: of road surface.
DEFAULT_TAU = 5.0

RmsState = NormalizerState
init = _norm.init


def _check(dt: float, tau: float) -> None:
    if not tau > 0 or not dt > 0:
        raise ParameterError(f"running RMS needs tau > 0 and dt > 0, got tau={tau}, dt={dt}")


def _rms_from(y: np.ndarray, yn: np.ndarray, rms0: float = np.nan) -> np.ndarray:
    """rms_k = |y_k / yn_k| where defined; held from the previous sample at zeros and NaNs."""
    with np.errstate(divide="ignore", invalid="ignore"):
        rms = np.abs(y / yn)
    ok = np.isfinite(rms) & (yn != 0)
    idx = np.where(ok, np.arange(y.size), -1)
    np.maximum.accumulate(idx, out=idx)
    out = np.where(idx >= 0, rms[np.maximum(idx, 0)], rms0)
    return out


def step(state: NormalizerState, y: float, dt: float, tau: float = DEFAULT_TAU,
         target: float = DEFAULT_SIGNAL_RMS) -> tuple[NormalizerState, float, float]:
    """One sample: ``(state, y_scaled, rms)``; the same numbers as :func:`normalise`."""
    _check(dt, tau)
    st, yn = _norm.step(state, float(y), dt, tau)
    rms = float(np.sqrt(max(st.s, 1e-300))) if st.count > 0 else np.nan
    return st, target * yn, rms


def normalise(
    y: np.ndarray, dt: float, *, tau: float = DEFAULT_TAU, target: float = DEFAULT_SIGNAL_RMS
) -> tuple[np.ndarray, np.ndarray]:
    """``(y_scaled, rms)``: ``target * running_rms_normalize(y, dt, tau)`` and the RMS used."""
    _check(dt, tau)
    y = np.ascontiguousarray(y, dtype=np.float64)
    yn = _norm.running_rms_normalize(y, dt, tau)
    return target * yn, _rms_from(y, yn)
