"""The comb check: the wheel speed of the strongest weighted harmonic comb.

Shared by the aided tracker (:mod:`vibrospeed.estimators.aided`) and the harmonic EKF
(:mod:`vibrospeed.estimators.ekf`): acquisition of omega after a start and the way out of a lock
on half (or twice) the wheel speed.

* :func:`comb_fixes`: every ``COMB_HOP_S`` the argmax of the weighted harmonic sum over a causal
  ``COMB_FRAME_S`` frame (the candidates, NaN between hops and where no comb stands out);
* :func:`comb_candidates`: the same on a raw accelerometer channel, band-limited to the road's
  band first, over a tracker's search range (what the trackers' ``estimate()`` feed their
  kernels as the per-sample input ``comb``);
* :func:`comb_vote` (compiled): the per-candidate rule inside a tracker's loop -- a candidate is
  *steady* when it agrees with the previous one within ``rel / 2``; after ``count`` steady
  candidates in a row that differ from omega by more than ``rel`` of the candidate the tracker
  resets omega to it; :func:`restart_phasors` restarts the phasor states (they belong to the old
  rotation: at half the wheel speed the wheel's line sits in phasor 2 and would pull omega back).

Why the decaying weights matter: with harmonic amplitudes ``A_1, A_2, A_3`` of the wheel speed w,
``S(w) = A_1 + d A_2 + d^2 A_3`` while ``S(w / 2) = d A_1 + d^3 ...`` (the wheel's fundamental
only at its 2nd place) and ``S(2 w) = A_2`` (+ harmonics 4, 6 the comb does not have): the true
speed wins for every comb shape with ``A_1 + d A_2 > A_2`` and ``A_1 > d A_1``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: comb check (acquisition and re-lock): frame length (s), hop (s), harmonics and their weights
COMB_FRAME_S = 3.0
COMB_HOP_S = 0.25
COMB_M = 3
COMB_DECAY = 0.84  # subharmonic-summation weight per harmonic (Hermes 1988)
COMB_OMEGA_MIN = 2.0 * np.pi  # rad/s, lowest wheel speed the comb check looks for


def comb_fixes(x: np.ndarray, dt: float, omega_range: tuple[float, float], *,
               still: np.ndarray | None = None, clarity: float = 3.0,
               rel_std: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Omega fixes from the harmonic comb: ``(ref, ref_var, score)`` per sample (NaN: none).

    Every ``COMB_HOP_S`` a ``COMB_FRAME_S`` Hann frame *ending* at that sample (causal) gets the
    weighted harmonic sum ``S(w) = sum_m d^(m-1) |X(m w)|`` (m = 1..3, d = 0.84, harmonics
    above Nyquist folded) on a log grid over ``omega_range``; where the best ``S`` is at least
    ``clarity`` times its median over the range (a comb stands out of the floor: the ratio
    does not depend on the signal's scale), the argmax is a fix with std ``rel_std`` of it.
    The decaying weights make the wheel speed beat half of it (whose sum holds the fundamental
    only at its 2nd place). No fixes in frames with a standing sample. ``score`` is the ratio.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    ref = np.full(n, np.nan)
    var = np.full(n, np.nan)
    score = np.full(n, np.nan)
    L = int(round(COMB_FRAME_S / dt))
    hop = max(1, int(round(COMB_HOP_S / dt)))
    if n < L or L < 8:
        return ref, var, score
    lo, hi = (float(w) for w in omega_range)
    nyq = np.pi / dt
    hi = min(hi, nyq)
    if not hi > lo > 0:
        return ref, var, score
    nfft = 1 << int(np.ceil(np.log2(4 * L)))
    grid = np.exp(np.linspace(np.log(lo), np.log(hi), 400))
    binw = 2 * np.pi / (nfft * dt)
    ends = np.arange(L - 1, n, hop)
    fin = np.isfinite(x)
    xz = np.where(fin, x, 0.0)
    win = np.hanning(L)
    idx = []
    wts = []
    for m in range(1, COMB_M + 1):
        w = np.abs((m * grid + nyq) % (2 * nyq) - nyq)
        idx.append(w / binw)
        wts.append(COMB_DECAY ** (m - 1))
    st = np.zeros(n, bool) if still is None else np.asarray(still) > 0.5
    st_cum = np.concatenate(([0], np.cumsum(st)))
    fin_cum = np.concatenate(([0], np.cumsum(fin)))
    for chunk in np.array_split(ends, max(1, ends.size // 256)):
        if chunk.size == 0:
            continue
        frames = np.lib.stride_tricks.sliding_window_view(xz, L)[chunk - L + 1]
        frames = frames - frames.mean(axis=1, keepdims=True)
        mag = np.abs(np.fft.rfft(frames * win, nfft, axis=1))
        S = np.zeros((chunk.size, grid.size))
        for fi, wt in zip(idx, wts, strict=True):
            i0 = np.minimum(np.floor(fi).astype(int), mag.shape[1] - 2)
            fr = fi - i0
            S += wt * (mag[:, i0] * (1 - fr) + mag[:, i0 + 1] * fr)
        best = np.argmax(S, axis=1)
        ratio = S[np.arange(chunk.size), best] / np.maximum(np.median(S, axis=1), 1e-300)
        ok = ((st_cum[chunk + 1] - st_cum[chunk - L + 1]) == 0) & \
             ((fin_cum[chunk + 1] - fin_cum[chunk - L + 1]) >= L // 2) & (ratio >= clarity)
        om = grid[best]
        score[chunk] = ratio
        ref[chunk[ok]] = om[ok]
        var[chunk[ok]] = (rel_std * om[ok]) ** 2
    return ref, var, score


#: comb check's rule: candidates in a row that must disagree with omega, by more than this share
COMB_COUNT = 2
COMB_REL = 0.1


def comb_candidates(x: np.ndarray, dt: float, omega_min: float | None, omega_max: float, *,
                    still: np.ndarray | None = None, clarity: float = 3.0
                    ) -> tuple[np.ndarray, tuple[float, float]]:
    """Comb candidates (rad/s per sample, NaN: none) from a raw accelerometer channel ``x``.

    ``x`` is band-limited to the road's band (2 Hz up to Nyquist: below 1 Hz the comb would pick
    the body's sway and the manoeuvres) and :func:`comb_fixes` searches
    ``max(omega_min, COMB_OMEGA_MIN) .. omega_max``. Returns ``(candidates, range)``.
    """
    from vibrospeed.signal import prefilter as pf

    c_rng = (max(omega_min or 0.0, COMB_OMEGA_MIN), omega_max)
    c_band = (min(4 * np.pi, 0.25 * np.pi / dt), np.pi / dt)  # the road's band, 2 Hz up
    sos_c = pf.design("range", 1.0 / dt, M=1, omega_range=c_band)
    c_om, _, _ = comb_fixes(pf.apply(sos_c, x), dt, c_rng, still=still, clarity=clarity)
    return c_om, c_rng


@njit(cache=True)
def comb_vote(cv, comb, omega, rel, count, allowed):
    """One comb candidate inside a tracker's loop; ``cv = [run, last candidate]`` in place.

    The candidate is steady when it agrees with the previous one within ``rel / 2`` of it; a
    steady candidate that differs from ``omega`` by more than ``rel`` of it while ``allowed``
    extends the run, anything else ends it. Returns ``(steady, reset)``: ``reset`` when the run
    reaches ``count`` (the run restarts at 0).
    """
    steady = abs(comb - cv[1]) <= 0.5 * rel * comb
    cv[1] = comb
    if abs(omega - comb) > rel * comb and steady and allowed:
        cv[0] += 1.0
    else:
        cv[0] = 0.0
    reset = cv[0] >= count
    if reset:
        cv[0] = 0.0
    return steady, reset


@njit(cache=True)
def restart_phasors(x, P, i0, i1, p0):
    """States ``i0 .. i1 - 1`` (the phasors) restart at 0 with variance ``p0``, uncorrelated."""
    n = x.size
    for i in range(i0, i1):
        x[i] = 0.0
        for j in range(n):
            P[i, j] = 0.0
            P[j, i] = 0.0
        P[i, i] = p0
