"""Spectrogram helper (angular-frequency axis, rad/s) for plots and diagnostics."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import signal as sps


class Spectrogram(NamedTuple):
    """Power spectral density ``power`` (n_freq, n_time) at ``omega`` (rad/s), times ``t`` (s)."""

    t: np.ndarray
    omega: np.ndarray
    power: np.ndarray


def spectrogram(
    x: np.ndarray,
    fs: float,
    *,
    window_s: float = 3.0,
    overlap: float = 0.75,
    t0: float = 0.0,
    omega_max: float | None = None,
) -> Spectrogram:
    """Hann-window STFT power of ``x`` (NaN replaced by 0), window ``window_s`` seconds.

    Times are window centres (plus ``t0``); ``omega`` in rad/s, cut at ``omega_max`` if given.
    """
    x = np.nan_to_num(np.asarray(x, dtype=np.float64) - np.nanmean(x))
    nper = int(max(16, min(x.size, round(window_s * fs))))
    nover = int(min(nper - 1, round(overlap * nper)))
    f, tt, p = sps.spectrogram(x, fs=fs, window="hann", nperseg=nper, noverlap=nover,
                               detrend="constant", scaling="density")
    om = 2 * np.pi * f
    if omega_max is not None:
        keep = om <= omega_max
        om, p = om[keep], p[keep]
    return Spectrogram(tt + t0, om, p)
