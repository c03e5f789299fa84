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

Computation. The predictor is the numbers of ``scipy.signal.welch(hist, fs, nperseg=seg,
average="median")``, ``scipy.ndimage.median_filter(P, k, mode="nearest")``,
``numpy.fft.irfft``, ``scipy.linalg.solve_toeplitz`` and the power of
``scipy.signal.lfilter(a, [1], hist)``, bit for bit, without their per-call overhead (about
1 ms per block in scipy, mostly argument handling): the FFTs are the same library calls, made
for many segments or blocks at once (each row is transformed alone, so batching changes no
bit); the rest is compiled and takes each sum in the order those functions take it (numpy's
pairwise summation for means, Levinson's recursion as scipy's ``levinson``, the FIR's dot
products as ``numpy.convolve``'s). :func:`apply` makes every block's predictor in batches of
blocks, each Welch segment's spectrum once (consecutive windows share most segments);
``tests/test_scale_whiten.py`` checks the predictors against the scipy calls.

On the randomised family (``benchmarks/robustness``, ``docs/robustness.md``) whitening after
the thesis high-pass lifts the grid tracker's share within tolerance most on cars and forklifts
(body motion in the band), at a small cost on some carts.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic

from vibrospeed.signal import dsp

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


@intrinsic
def _fma(typingctx, a, b, c):
    """``a b + c`` rounded once (LLVM's ``llvm.fma.f64``: the processor's fused multiply-add,
    or libm's ``fma`` where it has none)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True)
def _pw_block(x, lo, n):
    """numpy's pairwise sum of ``x[lo:lo + n]`` for n <= 128: eight interleaved partial
    sums, combined as a tree, then the rest in order (below 8 terms: in order)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += x[i]
        return res
    r0 = x[lo]
    r1 = x[lo + 1]
    r2 = x[lo + 2]
    r3 = x[lo + 3]
    r4 = x[lo + 4]
    r5 = x[lo + 5]
    r6 = x[lo + 6]
    r7 = x[lo + 7]
    i = 8
    m = n - n % 8
    while i < m:
        r0 += x[lo + i]
        r1 += x[lo + i + 1]
        r2 += x[lo + i + 2]
        r3 += x[lo + i + 3]
        r4 += x[lo + i + 4]
        r5 += x[lo + i + 5]
        r6 += x[lo + i + 6]
        r7 += x[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += x[lo + i]
        i += 1
    return res


@njit(cache=True)
def _pairwise(x, lo, n):
    """``sum(x[lo:lo + n])`` as numpy sums a contiguous float64 array, so that means here equal
    ``numpy.mean``'s bit for bit: above 128 terms the sum of the two halves' sums (the first
    half's length a multiple of 8), each summed the same way; blocks by :func:`_pw_block`.
    The recursion runs on an explicit stack (numba's cache does not load recursive
    functions)."""
    if n <= 128:
        return _pw_block(x, lo, n)
    los = np.empty(64, np.int64)
    ns = np.empty(64, np.int64)
    stage = np.zeros(64, np.int64)  # 1: left half pending, 2: right half pending
    left = np.empty(64)
    d = 0
    los[0] = lo
    ns[0] = n
    while True:
        m = ns[d]
        if m > 128:  # descend into the left half
            h = m // 2
            h -= h % 8
            stage[d] = 1
            los[d + 1] = los[d]
            ns[d + 1] = h
            d += 1
            continue
        ret = _pw_block(x, los[d], m)
        d -= 1
        while d >= 0 and stage[d] == 2:  # right halves done: combine upwards
            ret = left[d] + ret
            d -= 1
        if d < 0:
            return ret
        left[d] = ret  # a left half done: the right half next
        stage[d] = 2
        h = ns[d] // 2
        h -= h % 8
        los[d + 1] = los[d] + h
        ns[d + 1] = ns[d] - h
        d += 1


@njit(cache=True)
def _segments(z, starts, seg, win, out):
    """Welch's segments ``z[s:s + seg]`` for each start s: mean removed (``detrend=
    "constant"``) and windowed, into the rows of ``out``."""
    for r in range(starts.size):
        s0 = starts[r]
        mu = _pairwise(z, s0, seg) / seg
        for i in range(seg):
            out[r, i] = (z[s0 + i] - mu) * win[i]


@njit(cache=True)
def _running_median(P, k, win, out):
    """``out`` = the running median of ``k`` bins of ``P`` (``k`` odd, ends repeated:
    ``scipy.ndimage.median_filter(P, k, mode="nearest")``)."""
    nf = P.size
    h = k // 2
    for f in range(nf):
        for q in range(k):
            j = min(max(f + q - h, 0), nf - 1)
            v = P[j]
            i = q
            while i > 0 and win[i - 1] > v:
                win[i] = win[i - 1]
                i -= 1
            win[i] = v
        out[f] = win[h]


@njit(cache=True)
def _backgrounds(X, rows, nseg, bias, dbl_hi, k, kw, peak_max, S):
    """Per block b, the line-robust background ``S[b]``: the one-sided periodograms of the
    segment spectra ``X[rows[b, :nseg[b]]]`` (``|X|^2``, doubled for bins 1 <= f < dbl_hi),
    their median over the segments divided by ``bias[nseg]`` (one segment: itself, as welch),
    then the running median of ``k`` bins, at most ``peak_max`` times the running median of
    ``kw`` bins (``k``, ``kw`` odd)."""
    nf = X.shape[1]
    P = np.empty(nf)
    vals = np.empty(max(rows.shape[1], 1))
    win = np.empty(max(k, kw))
    narrow = np.empty(nf)
    wide = np.empty(nf)
    for b in range(rows.shape[0]):
        n = nseg[b]
        if n == 0:
            continue
        for f in range(nf):
            for q in range(n):  # insertion sort of the segments' values (n is small)
                x = X[rows[b, q], f]
                v = x.real * x.real + x.imag * x.imag
                if 1 <= f < dbl_hi:
                    v *= 2.0
                i = q
                while i > 0 and vals[i - 1] > v:
                    vals[i] = vals[i - 1]
                    i -= 1
                vals[i] = v
            if n == 1:
                P[f] = vals[0]
            elif n % 2 == 1:
                P[f] = vals[n // 2] / bias[n]
            else:
                P[f] = (vals[n // 2 - 1] + vals[n // 2]) / 2.0 / bias[n]
        _running_median(P, k, win, narrow)
        _running_median(P, kw, win, wide)
        for f in range(nf):
            S[b, f] = min(narrow[f], peak_max * wide[f])


@njit(cache=True)
def _finish(R, z, w0, w1, order, A, G):
    """Per block b, the predictor ``A[b]`` (order + 1) and gain ``G[b]`` from the inverse FFT
    ``R[b]`` of its background and its history ``z[w0[b]:w1[b]]`` (``w1 - w0`` shorter than
    a segment: ``A[b]`` is left as it is, the identity). As :func:`predictor_reference`: the
    autocorrelation normalised, Levinson's recursion for ``toeplitz(r[:p]) c = -r[1:]``
    (scipy's ``levinson``, its operations in its order), the prediction error ``1 + c . r[1:]``,
    then the power of the history and of its FIR output for the gain. ``lfilter`` with a
    one-tap denominator is ``numpy.convolve``, whose dot products (13 taps, more than its
    unrolled small-kernel path takes) go to OpenBLAS's ``ddot``: below 16 terms a plain loop,
    which OpenBLAS's builds for processors with FMA (Haswell on) contract to fused
    multiply-adds; the sums here are those, highest coefficient first."""
    p = order
    r = np.empty(p + 1)
    vals = np.empty(2 * p - 1)
    x = np.empty(p)
    g = np.empty(p)
    hh = np.empty(p)
    for b in range(R.shape[0]):
        m = w1[b] - w0[b]
        G[b] = 1.0
        if not R[b, 0] > 0:
            continue
        r0 = R[b, 0]
        fin = True
        for i in range(p + 1):
            r[i] = R[b, i] / r0
            if not np.isfinite(r[i]):
                fin = False
        if not fin:  # solve_toeplitz's check_finite
            continue
        for i in range(p - 1):  # [r_(p-1) .. r_1, r_0, r_1 .. r_(p-1)]
            vals[i] = r[p - 1 - i]
        for i in range(p):
            vals[p - 1 + i] = r[i]
        # scipy.linalg._solve_toeplitz.levinson(vals, bb) with bb = -r[1:]
        n = p
        ok = vals[n - 1] != 0.0
        if ok:
            x[:] = 0.0
            g[:] = 0.0
            hh[:] = 0.0
            x[0] = -r[1] / vals[n - 1]
            if n > 1:
                g[0] = vals[n - 2] / vals[n - 1]
                hh[0] = vals[n] / vals[n - 1]
            for mm in range(1, n):
                x_num = r[mm + 1]  # -b[m] with b = -r[1:]: both negations exact
                x_den = -vals[n - 1]
                for j in range(mm):
                    nmj = n + mm - (j + 1)
                    x_num = x_num + vals[nmj] * x[j]
                    x_den = x_den + vals[nmj] * g[mm - j - 1]
                if x_den == 0:
                    ok = False
                    break
                x[mm] = x_num / x_den
                for j in range(mm):
                    x[j] = x[j] - x[mm] * g[mm - j - 1]
                if mm == n - 1:
                    break
                g_num = -vals[n - mm - 2]
                h_num = -vals[n + mm]
                g_den = -vals[n - 1]
                for j in range(mm):
                    g_num = g_num + vals[n + j - mm - 1] * g[j]
                    h_num = h_num + vals[n + mm - j - 1] * hh[j]
                    g_den = g_den + vals[n + j - mm - 1] * hh[mm - j - 1]
                if g_den == 0.0:
                    ok = False
                    break
                g[mm] = g_num / g_den
                hh[mm] = h_num / x_den
                kk = mm - 1
                m2 = (mm + 1) >> 1
                c1 = g[mm]
                c2 = hh[mm]
                for j in range(m2):
                    gj = g[j]
                    gk = g[kk]
                    hj = hh[j]
                    hk = hh[kk]
                    g[j] = gj - (c1 * hk)
                    g[kk] = gk - (c1 * hj)
                    hh[j] = hj - (c2 * gk)
                    hh[kk] = hk - (c2 * gj)
                    kk -= 1
        if not ok:
            continue
        dot = 0.0  # numpy.dot: OpenBLAS's ddot, whose loop its FMA builds contract
        for i in range(p):
            dot = _fma(r[i + 1], x[i], dot)
        err = r[0] + dot
        fin = True
        for i in range(p):
            if not np.isfinite(x[i]):
                fin = False
        if not fin or not err > 1e-12:
            continue
        A[b, 0] = 1.0
        for i in range(p):
            A[b, i + 1] = x[i]
        # the gain: the history's power over its FIR output's (from the p-th sample on)
        lo = w0[b]
        e2 = np.empty(m)
        for t in range(p, m):
            acc = 0.0
            for kq in range(p, -1, -1):
                acc = _fma(z[lo + t - kq], A[b, kq], acc)
            e2[t - p] = acc * acc
        var = _pairwise(e2, 0, m - p) / (m - p)
        mu = _pairwise(z, lo, m) / m
        for t in range(m):
            d = z[lo + t] - mu
            e2[t] = d * d
        ref = _pairwise(e2, 0, m) / m
        G[b] = np.sqrt(ref / var) if var > 0 and ref > 0 else 1.0


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


@njit(cache=True)
def _fir_last(a, buf, end, gain):
    """``gain sum_k a[k] buf[end - 1 - k]`` over the samples that exist (index >= 0): the
    prediction-error FIR's output at sample ``end - 1`` (the one dot product of the streaming
    and the batch paths)."""
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


@njit(cache=True)
def _filter_blocks(z, b0s, B, A, G, a_first, g_first, out):
    """The output of blocks starting at ``b0s`` (B samples each, the last one cut at the end
    of ``z``): each block's FIR ``A[i]`` with gain ``G[i]``, faded in from the previous
    block's (``a_first``, ``g_first`` before the first) unless the two are equal; each
    output by :func:`_fir_last`, as :func:`step` makes it."""
    p = A.shape[1] - 1
    n = z.size
    for i in range(b0s.size):
        b0 = b0s[i]
        ap = A[i - 1] if i > 0 else a_first
        gp = G[i - 1] if i > 0 else g_first
        a = A[i]
        g = G[i]
        same = g == gp
        for k in range(p + 1):
            if a[k] != ap[k]:
                same = False
        for t in range(b0, min(b0 + B, n)):
            new = _fir_last(a, z, t + 1, g)
            if not same:
                old = _fir_last(ap, z, t + 1, gp)
                lam = ((t - b0) + 1.0) / B
                new = (1.0 - lam) * old + lam * new
            out[t] = new


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
