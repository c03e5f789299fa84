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
the first motion, with nothing to compare it with, is not recognised. The batch causal run and the
streaming detectors (:mod:`vibrospeed.signal.standstill_stream`: ``stream_step``, the lagged
``LagStream``) share the decision with the dwell (the compiled ``_frame_step``), so a change of
the rule is made once; the streams compute a frame's levels (``_frame_levels``, the body-motion
fit) in compiled code with numpy's arithmetic, to the bit (tests/test_standstill_stream_fast.py).

The constants are chosen on the randomised family (``simulate("random")``, with an idling
engine's broadband shaking) and checked on the real phone drives of ``hungary_car_phyphox``, whose
slow smooth stretches are the hard case; the broadband level alone declares a stop on slow smooth
roads, the body-motion level is what rules those out. Figures: ``benchmarks/robustness/
standstill.py`` and its ``STANDSTILL.md``.

Frames with fewer than half their samples finite have no level and repeat the last decision.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import ParameterError
from vibrospeed.signal import prefilter as pf

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
#: the body-motion level needs no contrast to its floor (its near-floor test is the rule)
_MOTION_CONTRAST = 1.0


def _band(band: tuple[float, float]) -> tuple[float, float]:
    """``band`` with a lower edge at or below 0 raised to :data:`BAND_LO_MIN` (at most half
    the upper edge): a 0 Hz high-pass failed with an error naming a cut-off the user never
    set."""
    lo, hi = float(band[0]), float(band[1])
    return (lo if lo > 0 else min(BAND_LO_MIN, 0.5 * hi)), hi


def _samples(seconds: float, dt: float, least: int) -> int:
    """``seconds`` in samples of period ``dt``, at least ``least``: the broadband frame (8), its
    hop (1) and the body-motion window (3)."""
    return max(least, int(round(seconds / dt)))


def _band_bins(L: int, dt: float, band: tuple[float, float]) -> np.ndarray:
    """The rfft bins of an ``L``-sample frame the broadband level reads: those in ``band``
    (rad/s, clipped to Nyquist), or the three around its lower edge where the band is narrower
    than the frame's resolution."""
    f = 2 * np.pi * np.fft.rfftfreq(L, dt)
    lo, hi = band
    sel = (f >= lo) & (f <= min(hi, np.pi / dt))
    if sel.sum() < 3:
        k = int(np.argmin(np.abs(f - lo)))
        sel = np.zeros_like(sel)
        sel[max(0, k - 1) : k + 2] = True
    return sel


def _frame_levels(frames: np.ndarray, win: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """Broadband level of each frame (row of ``frames``, NaN = missing): the per-frame rule
    of :func:`broadband_level` (:mod:`~vibrospeed.signal.standstill_stream` computes the same
    numbers compiled). NaN samples count as 0; a frame with fewer than half its samples finite
    gets NaN."""
    L = frames.shape[1]
    fin = np.isfinite(frames)
    good = 2 * np.count_nonzero(fin, axis=1) >= L
    frames = np.where(fin, frames, 0.0)
    frames = frames - frames.sum(axis=1, keepdims=True) / L  # the mean, without np.mean's cost
    X = np.fft.rfft(frames * win, axis=1)
    # the median power over the bins: np.median's value (the middle one, or the mean of the two
    # middle ones; NaN if any is) at a fraction of its per-call cost
    P = np.sort(np.abs(X[:, sel]) ** 2, axis=1)
    h = P.shape[1] // 2
    med = P[:, h] if P.shape[1] % 2 else (P[:, h - 1] + P[:, h]) / 2
    level = 2.0 * np.sqrt(med) / win.sum()
    level[~good | np.isnan(P[:, -1])] = np.nan
    return level


def broadband_level(x: np.ndarray, dt: float, band: tuple[float, float], *,
                    frame_s: float = FRAME_S,
                    hop_s: float = HOP_S) -> tuple[np.ndarray, np.ndarray]:
    """``(ends, level)``: per frame the index of its last sample and its broadband level.

    ``band`` in rad/s (clipped to Nyquist); NaN samples count as 0, frames with fewer than half
    their samples finite get NaN.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    L, hop = _samples(frame_s, dt, 8), _samples(hop_s, dt, 1)
    if n < L:
        return np.zeros(0, np.int64), np.zeros(0)
    starts = np.arange(0, n - L + 1, hop)
    frames = np.lib.stride_tricks.sliding_window_view(x, L)[starts]
    return starts + L - 1, _frame_levels(frames, np.hanning(L), _band_bins(L, dt, band))


def _log_level(level: np.ndarray) -> np.ndarray:
    """log10 of the levels, NaN where there is none (NaN or not above 0)."""
    level = np.asarray(level, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(level > 0, np.log10(level), np.nan)


@njit(cache=True)
def _hist_quantiles(hist, centres, total, q):
    """``(q quantile, median)`` of a histogram (bin centres), in one scan of its cumulative
    counts (the same sums as one scan per quantile)."""
    t1, t2 = q * total, 0.5 * total
    lo, hi = min(t1, t2), max(t1, t2)
    n = hist.size
    a = b = n - 1
    acc = 0.0
    for i in range(n):
        acc += hist[i]
        if acc >= lo and a == n - 1:
            a = i
        if acc >= hi:
            b = i
            break
    return (centres[a], centres[b]) if t1 <= t2 else (centres[b], centres[a])


class _Rule(NamedTuple):
    """The causal rule's constants (:func:`_rule`), one argument of the compiled frame step:
    log10 contrast and near-floor factors of the broadband (``b``) and body-motion (``m``)
    levels, whether the body motion is used, frames before a decision, the floor quantile,
    frames of dwell, and the log10-level histogram's lower edge and bin width (its bin centres
    are the step's own argument)."""

    lcb: float
    lnb: float
    lcm: float
    lnm: float
    motion: bool
    warmup: int
    q: float
    dwell: int
    lo: float
    width: float


def _rule(*, motion: bool, dwell: int, min_contrast: float | None = None,
          near_floor: float | None = None) -> _Rule:
    """The module's causal constants as read now (a benchmark may override them);
    ``min_contrast`` / ``near_floor`` of the broadband level (default the module's)."""
    min_contrast = MIN_CONTRAST if min_contrast is None else min_contrast
    near_floor = NEAR_FLOOR if near_floor is None else near_floor
    return _Rule(float(np.log10(min_contrast)), float(np.log10(near_floor)),
                 float(np.log10(_MOTION_CONTRAST)), float(np.log10(MOTION_NEAR)), bool(motion),
                 int(round(CAUSAL_WARMUP_S / HOP_S)), float(FLOOR_Q), max(int(dwell), 0),
                 float(_LOG_LO), float(_WIDTH))


@njit(cache=True)
def _level_step(hist, total, last, k, lg, lc, ln, rule, centres):
    """Level ``k`` (0 broadband, 1 body motion) of one frame, log10 ``lg`` (NaN: none, repeat
    the last decision): into its histogram, then standing when the median is ``lc`` above the
    floor quantile and ``lg`` within ``ln`` of it, once ``rule.warmup`` frames are seen."""
    if np.isfinite(lg):
        b = min(max(int((lg - rule.lo) / rule.width), 0), centres.size - 1)
        hist[k, b] += 1.0
        total[k] += 1.0
        if total[k] >= rule.warmup:
            floor, med = _hist_quantiles(hist[k], centres, total[k], rule.q)
            last[k] = med - floor >= lc and lg < floor + ln
    return last[k]


@njit(cache=True)
def _frame_step(hist, total, last, run, lgb, lgm, rule, centres):
    """One frame of the causal detector, the one implementation of its rule (the batch
    :func:`_causal` and the streaming
    :func:`~vibrospeed.signal.standstill_stream.stream_step` both run it): both levels' decisions
    (``hist`` (2, bins), ``total`` (2,), ``last`` (2,) updated in place), then the dwell.
    Returns ``(run, still)``: the run of standing frames and whether a stop is declared."""
    still = _level_step(hist, total, last, 0, lgb, rule.lcb, rule.lnb, rule, centres)
    if rule.motion:
        still = _level_step(hist, total, last, 1, lgm, rule.lcm, rule.lnm, rule,
                            centres) and still
    run = run + 1 if still else 0
    return run, run > rule.dwell


@njit(cache=True)
def _causal(lgb, lgm, rule, centres):
    """:func:`_frame_step` over the frames' log-levels from nothing seen."""
    hist = np.zeros((2, centres.size))
    total = np.zeros(2)
    last = np.zeros(2, np.bool_)
    out = np.zeros(lgb.size, np.bool_)
    run = 0
    for i in range(lgb.size):
        run, out[i] = _frame_step(hist, total, last, run, lgb[i], lgm[i], rule, centres)
    return out


def classify(level: np.ndarray, *, causal: bool = False, min_contrast: float | None = None,
             near_floor: float | None = None) -> np.ndarray:
    """Standing (bool) per frame from the frames' broadband levels (module docstring); causally
    without the dwell."""
    lg = _log_level(level)
    if causal:
        return _causal(lg, lg, _rule(motion=False, dwell=0, min_contrast=min_contrast,
                                     near_floor=near_floor), _CENTRES)
    min_contrast = MIN_CONTRAST if min_contrast is None else min_contrast
    near_floor = NEAR_FLOOR if near_floor is None else near_floor
    lc, ln = np.log10(min_contrast), np.log10(near_floor)
    fin = np.isfinite(lg)
    out = np.zeros(lg.size, bool)
    if fin.sum() >= 4:
        floor = np.quantile(lg[fin], FLOOR_Q)
        if np.median(lg[fin]) - floor >= lc:
            out[fin] = lg[fin] < floor + ln
    # frames without a level repeat the last decision
    idx = np.maximum.accumulate(np.where(fin, np.arange(lg.size), -1))
    return np.where(idx >= 0, out[np.maximum(idx, 0)], False)


class _LagPlan(NamedTuple):
    """Where a delay of ``lag`` s goes (samples ``shift`` and ``extra``, frames ``ahead``):
    the frame deciding a sample ends up to ``shift`` after it (centred on it at most), its
    body-motion window ``extra`` past the frame's end (centred on the frame at most), the
    dwell sees ``ahead`` frames past it; together at most ``lag`` s past the sample."""

    shift: int
    extra: int
    ahead: int


def _lag_plan(lag: float, dt: float, frame_s: float, hop_s: float, motion: bool) -> _LagPlan:
    """:class:`_LagPlan` for a detector with (``motion``) or without the body-motion test."""
    within = max(int(np.floor(lag / dt + 1e-9)), 0)  # samples of look-ahead
    L, Lm = _samples(frame_s, dt, 8), _samples(MOTION_FRAME_S, dt, 3)
    shift = min(within, L // 2)
    extra = min(within - shift, max(Lm // 2 - L // 2, 0)) if motion else 0
    return _LagPlan(shift, extra, (within - shift - extra) // _samples(hop_s, dt, 1))


def _check_lag(lag: float, causal: bool) -> None:
    """Refuse a ``lag`` that is not a finite number >= 0 s, or one given to the offline
    detector (which reads the whole log): NaN or a negative lag was the causal detector's
    decision without a word, a lag offline was ignored."""
    if not (lag >= 0 and np.isfinite(lag)):
        raise ParameterError(f"standstill: lag must be a finite number >= 0 s, got {lag}")
    if lag > 0 and not causal:
        raise ParameterError(f"standstill: lag = {lag:g} s is the causal detector's delay; "
                             "the offline one (causal=False) reads the whole log")


def _lag_dwell(flags: np.ndarray, dwell: int, ahead: int) -> np.ndarray:
    """The causal dwell with ``ahead`` frames of look-ahead: frame ``i`` is declared standing
    where it stands and its run of standing ``flags`` up to frame ``i + ahead`` holds more
    than ``dwell`` frames (``ahead = 0``: the causal rule, a run ending at ``i``)."""
    if not flags.any():
        return np.zeros(flags.size, bool)
    f = flags.astype(np.int8)
    edges = np.diff(np.concatenate(([0], f, [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # [start, stop)
    idx = np.arange(flags.size)
    k = np.searchsorted(starts, idx, side="right") - 1  # the run that may hold frame i
    k0 = np.maximum(k, 0)
    inside = flags & (k >= 0)
    seen = np.minimum(stops[k0] - 1, idx + ahead) - starts[k0] + 1
    return inside & (seen > dwell)


def _drop_short(flags: np.ndarray, k: int) -> np.ndarray:
    """``flags`` with runs of True shorter than ``k`` set False."""
    out = flags.copy()
    edges = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        if b - a < k:
            out[a:b] = False
    return out


def _line_terms(ok: np.ndarray, y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(6, m): the terms ``(1, y, y^2, t, t^2, t y)`` whose sums over a window
    :func:`line_residual` reads (``ok``: 1 where the sample is valid, ``y`` and ``t`` 0 where
    not)."""
    return np.stack([ok, y, y * y, t, t * t, t * y])


def motion_level(x: np.ndarray, dt: float, ends: np.ndarray, upper_hz: float, *,
                 frame_s: float = MOTION_FRAME_S) -> np.ndarray:
    """Body-motion level per frame: ``x`` low-passed below ``upper_hz`` (the vehicle's motion
    and manoeuvres, below the wheel's band), over ``frame_s`` s ending at each of ``ends``, the
    RMS of its residual from a straight line (a step such as the end of a braking is a line
    within a few frames and does not read as motion)."""
    x = np.asarray(x, dtype=np.float64)
    fin = np.isfinite(x)
    y = pf.apply(pf.butter_sos("lowpass", upper_hz, 1.0 / dt, 2), np.where(fin, x, np.nan))
    ok = np.isfinite(y)
    y0 = np.where(ok, y - np.nanmean(y) if ok.any() else 0.0, 0.0)
    t0 = np.where(ok, np.arange(x.size, dtype=np.float64), 0.0)
    sums = np.zeros((6, x.size + 1))
    np.cumsum(_line_terms(ok.astype(float), y0, t0), axis=1, out=sums[:, 1:])
    L = _samples(frame_s, dt, 3)
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
               lag: float = 0.0, frame_s: float = FRAME_S, hop_s: float = HOP_S,
               edge_s: float = 0.0) -> np.ndarray:
    """Standing (bool) per sample of the raw accelerometer axis ``x`` (n,), or of several axes
    ``x`` (n, A): standing where every axis says so (module docstring).

    ``band``: the tracker's search band in rad/s (lowest fundamental .. highest harmonic).
    Offline each frame decides for the samples around its centre (nearest frame centre);
    causally a frame's decision holds from its last sample to the next frame's.
    ``lag`` (s, causal): the decisions of a device that may wait ``lag`` s (the fixed-lag
    smoother's): each sample's uses data at most ``lag`` s after it (:func:`decide`).
    ``edge_s`` (offline): each standing run is shortened by this much at both ends. A per-sample
    label needs none; a filter that *holds* its state at zero while standing (the aided
    tracker) needs its stops to end before the vehicle moves off, not with the frame that
    first sees the motion.
    """
    x = np.asarray(x, dtype=np.float64)
    band = _band(band)
    _check_lag(lag, causal)
    if x.ndim == 2:
        return np.logical_and.reduce([
            _standstill_axis(x[:, j], dt, band, causal=causal, lag=lag, frame_s=frame_s,
                             hop_s=hop_s, edge_s=edge_s)
            for j in range(x.shape[1])])
    return _standstill_axis(x, dt, band, causal=causal, lag=lag, frame_s=frame_s, hop_s=hop_s,
                            edge_s=edge_s)


def _motion_upper(lo_hz: float) -> float:
    """Hz, the body-motion band's upper edge below a search band starting at ``lo_hz``; 0 where
    it would not reach :data:`MOTION_MIN_HI_HZ` (no body-motion test)."""
    upper = min(pf.RANGE_HP * lo_hz, MOTION_HI_HZ)
    return upper if upper >= MOTION_MIN_HI_HZ else 0.0


def _filters(dt: float, band: tuple[float, float]) -> tuple[np.ndarray, float]:
    """The broadband level's high-pass (sos) for ``band`` (rad/s, lower edge above 0) at
    sample period ``dt``, and the body-motion band's upper edge in Hz (0: none)."""
    fs = 1.0 / dt
    lo_hz = band[0] / (2 * np.pi)
    hp = pf.butter_sos("highpass", min(pf.RANGE_HP * lo_hz, 0.45 * fs), fs, 4)
    return hp, _motion_upper(lo_hz)


def _standstill_axis(x, dt, band, *, causal, lag, frame_s, hop_s, edge_s):
    n = x.size
    hp, upper = _filters(dt, band)
    ends, level = broadband_level(pf.apply(hp, x), dt, band, frame_s=frame_s, hop_s=hop_s)
    motion = None
    if upper and ends.size:  # the body motion has room below the band
        L = _samples(frame_s, dt, 8)
        motion = motion_level(x, dt, motion_ends(ends, L, n, dt, causal=causal, lag=lag),
                              upper)
    return decide(ends, level, motion, n, dt, causal=causal, lag=lag, frame_s=frame_s,
                  hop_s=hop_s, edge_s=edge_s)


def motion_ends(ends: np.ndarray, L: int, n: int, dt: float, *, causal: bool,
                lag: float = 0.0) -> np.ndarray:
    """Last sample of each frame's body-motion window: the frame's own end causally (with a
    ``lag``, as far past it as the lag allows, up to centred on the frame: :func:`_lag_plan`),
    else the window centred on the frame (frames of ``L`` samples ending at ``ends``, ``n``
    samples)."""
    if causal:
        if lag > 0:
            return np.minimum(ends + _lag_plan(lag, dt, L * dt, HOP_S, True).extra, n - 1)
        return ends
    return np.minimum(ends - L // 2 + int(round(MOTION_FRAME_S / 2 / dt)), n - 1)


def decide(ends: np.ndarray, level: np.ndarray, motion: np.ndarray | None, n: int, dt: float,
           *, causal: bool, lag: float = 0.0, frame_s: float = FRAME_S, hop_s: float = HOP_S,
           edge_s: float = 0.0, piece: int | None = None) -> np.ndarray:
    """Standing (bool) per sample of ``n`` from the frames' broadband ``level`` and body
    ``motion`` (None: no body-motion test), frames ending at sample ``ends`` (module
    docstring): causally the dwell, offline the gap closing, the short runs dropped and
    ``edge_s``; each sample takes the decision of its frame (causal: the last ended; offline:
    the nearest centre), ``piece`` samples at a time (bounded temporaries, same result).

    ``lag`` (s, causal) lets each sample's decision see ``lag`` s past it, as a device that
    waits that long before it reports: the frame that decides a sample may end up to
    ``min(lag, frame / 2)`` after it (the frame centred on it at most), and the dwell counts
    a run's standing frames up to the rest of the lag after that frame (:func:`_lag_dwell`),
    so a stop is declared from its first standing frame once the lag holds the dwell. Each
    frame's own decision stays the causal one (its floor from the frames before it)."""
    _check_lag(lag, causal)
    if ends.size == 0:
        return np.zeros(n, bool)
    L = _samples(frame_s, dt, 8)
    shift = 0
    if causal:  # a stop is declared after CAUSAL_DWELL_S s of standing frames
        lgb = _log_level(level)
        dwell = int(round(CAUSAL_DWELL_S / hop_s))
        lgm = lgb if motion is None else _log_level(motion)
        if lag > 0:
            plan = _lag_plan(lag, dt, frame_s, hop_s, motion is not None)
            shift = plan.shift
            flags = _causal(lgb, lgm, _rule(motion=motion is not None, dwell=0), _CENTRES)
            still = _lag_dwell(flags, dwell, plan.ahead)
        else:
            rule = _rule(motion=motion is not None, dwell=dwell)
            still = _causal(lgb, lgm, rule, _CENTRES)
    else:
        still = classify(level)
        if motion is not None:
            still &= classify(motion, min_contrast=_MOTION_CONTRAST, near_floor=MOTION_NEAR)
        if MIN_STOP_S > 0:  # close gaps < 1 s within a stop, then drop short runs
            still = ~_drop_short(~still, int(round(1.0 / hop_s)))
            still = _drop_short(still, int(round(MIN_STOP_S / hop_s)))
            e = int(round(edge_s / hop_s))
            if e > 0:
                run = np.convolve(still.astype(np.int64), np.ones(2 * e + 1, np.int64), "same")
                still = run == 2 * e + 1
    out = np.empty(n, bool)
    centres = ends - L // 2
    step = piece or max(n, 1)
    for p0 in range(0, n, step):
        i = np.arange(p0, min(p0 + step, n))
        if causal:
            j = np.searchsorted(ends, i + shift, side="right") - 1
            out[i] = np.where(j >= 0, still[np.maximum(j, 0)], False)
        else:
            j = np.clip(np.searchsorted(centres, i), 0, centres.size - 1)
            jm = np.maximum(j - 1, 0)
            nearer = np.abs(centres[jm] - i) < np.abs(centres[j] - i)
            out[i] = still[np.where(nearer, jm, j)]
    return out
