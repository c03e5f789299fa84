"""The background of a comb frame's power spectrum (:mod:`vibrospeed.estimators.grid.comb`):
a running order statistic over each bin's neighbourhood, divided by the same quantile of a unit
exponential, so that the whitened spectrum ``S(f) ~ Exp(1)`` where there is no line. Two
implementations that give the same values: :func:`running_median` (a selection per window) and
the compiled :func:`_background` (every window through one selection network, no
data-dependent branch), which the comb evidence uses."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _kth(a: np.ndarray, k: int) -> float:
    """The ``k``-th smallest (0-based) of ``a`` (no NaN), partly reordering ``a`` in place:
    Hoare's selection (the value is that of any exact order statistic: sorting, partition)."""
    lo = 0
    hi = a.size - 1
    while lo < hi:
        x = a[k]
        i = lo
        j = hi
        while i <= j:
            while a[i] < x:
                i += 1
            while x < a[j]:
                j -= 1
            if i <= j:
                tmp = a[i]
                a[i] = a[j]
                a[j] = tmp
                i += 1
                j -= 1
        if j < k:
            lo = i
        if k < i:
            hi = j
    return a[k]


@njit(cache=True)
def _window_medians(Pp: np.ndarray, starts: np.ndarray, width: int, out: np.ndarray) -> None:
    """``out[r, c]`` = median of ``Pp[r, starts[c] : starts[c] + width]``, as ``np.median``:
    the middle order statistic (odd ``width``), the mean ``(lo + hi) / 2`` of the two middle
    ones (even), NaN when the window holds a NaN."""
    buf = np.empty(width)
    h = width // 2
    for r in range(Pp.shape[0]):
        row = Pp[r]
        for c in range(starts.size):
            s0 = starts[c]
            nan = False
            for i in range(width):
                v = row[s0 + i]
                if v != v:
                    nan = True
                buf[i] = v
            if nan:
                out[r, c] = np.nan
                continue
            hi = _kth(buf, h)
            if width % 2 == 1:
                out[r, c] = hi
            else:  # buf[:h] now holds the h smallest: the lower middle is their maximum
                lo = buf[0]
                for i in range(1, h):
                    if buf[i] > lo:
                        lo = buf[i]
                out[r, c] = (lo + hi) / 2.0
    return


def running_median(P: np.ndarray, width: int) -> np.ndarray:
    """Running median of each row of ``P`` over ``width`` (odd) bins, edges extended
    ("nearest"), evaluated every ``max(1, width // 8)`` bins and linearly interpolated between
    (the background is smooth on that scale; ~8x cheaper than the exact filter, which it
    equals for ``width < 16``). The medians are those of ``np.median`` on each window,
    computed by a compiled selection per window (:func:`_window_medians`)."""
    P = np.asarray(P, dtype=np.float64)
    F, n = P.shape
    h = width // 2
    st = max(1, width // 8)
    Pp = np.concatenate([np.repeat(P[:, :1], h, 1), P, np.repeat(P[:, -1:], h, 1)], axis=1)
    cent = np.arange(0, n + st - 1, st)
    cent = np.minimum(cent, n - 1)
    med = np.empty((F, cent.size))
    _window_medians(np.ascontiguousarray(Pp), cent.astype(np.int64), int(width), med)
    if st == 1:
        return med
    i = np.arange(n)
    j = np.minimum(i // st, cent.size - 2)
    fr = (i - cent[j]) / np.maximum(cent[j + 1] - cent[j], 1)
    return med[:, j] * (1.0 - fr) + med[:, j + 1] * fr


#: the background of a frame's power spectrum: the ``k``-th smallest power (0-based) of the
#: ``width`` bins about each bin, divided by the same quantile of a unit exponential so that
#: ``S(f) ~ Exp(1)`` where there is no line (the median: ``k = width // 2`` and ln 2)
def _background_stat(width: int) -> tuple[int, float]:
    """``(k, scale)`` of the background over ``width`` (odd) bins: its ``k``-th smallest
    power divided by ``scale``."""
    return width // 2, float(np.log(2.0))


def selection_network(n: int, k: int) -> np.ndarray:
    """Comparators ``(i, j)``, i < j, in order, that leave the ``k``-th smallest (0-based) of
    ``n`` values on wire ``k``: Batcher's merge-exchange sorting network for any ``n`` (Knuth,
    TAOCP vol. 3, 5.2.2, Algorithm M), each comparator putting the smaller value on ``i``,
    less those whose outputs never reach wire ``k`` (walking back from the end: a comparator
    is kept where it writes a wire that a kept one, or the output, reads later). The result
    is a value of the inputs, with no arithmetic and no data-dependent branch: the same value
    as any exact selection."""
    t = max(1, (n - 1).bit_length())
    pairs = []
    p = 1 << (t - 1)
    while p > 0:
        q, r, d = 1 << (t - 1), 0, p
        while True:
            pairs.extend((i, i + d) for i in range(n - d) if i & p == r)
            if q == p:
                break
            d, q, r = q - p, q >> 1, p
        p >>= 1
    need, keep = {k}, []
    for i, j in reversed(pairs):
        if i in need or j in need:
            keep.append((i, j))
            need.update((i, j))
    return np.array(keep[::-1], np.int64).reshape(-1, 2)


@njit(cache=True)
def _sort_columns(mat, net, nc):
    """Apply the selection network ``net`` (comparator rows) to the first ``nc`` columns of
    ``mat``: each comparator puts the smaller value in its first row."""
    for t in range(net.shape[0]):
        lo = mat[net[t, 0]]
        hi = mat[net[t, 1]]
        for c in range(nc):
            x = lo[c]
            y = hi[c]
            lo[c] = x if x < y else y
            hi[c] = y if x < y else x


@njit(cache=True)
def _background(row: np.ndarray, width: int, step: int, rank: int, scale: float,
                net: np.ndarray, mat: np.ndarray, buf: np.ndarray, med: np.ndarray,
                out: np.ndarray) -> None:
    """``out`` = the running ``rank``-th smallest (0-based) of ``row`` over ``width`` (odd)
    bins, edges extended ("nearest"), evaluated every ``step`` bins and linearly interpolated
    between, divided by ``scale``; a window holding a NaN gives NaN. With ``rank = width // 2``
    and ``step = max(1, width // 8)`` this is ``running_median(row[None], width)[0] / scale``
    bitwise (the same windows, order statistics and interpolation). The windows are the
    columns of ``mat`` (at least ``width`` x windows), all passed through the selection
    network ``net`` (:func:`selection_network`) at once: no data-dependent branch, one window
    per SIMD lane (``buf`` (``width``): a window, where the row holds a NaN; ``med``: the
    order statistics, ``row.size``)."""
    n = row.size
    h = width // 2
    nc = (n + step - 2) // step + 1  # centres 0, step, 2 step, ..., the last bin
    nan = False
    for i in range(n):
        if row[i] != row[i]:
            nan = True
            break
    if nan:  # a window with NaN gives NaN: select in each window on its own
        for c in range(nc):
            cc = min(c * step, n - 1)
            bad = False
            for i in range(width):
                v = row[min(max(cc - h + i, 0), n - 1)]
                if v != v:
                    bad = True
                buf[i] = v
            med[c] = np.nan if bad else _kth(buf, rank)
    else:
        for c in range(nc):  # window c in column c
            s0 = min(c * step, n - 1) - h
            if s0 >= 0 and s0 + width <= n:
                for i in range(width):
                    mat[i, c] = row[s0 + i]
            else:
                for i in range(width):
                    mat[i, c] = row[min(max(s0 + i, 0), n - 1)]
        _sort_columns(mat, net, nc)
        mk = mat[rank]
        for c in range(nc):
            med[c] = mk[c]
    if step == 1:
        for i in range(n):
            out[i] = med[i] / scale
        return
    for i in range(n):
        j = min(i // step, nc - 2)
        c0 = min(j * step, n - 1)
        c1 = min((j + 1) * step, n - 1)
        fr = (i - c0) / max(c1 - c0, 1)
        out[i] = (med[j] * (1.0 - fr) + med[j + 1] * fr) / scale
