"""Standstill from the vibration: a standing vehicle neither shakes nor sways.

A rolling wheel excites the chassis over a wide band (road texture, tyre tread) and a moving
vehicle turns, brakes and pitches; a standing one leaves the sensor's noise, an idling engine's
shaking and its narrow idle lines. Per accelerometer axis:

1. each frame (``FRAME_S`` s, every ``HOP_S`` s, Hann window) gets a *broadband level*: the
   square root of the median power over the search band's bins, amplitude-scaled
   (``2 |X| / sum(w)``), on the axis high-passed (order 4) at the ``range`` pre-filter's corner,
   :data:`vibrospeed.signal.prefilter.RANGE_HP` times the band's lower edge.
   The median ignores narrow lines (the engine idling, a wheel harmonic);
2. and a *body-motion level*: the axis low-passed below the wheel's band (at most
   ``MOTION_HI_HZ``), over ``MOTION_FRAME_S`` s, the RMS of its residual from a straight line
   (so the end of a braking, a step, does not read as motion); only where that band reaches
   ``MOTION_MIN_HI_HZ`` (a car's range: a slow vehicle's wheel band starts in it);
3. each level's *floor* is the 1 % quantile over the frames; a frame is standing when both
   levels are within ``NEAR_FLOOR`` / ``MOTION_NEAR`` of their floors, provided the median
   frame's broadband level is at least ``MIN_CONTRAST`` above its floor (a log without a stop
   has no such gap and declares none).

With several axes a frame is standing where every axis says so. Offline the quantiles are over
the whole log; gaps under 1 s inside a stop are closed and standing runs shorter than
``MIN_STOP_S`` dropped; each frame decides for the samples nearest its centre. Causally
(``causal=True``, what a device can do) the quantiles are over the frames seen so far (a
histogram of log-levels, after ``CAUSAL_WARMUP_S`` s) and a stop is declared after
``CAUSAL_DWELL_S`` s of standing frames, so a decision never uses later data, and a stop before
the first motion, with nothing to compare it with, is not recognised.

The constants are chosen on the randomised family (``simulate("random")``, with an idling
engine's broadband shaking) and checked on the real phone drives of ``hungary_car_phyphox``, whose
slow smooth stretches are the hard case; the broadband level alone declares a stop on slow smooth
roads, the body-motion level is what rules those out. Figures: ``benchmarks/robustness/
standstill.py`` and its ``STANDSTILL.md``.

Frames with fewer than half their samples finite have no level and repeat the last decision.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

FRAME_S = 1.0
HOP_S = 0.25
#: amplitude ratio between the median frame's broadband level and its floor below which no
#: standstill is declared
MIN_CONTRAST = 2.0
#: a frame is standing when its broadband level is within this factor of its floor
NEAR_FLOOR = 3.0
#: s, offline: shorter standing runs are dropped (a vehicle rolling slowly through its floor)
MIN_STOP_S = 2.0
#: Hz, the body-motion level: RMS of the axis between these (upper: below the wheel's band)
#: over ``MOTION_FRAME_S`` s; a standing vehicle neither turns nor brakes nor pitches
MOTION_LO_HZ = 0.2
MOTION_HI_HZ = 2.0
#: Hz, the body-motion level is used only where its band reaches this high below the wheel's
#: band (``omega_min`` >= ~9 rad/s with the ``range`` pre-filter's corner): a narrower band
#: holds little but the tail of a braking and kept short stops from being declared
MOTION_MIN_HI_HZ = 1.0
MOTION_FRAME_S = 2.0
#: ... and its body-motion level within this factor of its floor
MOTION_NEAR = 3.0
#: the floor is this quantile of the frames' log-levels
FLOOR_Q = 0.01
#: s, causal: a stop is declared after standing frames for this long
CAUSAL_DWELL_S = 1.5
#: s, causal: frames seen before any decision (the floor needs a history)
CAUSAL_WARMUP_S = 10.0
#: rad/s, the band's lower edge where the search band starts at or below 0 (``omega_min = 0``,
#: which the grid trackers and the paper's RBPMF accept): the broadband level's high-pass and
#: the body-motion band need an edge above 0 Hz. The aided tracker's default edge
#: (:data:`vibrospeed.estimators.aiding.BROADBAND_LO`).
BAND_LO_MIN = 2.0
#: log10-level histogram (causal): 1e-7 .. 1e3 in 0.02 decades
_LOG_LO, _LOG_HI, _BINS = -7.0, 3.0, 500
_WIDTH = (_LOG_HI - _LOG_LO) / _BINS
_CENTRES = _LOG_LO + _WIDTH * (np.arange(_BINS) + 0.5)


def _band(band: tuple[float, float]) -> tuple[float, float]:
    """``band`` with a lower edge at or below 0 raised to :data:`BAND_LO_MIN` (at most half
    the upper edge): a 0 Hz high-pass failed with an error naming a cut-off the user never
    set."""
    lo, hi = float(band[0]), float(band[1])
    return (lo if lo > 0 else min(BAND_LO_MIN, 0.5 * hi)), hi


def broadband_level(x: np.ndarray, dt: float, band: tuple[float, float], *,
                    frame_s: float = FRAME_S,
                    hop_s: float = HOP_S) -> tuple[np.ndarray, np.ndarray]:
    """``(ends, level)``: per frame the index of its last sample and its broadband level.

    ``band`` in rad/s (clipped to Nyquist); NaN samples count as 0, frames with fewer than half
    their samples finite get NaN.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    L = max(8, int(round(frame_s / dt)))
    hop = max(1, int(round(hop_s / dt)))
    if n < L:
        return np.zeros(0, np.int64), np.zeros(0)
    starts = np.arange(0, n - L + 1, hop)
    fin = np.isfinite(x)
    frames = np.lib.stride_tricks.sliding_window_view(np.where(fin, x, 0.0), L)[starts]
    good = np.lib.stride_tricks.sliding_window_view(fin, L)[starts].mean(axis=1) >= 0.5
    w = np.hanning(L)
    frames = frames - frames.mean(axis=1, keepdims=True)
    X = np.fft.rfft(frames * w, axis=1)
    f = 2 * np.pi * np.fft.rfftfreq(L, dt)
    lo, hi = band
    sel = (f >= lo) & (f <= min(hi, np.pi / dt))
    if sel.sum() < 3:  # a band narrower than the frame's resolution: the bins around it
        k = int(np.argmin(np.abs(f - lo)))
        sel = np.zeros_like(sel)
        sel[max(0, k - 1) : k + 2] = True
    P = np.abs(X[:, sel]) ** 2
    level = 2.0 * np.sqrt(np.median(P, axis=1)) / w.sum()
    level[~good] = np.nan
    return starts + L - 1, level


@njit(cache=True)
def _hist_quantile(hist, centres, total, q):
    """The ``q`` quantile of a histogram (bin centre)."""
    target = q * total
    acc = 0.0
    for i in range(hist.size):
        acc += hist[i]
        if acc >= target:
            return centres[i]
    return centres[-1]


@njit(cache=True)
def _causal(loglev, centres, lo, width, q, log_contrast, log_near, min_frames):
    hist = np.zeros(centres.size)
    out = np.zeros(loglev.size, np.bool_)
    total = 0.0
    last = False
    for i in range(loglev.size):
        lg = loglev[i]
        if np.isfinite(lg):
            k = min(max(int((lg - lo) / width), 0), centres.size - 1)
            hist[k] += 1.0
            total += 1.0
            if total >= min_frames:
                floor = _hist_quantile(hist, centres, total, q)
                med = _hist_quantile(hist, centres, total, 0.5)
                last = med - floor >= log_contrast and lg < floor + log_near
        out[i] = last
    return out


def classify(level: np.ndarray, *, causal: bool = False, min_contrast: float | None = None,
             near_floor: float | None = None) -> np.ndarray:
    """Standing (bool) per frame from the frames' broadband levels (module docstring)."""
    min_contrast = MIN_CONTRAST if min_contrast is None else min_contrast
    near_floor = NEAR_FLOOR if near_floor is None else near_floor
    level = np.asarray(level, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        lg = np.where(level > 0, np.log10(level), np.nan)
    lc, ln = np.log10(min_contrast), np.log10(near_floor)
    if causal:
        return _causal(lg, _CENTRES, _LOG_LO, _WIDTH, FLOOR_Q, lc, ln,
                       int(round(CAUSAL_WARMUP_S / HOP_S)))
    fin = np.isfinite(lg)
    out = np.zeros(lg.size, bool)
    if fin.sum() >= 4:
        floor = np.quantile(lg[fin], FLOOR_Q)
        if np.median(lg[fin]) - floor >= lc:
            out[fin] = lg[fin] < floor + ln
    # frames without a level repeat the last decision
    idx = np.maximum.accumulate(np.where(fin, np.arange(lg.size), -1))
    return np.where(idx >= 0, out[np.maximum(idx, 0)], False)


def _drop_short(flags: np.ndarray, k: int) -> np.ndarray:
    """``flags`` with runs of True shorter than ``k`` set False."""
    out = flags.copy()
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        if b - a < k:
            out[a:b] = False
    return out


def motion_level(x: np.ndarray, dt: float, ends: np.ndarray, upper_hz: float, *,
                 frame_s: float = MOTION_FRAME_S) -> np.ndarray:
    """Body-motion level per frame: ``x`` low-passed below ``upper_hz`` (the vehicle's motion
    and manoeuvres, below the wheel's band), over ``frame_s`` s ending at each of ``ends``, the
    RMS of its residual from a straight line (a step such as the end of a braking is a line
    within a few frames and does not read as motion)."""
    from vibrospeed.signal import prefilter as pf

    x = np.asarray(x, dtype=np.float64)
    fin = np.isfinite(x)
    y = pf.apply(pf.butter_sos("lowpass", upper_hz, 1.0 / dt, 2), np.where(fin, x, np.nan))
    ok = np.isfinite(y)
    y0 = np.where(ok, y - np.nanmean(y) if ok.any() else 0.0, 0.0)
    t = np.arange(x.size, dtype=np.float64)
    t0 = np.where(ok, t, 0.0)

    def csum(v):
        return np.concatenate(([0.0], np.cumsum(v)))

    sums = np.stack([csum(ok.astype(float)), csum(y0), csum(y0 * y0), csum(t0), csum(t0 * t0),
                     csum(t0 * y0)])
    L = max(3, int(round(frame_s / dt)))
    a = np.maximum(ends + 1 - L, 0)
    return line_residual(sums[:, ends + 1], sums[:, a], L)


def line_residual(end: np.ndarray, start: np.ndarray, L: int) -> np.ndarray:
    """RMS residual from a least-squares line per window, from the running sums of ``(1, y,
    y^2, t, t^2, t y)`` over the valid samples at each window's end and start (``end``,
    ``start``: (6, F)); NaN where fewer than ``L // 2`` of the window's ``L`` samples are valid."""
    c1, cy, cyy, ct, ctt, cty = range(6)
    k = end[c1] - start[c1]
    with np.errstate(invalid="ignore", divide="ignore"):
        my, mt = (end[cy] - start[cy]) / k, (end[ct] - start[ct]) / k
        vy = (end[cyy] - start[cyy]) / k - my * my
        vt = (end[ctt] - start[ctt]) / k - mt * mt
        cv = (end[cty] - start[cty]) / k - mt * my
        res = np.maximum(vy - cv * cv / vt, 0.0)
    out = np.sqrt(res)
    out[k < L // 2] = np.nan
    return out


def standstill(x: np.ndarray, dt: float, band: tuple[float, float], *, causal: bool = False,
               frame_s: float = FRAME_S, hop_s: float = HOP_S,
               edge_s: float = 0.0) -> np.ndarray:
    """Standing (bool) per sample of the raw accelerometer axis ``x`` (n,), or of several axes
    ``x`` (n, A): standing where every axis says so (module docstring).

    ``band``: the tracker's search band in rad/s (lowest fundamental .. highest harmonic).
    Offline each frame decides for the samples around its centre (nearest frame centre);
    causally a frame's decision holds from its last sample to the next frame's.
    ``edge_s`` (offline): each standing run is shortened by this much at both ends. A per-sample
    label needs none; a filter that *holds* its state at zero while standing (the aided
    tracker) needs its stops to end before the vehicle moves off, not with the frame that
    first sees the motion.
    """
    x = np.asarray(x, dtype=np.float64)
    band = _band(band)
    if x.ndim == 2:
        return np.logical_and.reduce([
            _standstill_axis(x[:, j], dt, band, causal=causal, frame_s=frame_s, hop_s=hop_s,
                             edge_s=edge_s)
            for j in range(x.shape[1])])
    return _standstill_axis(x, dt, band, causal=causal, frame_s=frame_s, hop_s=hop_s,
                            edge_s=edge_s)


def _motion_upper(lo_hz: float) -> float:
    """Hz, the body-motion band's upper edge below a search band starting at ``lo_hz``; 0 where
    it would not reach :data:`MOTION_MIN_HI_HZ` (no body-motion test)."""
    from vibrospeed.signal.prefilter import RANGE_HP

    upper = min(RANGE_HP * lo_hz, MOTION_HI_HZ)
    return upper if upper >= MOTION_MIN_HI_HZ else 0.0


def _standstill_axis(x, dt, band, *, causal, frame_s, hop_s, edge_s):
    from vibrospeed.signal import prefilter as pf

    n = x.size
    fs = 1.0 / dt
    lo_hz = band[0] / (2 * np.pi)
    hp = pf.butter_sos("highpass", min(pf.RANGE_HP * lo_hz, 0.45 * fs), fs, 4)
    ends, level = broadband_level(pf.apply(hp, x), dt, band, frame_s=frame_s, hop_s=hop_s)
    if ends.size == 0:
        return np.zeros(n, bool)
    still = classify(level, causal=causal)
    upper = _motion_upper(lo_hz)
    if upper:  # the body motion has room below the band
        L = max(8, int(round(frame_s / dt)))
        ref = ends if causal else np.minimum(ends - L // 2 + int(round(MOTION_FRAME_S / 2 / dt)),
                                             n - 1)
        motion = motion_level(x, dt, ref, upper)
        still &= classify(motion, causal=causal, min_contrast=1.0, near_floor=MOTION_NEAR)
    if not causal and MIN_STOP_S > 0:  # close gaps < 1 s within a stop, then drop short runs
        still = ~_drop_short(~still, int(round(1.0 / hop_s)))
        still = _drop_short(still, int(round(MIN_STOP_S / hop_s)))
        e = int(round(edge_s / hop_s))
        if e > 0:
            run = np.convolve(still.astype(np.int64), np.ones(2 * e + 1, np.int64), "same")
            still = run == 2 * e + 1
    d = int(round(CAUSAL_DWELL_S / hop_s))
    if causal and d > 0:  # a stop is declared after CAUSAL_DWELL_S s of standing frames
        run = np.convolve(still.astype(np.int64), np.ones(d + 1, np.int64))[: still.size]
        still = run == d + 1
    if causal:
        j = np.searchsorted(ends, np.arange(n), side="right") - 1
        return np.where(j >= 0, still[np.maximum(j, 0)], False)
    L = max(8, int(round(frame_s / dt)))
    centres = ends - L // 2
    j = np.clip(np.searchsorted(centres, np.arange(n)), 0, centres.size - 1)
    jm = np.maximum(j - 1, 0)
    nearer = np.abs(centres[jm] - np.arange(n)) < np.abs(centres[j] - np.arange(n))
    return still[np.where(nearer, jm, j)]


# ------------------------------------------------------------------------------------------
# streaming: one sample at a time, the decisions of ``standstill(..., causal=True)``
# ------------------------------------------------------------------------------------------
class StreamState(NamedTuple):
    """Causal detector state for one axis (:func:`stream_init`, :func:`stream_step`):
    the high-pass and low-pass filter states, the last frame's ``hp`` samples and the last
    body-motion window's ``lp`` samples (oldest first), samples seen, each level's histogram
    (``hist``: (2, bins)), frame counts ``total`` (2,) and last decisions ``last`` (2,), the
    run of standing frames and the current decision. ``hp`` and ``lp`` are ring buffers: sample
    ``i`` at ``i % size``."""

    hp_state: Any
    lp_state: Any
    hp: np.ndarray
    lp: np.ndarray
    count: int
    hist: np.ndarray
    total: np.ndarray
    last: np.ndarray
    run: int
    still: bool


class StreamPlan(NamedTuple):
    """What :func:`stream_step` needs besides the state: sample period, search band (rad/s),
    frame and hop lengths in samples, the filters, whether the body motion is used."""

    dt: float
    band: tuple[float, float]
    L: int
    hop: int
    Lm: int
    hp_sos: np.ndarray
    lp_sos: np.ndarray | None
    win: np.ndarray
    sel: np.ndarray


def stream_plan(dt: float, band: tuple[float, float]) -> StreamPlan:
    """The constants of :func:`standstill` (``causal=True``) at sample period ``dt`` for
    ``band`` (rad/s)."""
    from vibrospeed.signal import prefilter as pf

    band = _band(band)
    fs = 1.0 / dt
    lo_hz = band[0] / (2 * np.pi)
    hp = pf.butter_sos("highpass", min(pf.RANGE_HP * lo_hz, 0.45 * fs), fs, 4)
    upper = _motion_upper(lo_hz)
    lp = pf.butter_sos("lowpass", upper, fs, 2) if upper else None
    L = max(8, int(round(FRAME_S / dt)))
    f = 2 * np.pi * np.fft.rfftfreq(L, dt)  # the bins broadband_level reads
    sel = (f >= band[0]) & (f <= min(band[1], np.pi / dt))
    if sel.sum() < 3:
        k = int(np.argmin(np.abs(f - band[0])))
        sel = np.zeros_like(sel)
        sel[max(0, k - 1) : k + 2] = True
    return StreamPlan(float(dt), (float(band[0]), float(band[1])), L,
                      max(1, int(round(HOP_S / dt))), max(3, int(round(MOTION_FRAME_S / dt))),
                      hp, lp, np.hanning(L), sel)


def _frame_level(plan: StreamPlan, x: np.ndarray) -> float:
    """:func:`broadband_level` of the one frame ``x`` (``plan.L`` samples), the same
    operations without its framing."""
    fin = np.isfinite(x)
    if not fin.mean() >= 0.5:
        return np.nan
    fr = np.where(fin, x, 0.0)
    X = np.fft.rfft((fr - fr.mean()) * plan.win)
    return float(2.0 * np.sqrt(np.median(np.abs(X[plan.sel]) ** 2)) / plan.win.sum())


def stream_init(plan: StreamPlan) -> StreamState:
    """Nothing seen: not standing."""
    from vibrospeed.signal import prefilter as pf

    return StreamState(pf.init(plan.hp_sos), None if plan.lp_sos is None
                       else pf.init(plan.lp_sos), np.full(plan.L, np.nan),
                       np.full(plan.Lm, np.nan), 0, np.zeros((2, _BINS)), np.zeros(2),
                       np.zeros(2, np.bool_), 0, False)



def _stream_classify(hist, total, last, k, level, min_contrast, near_floor) -> None:
    """One frame of ``_causal`` for level ``k`` (0 broadband, 1 body motion), in place."""
    if not level > 0:  # NaN or no level: repeat the last decision
        return
    lg = float(np.log10(level))
    hist[k, min(max(int((lg - _LOG_LO) / _WIDTH), 0), _BINS - 1)] += 1.0
    total[k] += 1.0
    if total[k] >= int(round(CAUSAL_WARMUP_S / HOP_S)):
        floor = _hist_quantile(hist[k], _CENTRES, total[k], FLOOR_Q)
        med = _hist_quantile(hist[k], _CENTRES, total[k], 0.5)
        last[k] = (med - floor >= np.log10(min_contrast)
                   and lg < floor + np.log10(near_floor))


def stream_step(plan: StreamPlan, state: StreamState, x: float) -> tuple[StreamState, bool]:
    """One raw sample of one axis (NaN = missing): the causal decision at this sample, as
    :func:`standstill` (``causal=True``) gives it for the samples so far. Why: a device has
    no whole log; the detector keeps one frame of samples, one body-motion window and two
    level histograms (bounded memory). ``state`` is left as it is."""
    from vibrospeed.signal import prefilter as pf

    i = state.count
    hs, h = pf.step(plan.hp_sos, state.hp_state, x)
    hp = state.hp.copy()
    hp[i % plan.L] = h
    ls, lp = state.lp_state, state.lp
    if plan.lp_sos is not None:
        ls, v = pf.step(plan.lp_sos, ls, x)
        lp = lp.copy()
        lp[i % plan.Lm] = v
    run, still = state.run, state.still
    hist, total, last = state.hist, state.total, state.last
    if i >= plan.L - 1 and (i - plan.L + 1) % plan.hop == 0:  # a frame ends here
        hist, total, last = hist.copy(), total.copy(), last.copy()
        p = (i + 1) % plan.L
        lev = _frame_level(plan, np.concatenate((hp[p:], hp[:p])))
        _stream_classify(hist, total, last, 0, lev, MIN_CONTRAST, NEAR_FLOOR)
        frame = bool(last[0])
        if plan.lp_sos is not None:
            p = (i + 1) % plan.Lm
            w = np.concatenate((lp[p:], lp[:p]))[max(0, plan.Lm - 1 - i):]  # up to Lm so far
            ok = np.isfinite(w)
            t = np.arange(w.size, dtype=np.float64)[ok]
            y = w[ok] - (np.mean(w[ok]) if ok.any() else 0.0)
            sums = np.array([ok.sum(), y.sum(), (y * y).sum(), t.sum(), (t * t).sum(),
                             (t * y).sum()], dtype=np.float64)[:, None]
            motion = float(line_residual(sums, np.zeros_like(sums), plan.Lm)[0])
            _stream_classify(hist, total, last, 1, motion, 1.0, MOTION_NEAR)
            frame = frame and bool(last[1])
        d = int(round(CAUSAL_DWELL_S / HOP_S))
        run = run + 1 if frame else 0
        still = run >= d + 1
    return StreamState(hs, ls, hp, lp, i + 1, hist, total, last, run, still), still
