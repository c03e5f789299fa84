"""The plain baseline every tracker is compared with: a 3 s STFT harmonic sum.

Per Hann window of ``win_s`` s (every ``hop_s`` s, zero-padded to 4x) the estimate is the grid
point omega in ``omega_min..omega_max`` that maximises ``sum_m |X(m omega)|``, m = 1..M (linear
interpolation between FFT bins; harmonics above Nyquist folded to their alias). Offline the
values refer to the window centres and are interpolated between them; causally
(``causal=True``, what a device can do) each value holds from its window's end, and with a
``lag`` of S s (a device that reports S s late, as the grid's fixed-lag smoother) each sample
takes the offline value where the windows it interpolates end within S s of it, else the
latest window ending by then. No pre-filter
here: give it the signal the compared tracker sees, or the raw axis high-passed.
:func:`stft_track` is the benchmarks' form on a recording (its axis high-passed with
``thesis-hp``) as a :class:`~vibrospeed.types.Track`, to score as an estimate is scored.
"""

from __future__ import annotations

import numpy as np

from vibrospeed.types import Recording, Track

#: the pre-filter of the benchmarks' baseline (benchmarks/robustness): the axis high-passed
PREFILTER = "thesis-hp"


def stft_harmonic_sum(y: np.ndarray, dt: float, omega_min: float, omega_max: float, *,
                      n_grid: int = 300, M: int = 3, win_s: float = 3.0, hop_s: float = 0.25,
                      causal: bool = False, lag: float = 0.0) -> np.ndarray:
    """omega (rad/s) per sample of ``y`` (module docstring); NaN samples count 0, samples
    before the first causal window (ending within ``lag`` s of them) are NaN."""
    y = np.asarray(y, dtype=np.float64)
    n = y.size
    if not (np.isfinite(lag) and lag >= 0.0) or (lag > 0 and not causal):
        raise ValueError(f"lag must be a finite number >= 0 s, with causal=True; got {lag}")
    L = int(round(win_s / dt))
    hop = max(1, int(round(hop_s / dt)))
    if n < L:
        return np.full(n, np.nan)
    nfft = 1 << int(np.ceil(np.log2(4 * L)))
    f = 2 * np.pi * np.fft.rfftfreq(nfft, dt)
    grid = np.linspace(omega_min, omega_max, n_grid)
    nyq = np.pi / dt
    win = np.hanning(L)
    starts = np.arange(0, n - L + 1, hop)
    x = np.nan_to_num(np.lib.stride_tricks.sliding_window_view(y, L)[starts])
    mag = np.abs(np.fft.rfft((x - x.mean(axis=1, keepdims=True)) * win, nfft, axis=1))
    score = np.zeros((starts.size, n_grid))
    for m in range(1, M + 1):
        w = np.abs((m * grid + nyq) % (2 * nyq) - nyq)  # folded frequency
        idx = np.interp(w, f, np.arange(f.size))
        i0 = np.floor(idx).astype(int)
        fr = idx - i0
        i1 = np.minimum(i0 + 1, f.size - 1)
        score += mag[:, i0] * (1 - fr) + mag[:, i1] * fr
    vals = grid[np.argmax(score, axis=1)]
    i = np.arange(n)
    centres = starts + L // 2
    if not causal:
        return np.interp(i, centres, vals)
    ends = starts + L - 1
    ahead = int(np.floor(lag / dt + 1e-9))  # samples of look-ahead
    j = np.searchsorted(ends, i + ahead, side="right") - 1  # the latest window ended by then
    out = np.where(j >= 0, vals[np.maximum(j, 0)], np.nan)
    if ahead > 0:  # the offline value where its windows (up to the next centre) have ended
        k1 = np.minimum(np.searchsorted(centres, i, side="right"), centres.size - 1)
        ok = ends[k1] <= i + ahead
        out[ok] = np.interp(i[ok], centres, vals)
    return out


def stft_track(recording: Recording, *, axis: str = "y", omega_min: float, omega_max: float,
               causal: bool = False, wheel_radius: float | None = None, n_grid: int = 300,
               M: int = 3, win_s: float = 3.0, hop_s: float = 0.25, lag: float = 0.0) -> Track:
    """The plain baseline of the benchmarks on ``recording`` as a Track (method ``"stft"``):
    the ``axis`` channel (``"y"`` or ``"ay"``, as the estimators take it; a sign is ignored,
    the spectrum's magnitudes do not see it) with NaN as 0, high-passed with
    :data:`PREFILTER`, then :func:`stft_harmonic_sum` over ``omega_min..omega_max`` rad/s
    (``causal``: each value from its window's end; ``lag``: from the windows ended ``lag`` s
    after it, as a device that reports that late). No band (NaN); speed = ``wheel_radius``
    times omega where the radius is given. A recording whose time stamps are further than
    :data:`vibrospeed.io.timebase.UNIFORM_ENOUGH` from uniform is resampled first, as the CLI
    reads one for the estimators. Its purpose: every estimate compared with what a plain
    3 s spectrogram gives on the same data."""
    from vibrospeed.estimators.common import signed_axis
    from vibrospeed.io import timebase
    from vibrospeed.signal import prefilter as pf

    channel = signed_axis(axis)[0]
    recording.require(channel)
    if not recording.is_uniform(rtol=timebase.UNIFORM_ENOUGH):
        recording = timebase.resample_uniform(recording)
    y = pf.apply(pf.design(PREFILTER, recording.fs), np.nan_to_num(recording.channel(channel)))
    omega = stft_harmonic_sum(y, recording.dt, omega_min, omega_max, n_grid=n_grid, M=M,
                              win_s=win_s, hop_s=hop_s, causal=causal, lag=lag)
    nan = np.full(omega.shape, np.nan)
    params = {"axis": channel, "omega_min": float(omega_min), "omega_max": float(omega_max),
              "causal": bool(causal), "lag": float(lag), "prefilter": PREFILTER,
              "n_grid": int(n_grid), "M": int(M), "win_s": float(win_s), "hop_s": float(hop_s)}
    return Track.from_omega(recording.t, omega, lo=nan, hi=nan, wheel_radius=wheel_radius,
                            method="stft", params=params)
