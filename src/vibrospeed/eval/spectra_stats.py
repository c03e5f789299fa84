"""Spectral statistics of accelerometer recordings, for calibrating the simulator on real data.

The quantities a vibration simulator must reproduce, measured the same way on real
recordings and simulated drives (``benchmarks/calibration/calibration.py``):

* **line amplitude**: the peak of an amplitude-correct Hann spectrum,
  ``A(f) = 2 |X(f)| / sum(w)``, so a sinusoid ``a cos(2 pi f0 t)`` reads ``a`` at ``f0``;
  :func:`frame_spectra` zero-pads ``pad`` times so that a line between FFT bins loses at most
  ~0.3 % (``pad = 8``) to scalloping; :func:`band_max` is the peak in a search band;
* **order-tracked line amplitude**: :func:`order_peaks`, the same Hann amplitude but demodulated
  with a known angle ``theta(t)`` (the wheel's, from a speed) instead of ``2 pi f t``:
  ``A(o) = 2 |sum w x exp(-i o theta)| / sum(w)`` searched over orders ``o`` near ``k``. At
  constant speed this is exactly the frequency spectrum at ``f = o omega / 2 pi``; while the
  speed changes within the frame the line stays sharp (no interpolation, no smear);
* **local noise floor**: :func:`band_median`, the median of the same spectrum near the line
  (a band around it, the line's own neighbourhood left out). For white noise of one-sided
  density ``S`` the median is ``sqrt(S) sqrt(3 ln 2 / T)`` for a window of ``T`` seconds
  (:func:`floor_from_asd`, :func:`asd_from_floor`);
* **band-limited standard deviations**: :func:`band_std` (zero-phase Butterworth, mean removed,
  optionally over a mask of samples: moving / standing);
* **spectral shape below 2 Hz**: :func:`loglog_knee` fits a straight line and a continuous
  two-piece line (a knee) to a PSD in log-log coordinates;
* **stationary bands** (body resonances): :func:`spectral_bands`, peaks of a PSD with their
  -3 dB width and prominence;
* :func:`power_law` fits ``y = c x^p`` (Theil-Sen on the logarithms).

Only numpy and scipy; NaN samples are tolerated where documented (left out of the statistics).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import signal as sps
from scipy import stats

__all__ = [
    "FrameSpectra",
    "amplitude_spectrum",
    "asd_from_floor",
    "band_max",
    "band_median",
    "band_std",
    "floor_from_asd",
    "frame_spectra",
    "loglog_knee",
    "order_peaks",
    "order_spectrum",
    "power_law",
    "spectral_bands",
    "welch_psd",
]


def _nfft(n: int, pad: int) -> int:
    """Next power of two >= pad * n."""
    return int(2 ** np.ceil(np.log2(max(pad * n, 2))))


def amplitude_spectrum(x: np.ndarray, fs: float, *, pad: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude-correct Hann spectrum ``2 |X| / sum(w)`` of one frame (mean removed).

    Returns ``(f, A)``: frequencies (Hz) and amplitudes in the units of ``x``; a sinusoid of
    amplitude ``a`` reads ``a`` at its frequency (to ~0.3 % between bins with ``pad = 8``).
    """
    x = np.asarray(x, dtype=np.float64)
    w = np.hanning(x.size)
    nfft = _nfft(x.size, pad)
    X = np.fft.rfft((x - x.mean()) * w, nfft)
    return np.fft.rfftfreq(nfft, 1.0 / fs), 2.0 * np.abs(X) / w.sum()


class FrameSpectra(NamedTuple):
    """Amplitude spectra of overlapping frames: ``A`` (n_frames, n_freq) at ``f`` (Hz);
    ``start`` (n_frames,) first sample index of each frame, ``n`` samples per frame."""

    f: np.ndarray
    A: np.ndarray
    start: np.ndarray
    n: int


def frame_spectra(x: np.ndarray, fs: float, *, win_s: float = 4.0, hop_s: float = 1.0,
                  pad: int = 8, fmax: float | None = None, chunk: int = 64) -> FrameSpectra:
    """:func:`amplitude_spectrum` of every ``win_s`` frame, hop ``hop_s`` (frame mean removed).

    Frames that contain a NaN get a NaN row. ``fmax`` drops the frequencies above it (memory).
    """
    x = np.asarray(x, dtype=np.float64)
    n = int(round(win_s * fs))
    hop = max(1, int(round(hop_s * fs)))
    start = np.arange(0, x.size - n + 1, hop) if x.size >= n else np.zeros(0, dtype=int)
    w = np.hanning(n)
    nfft = _nfft(n, pad)
    f = np.fft.rfftfreq(nfft, 1.0 / fs)
    keep = f.size if fmax is None else int(np.searchsorted(f, fmax, side="right"))
    f = f[:keep]
    A = np.empty((start.size, keep))
    view = np.lib.stride_tricks.sliding_window_view(x, n) if x.size >= n else None
    for i in range(0, start.size, chunk):
        fr = view[start[i:i + chunk]]
        fr = fr - fr.mean(axis=1, keepdims=True)
        A[i:i + chunk] = (2.0 / w.sum()) * np.abs(np.fft.rfft(fr * w, nfft, axis=1)[:, :keep])
    return FrameSpectra(f, A, start, n)


def _rows_in_band(f: np.ndarray, A: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    A = np.atleast_2d(A)
    lo = np.broadcast_to(np.asarray(lo, dtype=np.float64), (A.shape[0],))
    hi = np.broadcast_to(np.asarray(hi, dtype=np.float64), (A.shape[0],))
    return A, lo, hi


def band_max(f: np.ndarray, A: np.ndarray, lo, hi) -> np.ndarray:
    """Per row of ``A``, the largest value with ``lo <= f <= hi`` (NaN for an empty band).

    ``lo``, ``hi`` are scalars or one value per row: the search band of a line (Hz).
    """
    A, lo, hi = _rows_in_band(f, A, lo, hi)
    out = np.full(A.shape[0], np.nan)
    for i in range(A.shape[0]):
        a, b = np.searchsorted(f, lo[i], side="left"), np.searchsorted(f, hi[i], side="right")
        if b > a and np.isfinite(A[i, a:b]).all():
            out[i] = A[i, a:b].max()
    return out


def band_median(f: np.ndarray, A: np.ndarray, lo, hi, exclude=()) -> np.ndarray:
    """Per row of ``A``, the median over ``lo <= f <= hi`` without the intervals ``exclude``.

    ``exclude``: a sequence of ``(a, b)`` pairs (Hz; scalars or one value per row). NaN where
    fewer than 4 frequencies remain or the row has a NaN there.
    """
    A, lo, hi = _rows_in_band(f, A, lo, hi)
    ex = [(np.broadcast_to(np.asarray(a, float), (A.shape[0],)),
           np.broadcast_to(np.asarray(b, float), (A.shape[0],))) for a, b in exclude]
    out = np.full(A.shape[0], np.nan)
    for i in range(A.shape[0]):
        m = (f >= lo[i]) & (f <= hi[i])
        for a, b in ex:
            m &= ~((f >= a[i]) & (f <= b[i]))
        if m.sum() >= 4 and np.isfinite(A[i, m]).all():
            out[i] = float(np.median(A[i, m]))
    return out


def order_spectrum(x: np.ndarray, theta: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """Order-tracked Hann amplitude of one frame: ``2 |sum_n w_n x_n exp(-i o theta_n)| /
    sum(w)`` for each order ``o`` (cycles per radian of ``theta``, i.e. harmonic number when
    ``theta`` is the wheel angle). Mean removed; the Hann window is in time (samples).

    ``orders`` evenly spaced (as :func:`order_peaks` makes them) are evaluated by a running
    product of phasors (10x faster than one exponential per order and sample); any other
    set directly.
    """
    x = np.asarray(x, dtype=np.float64)
    w = np.hanning(x.size)
    xw = (x - x.mean()) * w
    ph = np.asarray(theta, dtype=np.float64) - theta[x.size // 2]
    o = np.asarray(orders, dtype=np.float64)
    d = np.diff(o)
    if o.size > 2 and np.allclose(d, d[0], rtol=1e-9, atol=1e-12):
        R = np.empty((o.size, x.size), dtype=np.complex128)
        R[0] = xw * np.exp(-1j * o[0] * ph)
        R[1:] = np.exp(-1j * d[0] * ph)
        np.cumprod(R, axis=0, out=R)
        return 2.0 * np.abs(R.sum(axis=1)) / w.sum()
    E = np.exp(-1j * np.outer(o, ph))
    return 2.0 * np.abs(E @ xw) / w.sum()


def order_peaks(x: np.ndarray, theta: np.ndarray, start: np.ndarray, n: int, lo, hi, *,
                pad: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Per frame ``x[s:s+n]`` (``s`` in ``start``), the largest :func:`order_spectrum` value
    over orders ``lo..hi`` (scalars or one per frame) and the order where it lies.

    The order grid step is ``2 pi / (pad * Theta)``, ``Theta`` the angle the frame spans (a
    ``pad``-times zero-padded spectrum). NaN for frames with NaN samples or no rotation.
    """
    x = np.asarray(x, dtype=np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    start = np.asarray(start, dtype=int)
    lo = np.broadcast_to(np.asarray(lo, dtype=np.float64), start.shape)
    hi = np.broadcast_to(np.asarray(hi, dtype=np.float64), start.shape)
    peak = np.full(start.size, np.nan)
    where = np.full(start.size, np.nan)
    for i, s in enumerate(start):
        xs, th = x[s:s + n], theta[s:s + n]
        span = th[-1] - th[0]
        if not (np.isfinite(xs).all() and np.isfinite(th).all() and span > 0
                and np.isfinite(lo[i]) and np.isfinite(hi[i]) and hi[i] >= lo[i]):
            continue
        step = 2.0 * np.pi / (pad * span)
        grid = lo[i] + step * np.arange(int(np.floor((hi[i] - lo[i]) / step + 0.5)) + 1)
        A = order_spectrum(xs, th, grid)
        j = int(np.argmax(A))
        peak[i], where[i] = A[j], grid[j]
    return peak, where


def floor_from_asd(asd: float, win_s: float = 4.0) -> float:
    """Median of the ``win_s`` Hann amplitude spectrum of white noise with one-sided amplitude
    density ``asd`` (units/sqrt(Hz)): ``asd * sqrt(3 ln 2 / win_s)`` (Rayleigh median)."""
    return float(asd * np.sqrt(3.0 * np.log(2.0) / win_s))


def asd_from_floor(floor: float, win_s: float = 4.0) -> float:
    """Inverse of :func:`floor_from_asd`: the white-noise density whose spectrum has that floor."""
    return float(floor / np.sqrt(3.0 * np.log(2.0) / win_s))


def band_std(x: np.ndarray, fs: float, lo: float | None = None, hi: float | None = None, *,
             mask: np.ndarray | None = None, order: int = 4) -> float:
    """Standard deviation of ``x`` between ``lo`` and ``hi`` Hz (None: open end).

    The mean is removed, NaN samples set to 0 for the zero-phase Butterworth filter of order
    ``order`` (``sosfiltfilt``) and left out afterwards; with ``mask`` only those samples count
    (the std is about their own mean). NaN if fewer than 2 samples count.
    """
    y = filtered(x, fs, lo, hi, order=order)
    m = np.isfinite(y) if mask is None else (np.asarray(mask, bool) & np.isfinite(y))
    if m.sum() < 2:
        return float("nan")
    return float(np.std(y[m]))


def filtered(x: np.ndarray, fs: float, lo: float | None = None, hi: float | None = None, *,
             order: int = 4) -> np.ndarray:
    """``x`` minus its mean, band-passed zero-phase to [lo, hi] Hz (NaN kept as NaN)."""
    x = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(x)
    if not ok.any():
        return np.full(x.shape, np.nan)
    y = np.where(ok, x - np.mean(x[ok]), 0.0)
    nyq = fs / 2.0
    if hi is not None and hi >= nyq:
        hi = None
    if lo is not None and lo <= 0:
        lo = None
    if lo is not None and hi is not None:
        sos = sps.butter(order, [lo, hi], btype="bandpass", fs=fs, output="sos")
    elif lo is not None:
        sos = sps.butter(order, lo, btype="highpass", fs=fs, output="sos")
    elif hi is not None:
        sos = sps.butter(order, hi, btype="lowpass", fs=fs, output="sos")
    else:
        sos = None
    if sos is not None and y.size > 3 * (2 * sos.shape[0] + 1):
        y = sps.sosfiltfilt(sos, y)
    return np.where(ok, y, np.nan)


def welch_psd(x: np.ndarray, fs: float, *, seg_s: float, mask: np.ndarray | None = None,
              overlap: float = 0.5, detrend: str = "linear") -> tuple[np.ndarray, np.ndarray, int]:
    """One-sided Welch PSD (units^2/Hz) from the Hann segments of ``seg_s`` seconds that lie
    wholly inside ``mask`` (default: all finite samples). Returns ``(f, P, n_segments)``;
    ``P`` is NaN when no segment fits."""
    x = np.asarray(x, dtype=np.float64)
    n = int(round(seg_s * fs))
    ok = np.isfinite(x) if mask is None else (np.asarray(mask, bool) & np.isfinite(x))
    hop = max(1, int(round(n * (1.0 - overlap))))
    f = np.fft.rfftfreq(n, 1.0 / fs)
    if x.size < n:
        return f, np.full(f.size, np.nan), 0
    bad = np.concatenate(([0], np.cumsum(~ok)))
    starts = np.arange(0, x.size - n + 1, hop)
    starts = starts[(bad[starts + n] - bad[starts]) == 0]
    if starts.size == 0:
        return f, np.full(f.size, np.nan), 0
    frames = np.lib.stride_tricks.sliding_window_view(x, n)[starts]
    frames = sps.detrend(frames, axis=1, type=detrend)
    w = np.hanning(n)
    X = np.fft.rfft(frames * w, axis=1)
    P = np.mean(np.abs(X) ** 2, axis=0) / (fs * np.sum(w * w))
    last = -1 if n % 2 == 0 else None  # the Nyquist bin (even n) is not doubled
    P[1:last] *= 2.0
    return f, P, int(starts.size)


class Knee(NamedTuple):
    """Log-log fit of a PSD: ``slope`` of one straight line; the continuous two-piece fit's
    ``slope_lo`` (below ``f_knee``) and ``slope_hi`` (above); ``gain``: how much the two-piece
    fit lowers the rms log10 residual relative to the straight line (0..1)."""

    slope: float
    slope_lo: float
    slope_hi: float
    f_knee: float
    gain: float


def loglog_knee(f: np.ndarray, P: np.ndarray, fmin: float = 0.1, fmax: float = 2.0, *,
                bins: int = 14, min_points: int = 3) -> Knee:
    """Fit ``log10 P`` against ``log10 f`` on ``[fmin, fmax]``, first averaged into ``bins``
    log-spaced bins (so that the many high-frequency points do not dominate).

    The knee is searched on a grid of log-spaced frequencies with at least ``min_points``
    binned points on each side. PSD slope -2 means the amplitude falls like 1/f.
    """
    f = np.asarray(f, float)
    P = np.asarray(P, float)
    edges = np.geomspace(fmin, fmax, bins + 1)
    lx, ly = [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        m = (f >= a) & (f < b) & np.isfinite(P) & (P > 0)
        if m.any():
            lx.append(np.log10(np.sqrt(a * b)))
            ly.append(np.log10(np.mean(P[m])))
    lx, ly = np.asarray(lx), np.asarray(ly)
    nan = float("nan")
    if lx.size < 2 * min_points:
        return Knee(nan, nan, nan, nan, nan)
    A1 = np.column_stack([np.ones_like(lx), lx])
    c1, *_ = np.linalg.lstsq(A1, ly, rcond=None)
    rss1 = float(np.sum((ly - A1 @ c1) ** 2))
    best = (np.inf, nan, nan, nan)
    for lk in np.linspace(lx[min_points - 1], lx[-min_points], 40):
        A2 = np.column_stack([np.ones_like(lx), np.minimum(lx - lk, 0.0),
                              np.maximum(lx - lk, 0.0)])
        c2, *_ = np.linalg.lstsq(A2, ly, rcond=None)
        rss = float(np.sum((ly - A2 @ c2) ** 2))
        if rss < best[0]:
            best = (rss, float(c2[1]), float(c2[2]), float(10 ** lk))
    gain = 1.0 - np.sqrt(best[0] / rss1) if rss1 > 0 else 0.0
    return Knee(float(c1[1]), best[1], best[2], best[3], float(gain))


class Band(NamedTuple):
    """A spectral band: centre ``f`` (Hz), ``fwhm`` (Hz, -3 dB width), ``prominence_db``
    (above the higher of the two surrounding minima), ``rms`` of the PSD's excess over that
    base within +-fwhm of the centre (units), ``asd`` the peak's amplitude density."""

    f: float
    fwhm: float
    prominence_db: float
    rms: float
    asd: float


def spectral_bands(f: np.ndarray, P: np.ndarray, fmin: float, fmax: float, *,
                   min_prominence_db: float = 3.0, min_fwhm: float = 0.0,
                   max_bands: int = 6, smooth_hz: float = 0.0) -> list[Band]:
    """Peaks of a PSD ``P`` on ``[fmin, fmax]`` with at least ``min_prominence_db`` of
    prominence (``scipy.signal.find_peaks`` on ``10 log10 P``) and a -3 dB width >= ``min_fwhm``.

    ``smooth_hz`` > 0 first averages ``P`` over that many Hz (a boxcar) to calm a noisy
    estimate. The ``max_bands`` most prominent, sorted by frequency.
    """
    f = np.asarray(f, float)
    P = np.asarray(P, float)
    m = (f >= fmin) & (f <= fmax) & np.isfinite(P) & (P > 0)
    f, P = f[m], P[m]
    if f.size < 5:
        return []
    df = float(np.median(np.diff(f)))
    if smooth_hz > df:
        k = int(round(smooth_hz / df)) | 1
        P = np.convolve(np.pad(P, k // 2, mode="edge"), np.ones(k) / k, mode="valid")
    L = 10.0 * np.log10(P)
    peaks, props = sps.find_peaks(L, prominence=min_prominence_db)
    out = []
    for i, p in enumerate(peaks):
        prom = float(props["prominences"][i])
        wid = sps.peak_widths(L, [p], rel_height=min(1.0, 3.0 / prom))
        fwhm = float(wid[0][0] * df)
        if fwhm < min_fwhm:
            continue
        base = 10 ** ((L[p] - prom) / 10.0)
        sel = np.abs(f - f[p]) <= fwhm
        rms = float(np.sqrt(np.sum(np.maximum(P[sel] - base, 0.0)) * df))
        # interpolated centre: middle of the -3 dB crossing points
        fc = float(np.interp((wid[2][0] + wid[3][0]) / 2.0, np.arange(f.size), f))
        out.append(Band(fc, fwhm, prom, rms, float(np.sqrt(P[p]))))
    out.sort(key=lambda b: -b.prominence_db)
    return sorted(out[:max_bands], key=lambda b: b.f)


def power_law(x: np.ndarray, y: np.ndarray) -> tuple[float, float, int]:
    """Robust fit of ``y = c x^p`` (Theil-Sen slope of log y on log x, median intercept).

    Returns ``(p, c, n)``; uses the pairs with finite, positive x and y; NaN with < 3 pairs.
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    m = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if m.sum() < 3 or np.ptp(np.log(x[m])) == 0:
        return float("nan"), float("nan"), int(m.sum())
    lx, ly = np.log(x[m]), np.log(y[m])
    if m.sum() > 400:  # Theil-Sen is O(n^2): thin evenly (the fit is robust anyway)
        idx = np.linspace(0, lx.size - 1, 400).round().astype(int)
        lx, ly = lx[idx], ly[idx]
    p, c, *_ = stats.theilslopes(ly, lx)
    return float(p), float(np.exp(c)), int(m.sum())
