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
  brakes does not enter it, then a running *median* over ``SMOOTH_HZ`` Hz, so a steady narrow
  line (wheel harmonics, engine orders) does not enter it either;
* its autocorrelation (inverse FFT) gives, by Levinson-Durbin (``scipy.linalg.solve_toeplitz``),
  the order-``ORDER`` linear predictor ``a``; the block is filtered by the prediction-error FIR
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

On the randomised family (``benchmarks/robustness``, ``docs/robustness.md``) whitening after
the thesis high-pass lifts the grid tracker's share within tolerance most on cars and forklifts
(body motion in the band), at a small cost on some carts.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy import signal as sps
from scipy.linalg import solve_toeplitz
from scipy.ndimage import median_filter

ORDER = 12
WINDOW_S = 9.0
BLOCK_S = 1.0
SEGMENT_S = 2.0
SMOOTH_HZ = 1.0


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


def predictor(hist: np.ndarray, fs: float) -> tuple[np.ndarray, float]:
    """``(a, gain)``: prediction-error FIR of the line-robust background of ``hist`` and the
    gain that keeps ``hist``'s power through it; identity while ``hist`` is short."""
    _, _, seg = _sizes(fs)
    ident = np.zeros(ORDER + 1)
    ident[0] = 1.0
    if hist.size < seg:
        return ident, 1.0
    f, P = sps.welch(hist, fs=fs, nperseg=seg, average="median")
    k = 2 * max(1, int(round(0.5 * SMOOTH_HZ / (f[1] - f[0])))) + 1
    S = median_filter(P, size=k, mode="nearest")
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
    # keep the history's power: the output stays in the input's units and scale (the
    # trackers' running-RMS normalisation follows), with no step where the first FIR starts
    var = float(np.mean(np.square(np.asarray(sps.lfilter(a, [1.0], hist))[ORDER:])))
    ref = float(np.mean(np.square(hist - np.mean(hist))))
    return a, (np.sqrt(ref / var) if var > 0 and ref > 0 else 1.0)


@njit(cache=True)
def _fir(a, x, start, stop, gain, out):
    """``out[n] = gain sum_k a[k] x[n - k]`` for ``start <= n < stop`` (x before 0 counts 0)."""
    p = a.size - 1
    for n in range(start, stop):
        acc = 0.0
        for k in range(p + 1):
            j = n - k
            if j >= 0:
                acc += a[k] * x[j]
        out[n] = gain * acc


@njit(cache=True)
def _fir_last(a, buf, end, gain):
    """``gain sum_k a[k] buf[end - 1 - k]`` over the samples that exist (index >= 0): the
    last output of :func:`_fir` on the same samples, the same operations in the same order."""
    p = a.size - 1
    n = end - 1
    acc = 0.0
    for k in range(p + 1):
        j = n - k
        if j >= 0:
            acc += a[k] * buf[j]
    return gain * acc


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
    for b0 in range(0, z.size, B):
        a_prev, gain_prev = a, gain
        a, gain = predictor(z[max(0, b0 - W) : b0], fs)
        lo = max(0, b0 - ORDER)
        seg = np.ascontiguousarray(z[lo : b0 + B])
        tmp = np.zeros(seg.size)
        _fir(a, seg, b0 - lo, seg.size, gain, tmp)  # samples before the start count 0
        new = tmp[b0 - lo :]
        if not (gain == gain_prev and np.array_equal(a, a_prev)):
            old = np.zeros(seg.size)
            _fir(a_prev, seg, b0 - lo, seg.size, gain_prev, old)
            lam = (np.arange(new.size) + 1.0) / B
            new = (1.0 - lam) * old[b0 - lo :] + lam * new
        out[b0 : b0 + B] = new
    y[fin] = out
    return y
