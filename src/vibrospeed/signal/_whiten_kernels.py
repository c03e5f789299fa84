"""The whitener's compiled kernels: scipy's and numpy's numbers, bit for bit, without their
per-call overhead.

:func:`vibrospeed.signal.whiten.predictor` is the numbers of ``scipy.signal.welch(hist, fs,
nperseg=seg, average="median")``, ``scipy.ndimage.median_filter(P, k, mode="nearest")``,
``numpy.fft.irfft``, ``scipy.linalg.solve_toeplitz`` and the power of
``scipy.signal.lfilter(a, [1], hist)``; those calls cost about 1 ms per block, mostly argument
handling. The FFTs stay the library calls (made for many segments or blocks at once: each row
is transformed alone, so batching changes no bit); the rest is here, each sum taken in the
order those functions take it: numpy's pairwise summation for means (:func:`_pairwise`),
Welch's segments (:func:`_segments`), the median over segments and the running medians
(:func:`_backgrounds`), Levinson's recursion as scipy's ``levinson`` and the FIR's dot
products as ``numpy.convolve``'s (:func:`_finish`). Bitwise, not merely close, so that the
whitener's output, and every track made from it, is that of the scipy calls
(:func:`vibrospeed.signal.whiten.predictor_reference`; ``tests/test_scale_whiten.py``), with
one machine-dependent exception: the gain's dot products follow OpenBLAS's FMA ``ddot`` of
Intel builds (Haswell on); where the BLAS picks another kernel (AMD EPYC) the reference's gain
differs by a few ulp, and so the outputs scaled by it. The compiled numbers are the same on
every machine, so step and batch runs still agree bit for bit. The
FIR itself, shared by the streaming and the batch paths, is :func:`_fir_last` and
:func:`_filter_blocks`.

Every compiled function of the whitener is in this one file: numba's cache keys a function on
its own file, so a kernel that called one in another file could keep a stale copy of it.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic


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
    a segment: ``A[b]`` is left as it is, the identity). As
    :func:`vibrospeed.signal.whiten.predictor_reference`: the autocorrelation normalised,
    Levinson's recursion for ``toeplitz(r[:p]) c = -r[1:]`` (scipy's ``levinson``, its
    operations in its order), the prediction error ``1 + c . r[1:]``, then the power of the
    history and of its FIR output for the gain. ``lfilter`` with a
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


@njit(cache=True)
def _filter_blocks(z, b0s, B, A, G, a_first, g_first, out):
    """The output of blocks starting at ``b0s`` (B samples each, the last one cut at the end
    of ``z``): each block's FIR ``A[i]`` with gain ``G[i]``, faded in from the previous
    block's (``a_first``, ``g_first`` before the first) unless the two are equal; each
    output by :func:`_fir_last`, as :func:`vibrospeed.signal.whiten.step` makes it."""
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
