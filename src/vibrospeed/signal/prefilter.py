"""Butterworth pre-filters as second-order sections, batch and streaming (thesis 2.2, 3.4-3.5;
chassis-vibration paper section IV).

Presets (cut-offs in rad/s unless said otherwise, digital design with ``fs``):

=============== ===================================================================
``thesis-hp``   high-pass order 2 at 4 rad/s (thesis 3.4)
``thesis-bp``   band-pass order 2, 4..50 rad/s (thesis eq. 2.7)
``thesis-hplp`` high-pass order 2 at 4 rad/s + low-pass order 1 with a cut-off per M:
                M = 1: 12, M = 2: 19, M = 3: 10, M = 4: 8 rad/s (thesis table 3.1, the
                best omega_lp per M; M > 4 uses M = 4's)
``paper-hp``    high-pass order 2 at 8 Hz (chassis-vibration paper, section IV)
``range``       tied to the search range ``omega_min..omega_max``: high-pass order 4 at
                ``RANGE_HP * omega_min``, low-pass order 4 at ``RANGE_LP * M * omega_max``
                (left out when that is above ``0.4 fs``: the harmonics alias there)
``whiten``      ``thesis-hp``, then adaptive pre-whitening (:mod:`vibrospeed.signal.whiten`):
                the background spectrum, whatever its shape, divided out; lines kept
``none``        identity
=============== ===================================================================

Batch filtering starts from the steady state of the first sample (``sosfilt_zi * x[0]``), so a
constant offset such as gravity produces no start-up transient; the streaming state does the same
on its first sample, and ``apply`` equals repeated ``step`` exactly.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import ParameterError
from vibrospeed.signal import dsp

#: thesis low-pass cut-offs (rad/s) per number of harmonics M (thesis section 3.5, table 3.1:
#: omega_lp 12 / 19 / 10 / 8 for M = 1 / 2 / 3 / 4)
THESIS_LP_CUTOFF = {1: 12.0, 2: 19.0, 3: 10.0, 4: 8.0}

PRESETS = {
    "thesis-hp": "Butterworth high-pass order 2 at 4 rad/s (thesis 3.4)",
    "thesis-bp": "Butterworth band-pass order 2, 4..50 rad/s (thesis eq. 2.7)",
    "thesis-hplp": "high-pass order 2 at 4 rad/s + low-pass order 1, cut-off per M (thesis 3.5)",
    "paper-hp": "Butterworth high-pass order 2 at 8 Hz (chassis-vibration paper IV)",
    "range": "high-pass order 4 below omega_min, low-pass order 4 above M omega_max",
    "whiten": "thesis-hp, then adaptive pre-whitening of the background (signal.whiten)",
    "none": "no pre-filter",
}


#: presets followed by the adaptive whitener (:mod:`vibrospeed.signal.whiten`) after their SOS
ADAPTIVE = frozenset({"whiten"})

#: ``range`` preset: high-pass corner as a fraction of omega_min, low-pass corner as a multiple
#: of M omega_max. A vehicle's body motion and manoeuvres (0.2-1.5 m/s^2 below 2 Hz on a car,
#: 10-20x a wheel harmonic) lie below the search range; what is left of them in it is what the
#: tracker must live with, so everything below it goes.
RANGE_HP = 0.7
RANGE_LP = 1.3


def _rad_to_hz(w: float) -> float:
    return w / (2.0 * np.pi)


def butter_sos(
    kind: str, cutoff_hz: float | tuple[float, float], fs: float, order: int = 2
) -> np.ndarray:
    """Digital Butterworth SOS; ``kind`` in 'highpass', 'lowpass', 'bandpass'
    (``scipy.signal.butter(order, cutoff_hz, kind, fs=fs, output="sos")`` bit for bit, computed
    by :func:`vibrospeed.signal.dsp.butter_sos` without importing ``scipy.signal``)."""
    nyq = fs / 2.0
    cuts = np.atleast_1d(np.asarray(cutoff_hz, dtype=float))
    if np.any(cuts <= 0) or np.any(cuts >= nyq):
        raise ParameterError(
            f"{kind} cut-off {cutoff_hz} Hz must lie in (0, {nyq:g}) Hz for fs = {fs:g} Hz"
        )
    wn = float(cuts[0]) if cuts.size == 1 else (float(cuts[0]), float(cuts[1]))
    return dsp.butter_sos(order, wn, kind, fs)


def design(
    preset: str = "thesis-hp",
    fs: float = 100.0,
    *,
    M: int = 3,
    lp_cutoff: float | None = None,
    hp_cutoff: float | None = None,
    omega_range: tuple[float, float] | None = None,
) -> np.ndarray:
    """SOS array (n_sections, 6) of a named preset.

    Parameters
    ----------
    preset : one of :data:`PRESETS`.
    fs : sample rate in Hz.
    M : number of harmonics tracked (chooses the ``thesis-hplp`` low-pass cut-off).
    lp_cutoff, hp_cutoff : override the preset's cut-offs, in rad/s (Hz for ``paper-hp``).
    omega_range : rad/s, the tracker's search range (needed by ``range``).

    Examples
    --------
    >>> sos = design("thesis-hplp", 100.0, M=2)
    >>> sos.shape
    (2, 6)
    """
    if preset == "none":
        return np.array([[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]])
    if preset in ("thesis-hp", "whiten"):
        return butter_sos("highpass", _rad_to_hz(hp_cutoff or 4.0), fs, 2)
    if preset == "thesis-bp":
        lo = hp_cutoff or 4.0
        hi = lp_cutoff or 50.0
        return butter_sos("bandpass", (_rad_to_hz(lo), _rad_to_hz(hi)), fs, 2)
    if preset == "thesis-hplp":
        lp = lp_cutoff or THESIS_LP_CUTOFF[min(max(int(M), 1), 4)]
        hp = butter_sos("highpass", _rad_to_hz(hp_cutoff or 4.0), fs, 2)
        return np.vstack([hp, butter_sos("lowpass", _rad_to_hz(lp), fs, 1)])
    if preset == "paper-hp":
        return butter_sos("highpass", hp_cutoff or 8.0, fs, 2)
    if preset == "range":
        if omega_range is None:
            raise ParameterError("pre-filter 'range' needs the search range omega_min..omega_max")
        lo, hi = (float(w) for w in omega_range)
        sos = butter_sos("highpass", _rad_to_hz(hp_cutoff or RANGE_HP * lo), fs, 4)
        lp = _rad_to_hz(lp_cutoff or RANGE_LP * M * hi)
        if lp < 0.4 * fs:
            sos = np.vstack([sos, butter_sos("lowpass", lp, fs, 4)])
        return sos
    raise ParameterError(f"unknown pre-filter '{preset}' (choose from: {', '.join(PRESETS)})")


class PrefilterState(NamedTuple):
    """Streaming filter state: ``zi`` (n_sections, 2); ``started`` False until the first sample."""

    zi: np.ndarray
    started: bool


def init(sos: np.ndarray, level: float | None = None) -> PrefilterState:
    """Streaming state at rest on a constant input ``level``.

    ``None``: the first sample sets the level. A better level is the mean of the first second
    (a device can buffer it): starting at ``x[0]`` turns the vibration's own value at that
    instant into a step that the high-pass rings out for about a second, and that transient can
    pull a tracker off a line.
    """
    if level is None or not np.isfinite(level):
        return PrefilterState(np.zeros((sos.shape[0], 2)), False)
    return PrefilterState(dsp.sosfilt_zi(sos) * float(level), True)


@njit(cache=True)
def _sos_step(sos, zi, x, zf):
    """One sample ``x`` through the sections from the state ``zi`` (n_sections, 2) into
    ``zf``: transposed direct form II in the operation order of scipy's ``sosfilt``, so that
    :func:`apply` equals repeated :func:`step` bitwise."""
    if sos.shape[1] != 6 or zi.shape[0] != sos.shape[0] or zi.shape[1] != 2:
        raise ValueError("pre-filter state: zi must be (n_sections, 2) for sos (n_sections, 6)")
    v = x
    for k in range(sos.shape[0]):
        out = sos[k, 0] * v + zi[k, 0]
        zf[k, 0] = sos[k, 1] * v - sos[k, 4] * out + zi[k, 1]
        zf[k, 1] = sos[k, 2] * v - sos[k, 5] * out
        v = out
    return v


def step(sos: np.ndarray, state: PrefilterState, x: float) -> tuple[PrefilterState, float]:
    """Filter one sample. NaN input gives NaN output and leaves the state unchanged.

    One compiled call (scipy's ``sosfilt`` costs ~90 us per call from Python) into fresh
    state storage: ``state`` is left as it is."""
    x = float(x)
    if not math.isfinite(x):
        return state, math.nan
    if type(sos) is not np.ndarray or sos.dtype != np.float64 or not sos.flags.c_contiguous:
        sos = np.ascontiguousarray(sos, dtype=np.float64)
    zi = state.zi if state.started else dsp.sosfilt_zi(sos) * x
    zf = np.empty((sos.shape[0], 2))
    return PrefilterState(zf, True), _sos_step(sos, zi, x, zf)


def apply(sos: np.ndarray, x: np.ndarray, level: float | None = None) -> np.ndarray:
    """Filter a whole signal causally; NaN samples pass as NaN and leave the state unchanged.

    ``level``: the constant input the filter is at rest on before the first sample (see
    :func:`init`); None = the first finite sample. Equals repeated :func:`step` from
    ``init(sos, level)`` (NaN-free runs are filtered in one ``sosfilt`` call each).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.full_like(x, np.nan)
    finite = np.isfinite(x)
    if not finite.any():
        return y
    zi = None if level is None or not np.isfinite(level) else dsp.sosfilt_zi(sos) * float(level)
    # contiguous runs of finite samples; the state carries over NaN gaps unchanged
    idx = np.flatnonzero(finite)
    breaks = np.flatnonzero(np.diff(idx) > 1) + 1
    for run in np.split(idx, breaks):
        seg = x[run[0] : run[-1] + 1]
        if zi is None:
            zi = dsp.sosfilt_zi(sos) * seg[0]
        out, zi = dsp.sosfilt(sos, seg, zi)
        y[run[0] : run[-1] + 1] = out
    return y
