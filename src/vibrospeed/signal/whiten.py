"""Adaptive pre-whitening: a vehicle's red, resonant background made flat, its lines kept.

A vehicle's accelerometer is dominated by what is not a wheel line: body motion and manoeuvres
below ~2 Hz (0.2-1.5 m/s^2 on a car, 10-20x a wheel harmonic), body bands, road noise that
grows with speed. A fixed high-pass either leaves that power in a car's search band or removes
a slow cart's fundamental; a Hann window leaks what is left onto the lines nearby, and a
tracker's time-domain model spends its harmonics on it. The whitener instead divides the
background out, whatever its shape:

* every ``BLOCK_S`` s, the background spectrum of the last ``WINDOW_S`` s is estimated line-
  robustly: per frequency the *median* over the ``SEGMENT_S`` s Hann segments (Welch with a
  median average), so a line that sweeps across a frequency while the vehicle speeds up or
  brakes does not enter it, then a running *median* over ``SMOOTH_HZ`` Hz, at most
  ``PEAK_MAX`` times the running median over ``PEAK_HZ`` Hz. A steady line (a cruise) is in
  every segment, and a 2 s Hann segment spreads it over a main lobe 2 Hz wide, wider than the
  1 Hz median: without the cap the background would hold the line ~20 dB up and the FIR would
  notch it out. The 3 Hz median (a main lobe and a half) leaves the line out, and the cap lets
  the whitener take at most ``PEAK_MAX`` (6 dB) off any narrow peak: wheel lines, engine
  orders and narrow body resonances all look alike to it (narrow peaks that hold for
  seconds), and telling them apart is the comb's work (its harmonic structure); the broad
  colour of the background (body motion, road noise) is whitened as before;
* its autocorrelation (inverse FFT) gives, by Levinson-Durbin, the order-``ORDER`` linear
  predictor ``a``; the block is filtered by the prediction-error FIR
  ``e[n] = sum_k a[k] x[n - k]``, ``a[0] = 1`` (Yule-Walker: ``e`` is white where ``x`` was
  the background alone), scaled so that the history keeps its power (the output stays in the
  input's units);
* across each block the output fades linearly from the previous block's FIR to the new one,
  ``e = (1 - l) e_prev + l e_new`` with ``l = (i + 1) / B`` at the block's i-th of B samples.
  A FIR applies its own gain and phase to a line, so a FIR switched at once puts a step in
  every line's amplitude and phase, and the tracker's phasor model, which integrates a weak
  line coherently over many seconds, loses the line at each step. The 9 s window keeps
  consecutive FIRs close and the fade makes their change continuous, while the 1 s blocks
  keep the FIR fresh. A median follows a change of the background (a start, a stop) once
  half the window has changed, so the window is a trade between holding the lines (longer)
  and following the stops (shorter); benchmarks/robustness/RESULTS.md, "levers measured in
  stop 24";
* before ``SEGMENT_S`` s of data the FIR is the identity.

Streaming (:func:`init` / :func:`step`) and batch (:func:`apply`) give the same numbers: both
compute the predictor from the same history at the same samples and run the same compiled FIR.
A NaN sample passes as NaN and leaves the state unchanged.

Computation. The predictor is the numbers of scipy's Welch median average, median filter,
``solve_toeplitz`` and ``lfilter``, bit for bit, without their per-call overhead (about 1 ms
per block): the FFTs are numpy's calls, the rest compiled kernels that take each sum in those
functions' order (:mod:`vibrospeed.signal._whiten_kernels`). :func:`apply` makes every block's
predictor in batches of blocks, each Welch segment's spectrum once (consecutive windows share
most segments); ``tests/test_scale_whiten.py`` checks the predictors against the scipy calls
(:func:`predictor_reference`).

On the randomised family (``benchmarks/robustness``, ``docs/robustness.md``) whitening after
the thesis high-pass lifts the grid tracker's share within tolerance most on cars and forklifts
(body motion in the band), at a small cost on some carts.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from vibrospeed.signal import dsp
from vibrospeed.signal._whiten_kernels import (
    _backgrounds,
    _filter_blocks,
    _finish,
    _fir_last,
    _segments,
)

ORDER = 12
WINDOW_S = 9.0
BLOCK_S = 1.0
SEGMENT_S = 2.0
SMOOTH_HZ = 1.0
PEAK_HZ = 3.0
PEAK_MAX = 4.0


class WhitenState(NamedTuple):
    """History of finite samples, samples seen, the current FIR ``a`` (ORDER + 1) and its gain,
    and the previous block's FIR and gain that the output fades from (``a_prev`` None: the two
    are equal, nothing to fade).

    The history is ``buf[max(0, end - K):end]``, K = ``max(WINDOW_S s, ORDER + 1)`` samples,
    oldest first. ``buf`` is storage shared with the states that follow: a step appends at
    ``buf[end]`` when ``tip[0] == end`` (no later sample written yet) and otherwise copies the
    last K samples to fresh storage, so what a state reads is never written again and an old
    state can be stepped again (or kept) safely."""

    buf: np.ndarray
    end: int
    tip: np.ndarray
    count: int
    a: np.ndarray
    gain: float
    a_prev: np.ndarray | None
    gain_prev: float


@functools.lru_cache(maxsize=64)
def _sizes(fs: float) -> tuple[int, int, int]:
    return (max(1, int(round(WINDOW_S * fs))), max(1, int(round(BLOCK_S * fs))),
            max(8, int(round(SEGMENT_S * fs))))


class _Plan(NamedTuple):
    """Welch's constants at one sample rate: segment length and hop, the window it applies
    (Hann, scaled to a density), the bins it doubles, the running medians' widths and the
    median's bias per segment count."""

    seg: int
    hop: int
    win: np.ndarray
    dbl_hi: int
    k: int
    kw: int
    bias: np.ndarray


def _widths(df: float) -> tuple[int, int]:
    """The running medians' widths in bins of ``df`` Hz (odd, at least 3): ``SMOOTH_HZ`` and
    ``PEAK_HZ``."""
    return (2 * max(1, int(round(0.5 * SMOOTH_HZ / df))) + 1,
            2 * max(1, int(round(0.5 * PEAK_HZ / df))) + 1)


@functools.lru_cache(maxsize=16)
def _plan(fs: float) -> _Plan:
    W, _, seg = _sizes(fs)
    hop = seg - seg // 2
    # ShortTimeFFT(get_window("hann", seg), hop, fs, mfft=seg, scale_to="psd")'s window and
    # frequencies (scipy.signal's numbers, from vibrospeed.signal.dsp)
    win = np.ascontiguousarray(dsp.psd_window(dsp.hann(seg), fs), dtype=np.float64)
    f = np.fft.rfftfreq(seg, 1 / fs)
    k, kw = _widths(f[1] - f[0])
    return _Plan(seg, hop, win, seg // 2 if seg % 2 == 0 else seg // 2 + 1, k, kw,
                 _bias(max(W, seg) // hop + 2))


@functools.lru_cache(maxsize=16)
def _bias(nmax: int) -> np.ndarray:
    """``bias[n]``: the median's bias for n segments (n >= 2), the operations of scipy.signal's
    ``_median_bias(n)``; ``bias[0], bias[1]`` unused."""
    bias = np.ones(nmax + 1)
    for n in range(2, nmax + 1):
        ii_2 = 2 * np.arange(1.0, (n - 1) // 2 + 1)
        bias[n] = 1 + np.sum(1.0 / (ii_2 + 1) - 1.0 / ii_2)
    return bias


def _predictors(z: np.ndarray, w0: np.ndarray, w1: np.ndarray,
                fs: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, G)``: :func:`predictor` of ``z[w0[b]:w1[b]]`` for each block b (``z``
    contiguous float64), each distinct Welch segment's spectrum computed once."""
    pl = _plan(fs)
    nb = w0.size
    A = np.zeros((nb, ORDER + 1))
    A[:, 0] = 1.0
    G = np.ones(nb)
    m = w1 - w0
    nseg = np.where(m >= pl.seg, (m - pl.seg // 2) // pl.hop, 0)
    use = np.flatnonzero(nseg > 0)
    if use.size == 0:
        return A, G
    mx = int(nseg.max())
    q = np.arange(mx)
    starts = w0[use, None] + q[None, :] * pl.hop  # (blocks, segments), past nseg unused
    valid = q[None, :] < nseg[use, None]
    uniq, inv = np.unique(starts[valid], return_inverse=True)
    rows = np.zeros(starts.shape, dtype=np.int64)
    rows[valid] = inv
    if 2 * (pl.seg // 2) < ORDER + 1:  # the autocorrelation is shorter than the predictor
        return A, G  # (solve_toeplitz's shapes disagree: the identity, as predictor_reference)
    segs = np.empty((uniq.size, pl.seg))
    _segments(z, uniq.astype(np.int64), pl.seg, pl.win, segs)
    X = np.fft.rfft(segs, n=pl.seg, axis=-1)
    S = np.empty((use.size, X.shape[1]))
    bias = pl.bias if mx < pl.bias.size else _bias(mx)
    _backgrounds(X, rows, nseg[use].astype(np.int64), bias, pl.dbl_hi, pl.k, pl.kw,
                 float(PEAK_MAX), S)
    R = np.ascontiguousarray(np.fft.irfft(S)[:, : ORDER + 1])
    Au = A[use]
    Gu = np.ones(use.size)
    _finish(R, z, w0[use].astype(np.int64), w1[use].astype(np.int64), ORDER, Au, Gu)
    A[use] = Au
    G[use] = Gu
    return A, G


def predictor(hist: np.ndarray, fs: float) -> tuple[np.ndarray, float]:
    """``(a, gain)``: prediction-error FIR of the line-robust background of ``hist`` and the
    gain that keeps ``hist``'s power through it; identity while ``hist`` is short."""
    z = np.ascontiguousarray(hist, dtype=np.float64)
    A, G = _predictors(z, np.zeros(1, np.int64), np.full(1, z.size, np.int64), fs)
    return A[0], float(G[0])


def predictor_reference(hist: np.ndarray, fs: float) -> tuple[np.ndarray, float]:
    """:func:`predictor` by the scipy and numpy calls it reproduces (for tests; ~1 ms)."""
    from scipy import signal as sps
    from scipy.linalg import solve_toeplitz
    from scipy.ndimage import median_filter

    _, _, seg = _sizes(fs)
    ident = np.zeros(ORDER + 1)
    ident[0] = 1.0
    if hist.size < seg:
        return ident, 1.0
    f, P = sps.welch(hist, fs=fs, nperseg=seg, average="median")
    k, kw = _widths(f[1] - f[0])
    S = np.minimum(median_filter(P, size=k, mode="nearest"),
                   PEAK_MAX * median_filter(P, size=kw, mode="nearest"))
    r = np.fft.irfft(S)[: ORDER + 1]
    if not r[0] > 0:
        return ident, 1.0
    r = r / r[0]
    try:
        coef = solve_toeplitz(r[:ORDER], -r[1 : ORDER + 1])
    except (np.linalg.LinAlgError, ValueError):
        return ident, 1.0
    a = np.concatenate(([1.0], coef))
    err = float(r[0] + np.dot(coef, r[1 : ORDER + 1]))
    if not np.all(np.isfinite(a)) or not err > 1e-12:
        return ident, 1.0
    var = float(np.mean(np.square(np.asarray(sps.lfilter(a, [1.0], hist))[ORDER:])))
    ref = float(np.mean(np.square(hist - np.mean(hist))))
    return a, (np.sqrt(ref / var) if var > 0 and ref > 0 else 1.0)


def init() -> WhitenState:
    """Empty history, identity FIR."""
    a = np.zeros(ORDER + 1)
    a[0] = 1.0
    return WhitenState(np.zeros(0), 0, np.zeros(1, dtype=np.int64), 0, a, 1.0, a, 1.0)


def step(state: WhitenState, x: float, fs: float) -> tuple[WhitenState, float]:
    """Whiten one sample; NaN passes as NaN and leaves the state unchanged.

    Per sample: one store into the history (a copy of K samples only when its storage is full,
    every 3 K samples) and two compiled FIR dot products (the previous and the current FIR,
    faded); every ``BLOCK_S`` s the predictor is made from the last ``WINDOW_S`` s, as
    :func:`apply` does."""
    x = float(x)
    if not math.isfinite(x):
        return state, math.nan
    W, B, _ = _sizes(fs)
    buf, end, tip, a, gain = state.buf, state.end, state.tip, state.a, state.gain
    a_prev, gain_prev = state.a_prev, state.gain_prev
    if state.count % B == 0:  # a block starts: new predictor from the history so far
        a_prev, gain_prev = a, gain
        a, gain = predictor(buf[max(0, end - W) : end], fs)
        if gain == gain_prev and np.array_equal(a, a_prev):
            a_prev = None  # the same FIR: nothing to fade
    if end < buf.size and tip[0] == end:
        buf[end] = x
        tip[0] = end = end + 1
    else:  # storage full, or this state was stepped before: fresh storage, last K - 1 + x
        K = max(W, ORDER + 1)
        old = buf[max(0, end - (K - 1)) : end]
        buf = np.empty(4 * K)
        buf[: old.size] = old
        buf[old.size] = x
        end = old.size + 1
        tip = np.array([end], dtype=np.int64)
    out = _fir_last(a, buf, end, gain)
    if a_prev is not None:
        lam = ((state.count % B) + 1.0) / B
        out = (1.0 - lam) * _fir_last(a_prev, buf, end, gain_prev) + lam * out
    return WhitenState(buf, end, tip, state.count + 1, a, gain, a_prev, gain_prev), out


#: blocks whose predictors :func:`apply` makes in one batch (bounds its temporary arrays)
BATCH = 512


def apply(x: np.ndarray, fs: float) -> np.ndarray:
    """Whiten a whole signal (equals repeated :func:`step` from :func:`init`)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.full_like(x, np.nan)
    fin = np.flatnonzero(np.isfinite(x))
    z = np.ascontiguousarray(x[fin])
    W, B, _ = _sizes(fs)
    out = np.zeros(z.size)
    a = np.zeros(ORDER + 1)
    a[0], gain = 1.0, 1.0
    starts = np.arange(0, z.size, B, dtype=np.int64)
    for c0 in range(0, starts.size, BATCH):
        b0s = starts[c0 : c0 + BATCH]
        A, G = _predictors(z, np.maximum(0, b0s - W), b0s, fs)
        _filter_blocks(z, b0s, B, A, G, a, gain, out)
        a, gain = A[-1].copy(), float(G[-1])
    y[fin] = out
    return y
