"""The accelerometer's effective noise density learned from a drive's own GPS fixes, for the
speed band of :mod:`vibrospeed.estimators.fuse` (``Config.band_psd="learned"``).

Between two fixes ``T`` s apart the speed change the GPS sees, less the accelerometer's
integral over the same time, ``r = (g1 - g0) - int a dt``, is the accelerometer's error
integrated over ``T`` (an offset ``b`` adds ``-b T``; the receiver's noise adds a constant).
For a white error of density ``q`` ((m/s^2)^2 s) ``var(r) = c + q T``: the slope of the
robust variance of ``r`` against ``T`` is the density the accelerometer really shows. On the
GoPro kart it is 2.83 against the filter's ``acc_psd`` of 0.1, which left its 98 % band
holding the withheld GPS on 62 % (benchmarks/fuse/RESULTS.md).
"""

from __future__ import annotations

import numpy as np

from vibrospeed.errors import InputError

#: s, the fix-pair intervals whose robust variances give the slope
INTERVALS = (1.0, 2.0, 4.0, 8.0)
#: least fix pairs per interval for its variance to count; at least two intervals must count
MIN_PAIRS = 20
#: a pair's interval may differ from the nominal one by this share of it
PAIR_TOL = 0.2
#: s between the causal estimates (:func:`learn_acc_psd_causal`), and their share of the
#: elapsed time once that is longer: re-estimated every ``max(CAUSAL_EVERY, CAUSAL_REL *
#: elapsed)`` s, so a day-long drive takes a few hundred estimates, not 17 000 (each reads
#: every pair so far)
CAUSAL_EVERY = 5.0
CAUSAL_REL = 0.02
#: MAD^2 / this is the variance of a normal sample (0.6745^2)
MAD2_VAR = 0.455


def _pairs(t, accel, gps, intervals):
    """Per interval: ``(r, dt, t_end)`` of the fix pairs ``T`` apart (within ``PAIR_TOL``) with
    an acceleration at every sample between them."""
    t = np.asarray(t, dtype=np.float64)
    a = np.asarray(accel, dtype=np.float64)
    g = np.asarray(gps, dtype=np.float64)
    if not (t.shape == a.shape == g.shape):
        raise InputError(f"fuse band_psd: t, accel, gps have shapes {t.shape}, {a.shape}, "
                         f"{g.shape}; they must match")
    dts = np.diff(t, prepend=t[0] if t.size else 0.0)
    ok = np.isfinite(a)
    cum = np.cumsum(np.where(ok, a, 0.0) * dts)
    ok[:1] = True  # the first sample's mean covers no time
    nbad = np.cumsum(~ok)
    fi = np.flatnonzero(np.isfinite(g))
    tf = t[fi]
    out = []
    for T in intervals:
        if tf.size < 2:
            out.append((np.empty(0), np.empty(0), np.empty(0)))
            continue
        j = np.clip(np.searchsorted(tf, tf + T), 1, tf.size - 1)
        j = np.where(np.abs(tf[j - 1] - tf - T) < np.abs(tf[j] - tf - T), j - 1, j)
        i = np.arange(tf.size)
        use = (j > i) & (np.abs(tf[j] - tf - T) <= PAIR_TOL * T)
        i, j = i[use], j[use]
        a0, a1 = fi[i], fi[j]
        use = nbad[a1] == nbad[a0]
        a0, a1, i, j = a0[use], a1[use], i[use], j[use]
        r = (g[a1] - g[a0]) - (cum[a1] - cum[a0])
        out.append((r, tf[j] - tf[i], tf[j]))
    return out


def _slope(pairs, intervals) -> float | None:
    """The density from the pairs: their median offset rate removed, the robust variance per
    interval, the least-squares slope against the interval (None: fewer than two intervals
    with ``MIN_PAIRS`` pairs); clipped at 0."""
    rates = [r / d for r, d in ((p[0], p[1]) for p in pairs) if r.size]
    if not rates:
        return None
    rate = float(np.median(np.concatenate(rates)))
    xs, vs = [], []
    for (r, d, _), T in zip(pairs, intervals, strict=True):
        if r.size < MIN_PAIRS:
            continue
        e = r - rate * d
        mad = np.median(np.abs(e - np.median(e)))
        xs.append(T)
        vs.append(mad * mad / MAD2_VAR)
    if len(xs) < 2:
        return None
    x, v = np.asarray(xs), np.asarray(vs)
    q = float(np.sum((x - x.mean()) * (v - v.mean())) / np.sum((x - x.mean()) ** 2))
    return max(q, 0.0)


def learn_acc_psd(t, accel, gps, intervals=INTERVALS) -> float | None:
    """The accelerometer's effective white-noise density ((m/s^2)^2 s) from a whole drive:
    ``t`` (n,) s, ``accel`` (n,) the mean acceleration since the previous sample (m/s^2, NaN:
    none), ``gps`` (n,) the valid GPS speed fixes (m/s, NaN elsewhere). For each interval of
    ``intervals`` (s) the pairs of fixes that far apart, ``r = (g1 - g0) - int a dt`` less the
    drive's median offset rate times the interval, the robust variance of ``r``
    (``MAD^2 / 0.455``); the slope of those variances against the interval (least squares).
    None where fewer than two intervals have :data:`MIN_PAIRS` pairs."""
    return _slope(_pairs(t, accel, gps, intervals), intervals)


def next_checkpoint(c: float, t0: float, every: float = CAUSAL_EVERY,
                    rel: float = CAUSAL_REL) -> float:
    """The causal estimate after the one at ``c`` s (the drive starting at ``t0``; the first
    is at ``t0 + every``): ``every`` s later, or ``rel`` of the elapsed time once that is
    longer."""
    return c + max(every, rel * (c - t0))


def learn_acc_psd_causal(t, accel, gps, intervals=INTERVALS,
                         every: float = CAUSAL_EVERY) -> np.ndarray:
    """:func:`learn_acc_psd` from the fixes so far, per sample (n,): re-estimated at the
    checkpoints of :func:`next_checkpoint` (and at the last sample) from the pairs that ended
    by then (NaN until enough pairs), for the forward filter, which may not see fixes to
    come. Each estimate holds from its checkpoint to the next one that gives one."""
    t = np.asarray(t, dtype=np.float64)
    pairs = _pairs(t, accel, gps, intervals)  # each interval's pairs in order of their end
    out = np.full(t.size, np.nan)
    if t.size == 0:
        return out
    cs = []
    c = t[0] + every
    while c < t[-1]:
        cs.append(c)
        c = next_checkpoint(c, t[0], every)
    cs.append(t[-1])
    held = []  # (first sample, density) of each estimate made
    for c, k in zip(cs, np.searchsorted(t, cs), strict=True):
        q = _slope([(r[:m], d[:m], e[:m]) for r, d, e in pairs
                    for m in (int(np.searchsorted(e, c, side="right")),)], intervals)
        if q is not None:
            held.append((int(k), q))
    for i, (k, q) in enumerate(held):
        out[k:held[i + 1][0] if i + 1 < len(held) else t.size] = q  # until the next one
    return out
