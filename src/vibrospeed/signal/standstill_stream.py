"""The standstill detector of :mod:`vibrospeed.signal.standstill` one raw sample at a time, for
a device: :func:`stream_step` gives the causal detector's decisions (``standstill(...,
causal=True)``) and :class:`LagStream` those with a delay (``lag``, the fixed-lag smoother's),
in bounded memory (one frame, one body-motion window, the level histograms and the frames of
one lag). The per-frame rule is the batch one (the compiled ``_frame_step``, ``_lag_plan``),
so a change of the rule is made once.

Cost: a sample is one compiled call (both filters, the ring buffers) on a copy of one small
array; a frame (every ``HOP_S`` s) adds the FFT of the frame (numpy's pocketfft, as the batch
run) and compiled code for the rest. The compiled parts make numpy's arithmetic in its order
(its pairwise sums: the whitener's :func:`~vibrospeed.signal._whiten_kernels._pairwise`) and
leave to numpy what numba computes differently
(``abs`` of a complex number, ``log10``), so each frame's levels are those of the batch
functions (``_frame_levels``; ``line_residual`` of one window) bit for bit.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vibrospeed.signal import dsp
from vibrospeed.signal import prefilter as pf
from vibrospeed.signal._whiten_kernels import _pairwise as _pairwise_sum  # numpy's sum
from vibrospeed.signal.standstill import (
    _BINS,
    _CENTRES,
    CAUSAL_DWELL_S,
    FRAME_S,
    HOP_S,
    MOTION_FRAME_S,
    _band,
    _band_bins,
    _check_lag,
    _filters,
    _frame_step,
    _lag_plan,
    _Rule,
    _rule,
    _samples,
)


def _rfft_gufuncs() -> tuple[Any, Any]:
    """numpy's rfft gufuncs (even and odd lengths) behind ``np.fft.rfft``, called directly for
    a third of its per-call cost; None where this numpy has none that gives its numbers."""
    try:
        from numpy.fft import _pocketfft_umath as pfu

        even, odd = pfu.rfft_n_even, pfu.rfft_n_odd
        for n, f in ((8, even), (9, odd)):
            a = np.linspace(-1.0, 2.0, n) ** 2
            if not np.array_equal(f(a, 1, out=np.empty(n // 2 + 1, np.complex128)),
                                  np.fft.rfft(a)):
                return None, None
        return even, odd
    except Exception:  # another numpy: its public rfft
        return None, None


_RFFT_EVEN, _RFFT_ODD = _rfft_gufuncs()

#: a NamedTuple's fields as one tuple, without its generated ``__new__``'s cost per sample
_new = tuple.__new__

#: the state array's head: samples seen, whether each filter has started (0/1), the filters'
#: sections, the rings' lengths and the hop (so that the compiled step and a state's
#: properties read its parts from it)
_COUNT, _HP_ON, _LP_ON, _NH, _NL, _NHP, _NLP, _HOP, _HEAD = range(9)


class StreamState(NamedTuple):
    """Causal detector state for one axis (:func:`stream_init`, :func:`stream_step`):
    ``buf`` the per-sample part in one array (samples seen, whether each filter has started,
    the high-pass and low-pass filter states, the last frame's ``hp`` samples and the last
    body-motion window's ``lp`` samples, both ring buffers: sample ``i`` at ``i % size``; the
    properties below read them), each level's histogram (``hist``: (2, bins)), frame counts
    ``total`` (2,) and last decisions ``last`` (2,), the run of standing frames and the
    current decision."""

    buf: np.ndarray
    hist: np.ndarray
    total: np.ndarray
    last: np.ndarray
    run: int
    still: bool

    def _part(self, k: int) -> tuple[int, int]:
        """Start and length in ``buf`` of part ``k``: 0 high-pass state, 1 low-pass state,
        2 ``hp`` ring, 3 ``lp`` ring."""
        b = self.buf
        n = [2 * int(b[_NH]), 2 * int(b[_NL]), int(b[_NHP]), int(b[_NLP])]
        return _HEAD + sum(n[:k]), n[k]

    @property
    def count(self) -> int:
        """Samples seen."""
        return int(self.buf[_COUNT])

    @property
    def hp(self) -> np.ndarray:
        """The last frame's high-passed samples (ring buffer, a copy)."""
        o, n = self._part(2)
        return self.buf[o : o + n].copy()

    @property
    def lp(self) -> np.ndarray:
        """The last body-motion window's low-passed samples (ring buffer, a copy)."""
        o, n = self._part(3)
        return self.buf[o : o + n].copy()

    @property
    def hp_state(self) -> pf.PrefilterState:
        """The high-pass filter's state (a copy)."""
        o, n = self._part(0)
        return pf.PrefilterState(self.buf[o : o + n].reshape(-1, 2).copy(),
                                 bool(self.buf[_HP_ON]))

    @property
    def lp_state(self) -> pf.PrefilterState | None:
        """The low-pass filter's state (a copy; None: no body-motion test)."""
        o, n = self._part(1)
        return (pf.PrefilterState(self.buf[o : o + n].reshape(-1, 2).copy(),
                                  bool(self.buf[_LP_ON])) if n else None)


class StreamPlan(NamedTuple):
    """What :func:`stream_step` needs besides the state: sample period, search band (rad/s),
    frame and hop lengths in samples, the filters, the frame's window and bins, the rule (and
    as a plain tuple, ``rule_t``); and for the compiled step both filters' sections, each
    beside its rest state on a unit input (``k``: (sections, 8), the high-pass's first), the
    window's sum, the bins as a range (``b0 .. b1 - 1``) and where the rings start in the
    state array (``o_hp``, ``o_lp``)."""

    dt: float
    band: tuple[float, float]
    L: int
    hop: int
    Lm: int
    hp_sos: np.ndarray
    lp_sos: np.ndarray | None
    win: np.ndarray
    sel: np.ndarray
    rule: _Rule
    rule_t: tuple
    k: np.ndarray
    wsum: float
    b0: int
    b1: int
    o_hp: int
    o_lp: int


def _sections(sos: np.ndarray | None) -> np.ndarray:
    """(sections, 8): each section's coefficients, then its state at rest on a unit input
    (:func:`~vibrospeed.signal.dsp.sosfilt_zi`); (0, 8) for no filter."""
    if sos is None:
        return np.zeros((0, 8))
    sos = np.asarray(sos, dtype=np.float64)
    return np.hstack([sos, dsp.sosfilt_zi(sos)])


def stream_plan(dt: float, band: tuple[float, float]) -> StreamPlan:
    """The constants of :func:`~vibrospeed.signal.standstill.standstill` (``causal=True``) at
    sample period ``dt`` for ``band`` (rad/s)."""
    band = _band(band)
    hp, upper = _filters(dt, band)
    lp = pf.butter_sos("lowpass", upper, 1.0 / dt, 2) if upper else None
    L = _samples(FRAME_S, dt, 8)
    Lm = _samples(MOTION_FRAME_S, dt, 3)
    win, sel = np.hanning(L), _band_bins(L, dt, band)
    bins = np.flatnonzero(sel)
    if bins.size == 0 or np.any(np.diff(bins) != 1):  # _band_bins makes one range
        raise ValueError(f"standstill: the band's frame bins are not one range: {bins}")
    k = np.ascontiguousarray(np.vstack([_sections(hp), _sections(lp)]))
    o_hp = _HEAD + 2 * k.shape[0]
    rule = _rule(motion=upper > 0, dwell=int(round(CAUSAL_DWELL_S / HOP_S)))
    return StreamPlan(float(dt), (float(band[0]), float(band[1])), L, _samples(HOP_S, dt, 1),
                      Lm, hp, lp, win, sel, rule, tuple(rule), k, float(win.sum()),
                      int(bins[0]), int(bins[-1]) + 1, o_hp, o_hp + L)


def _init_buf(plan: StreamPlan) -> np.ndarray:
    """The per-sample state array from nothing seen: filters not started, rings NaN."""
    buf = np.full(plan.o_lp + plan.Lm, np.nan)
    buf[:plan.o_hp] = 0.0
    buf[_NH] = plan.hp_sos.shape[0]
    buf[_NL] = 0 if plan.lp_sos is None else plan.lp_sos.shape[0]
    buf[_NHP], buf[_NLP], buf[_HOP] = plan.L, plan.Lm, plan.hop
    return buf


def stream_init(plan: StreamPlan) -> StreamState:
    """Nothing seen: not standing."""
    return StreamState(_init_buf(plan), np.zeros((2, _BINS)), np.zeros(2),
                       np.zeros(2, np.bool_), 0, False)


@njit(cache=True)
def _filter(k, buf, on, o, x):
    """One sample ``x`` through the filter of sections ``k`` (:func:`_sections`) whose state
    is ``buf[o : o + 2 n]``, started where ``buf[on]`` is 1 (else at rest on ``x``), in place:
    :func:`vibrospeed.signal.prefilter.step`'s numbers (its compiled section step). NaN (or
    inf) gives NaN and leaves the state."""
    if not np.isfinite(x):
        return np.nan
    n = k.shape[0]
    zi = buf[o : o + 2 * n].reshape((n, 2))
    if buf[on] == 0.0:
        for s in range(n):
            zi[s, 0] = k[s, 6] * x
            zi[s, 1] = k[s, 7] * x
        buf[on] = 1.0
    return pf._sos_step(k[:, :6], zi, x, zi)  # zf over zi: each value is read before it goes


@njit(cache=True)
def _advance(k, buf, x):
    """One raw sample into the state array ``buf`` (in place; its head gives the layout):
    both filters (sections ``k``, the high-pass's first), their outputs into the rings. True
    where a frame ends at this sample."""
    i = int(buf[_COUNT])
    nh, nl = int(buf[_NH]), int(buf[_NL])
    L, hop = int(buf[_NHP]), int(buf[_HOP])
    o_hp = _HEAD + 2 * (nh + nl)
    buf[o_hp + i % L] = _filter(k[:nh], buf, _HP_ON, _HEAD, x)
    if nl:
        Lm = int(buf[_NLP])
        buf[o_hp + L + i % Lm] = _filter(k[nh:], buf, _LP_ON, _HEAD + 2 * nh, x)
    buf[_COUNT] = i + 1
    return i >= L - 1 and (i - L + 1) % hop == 0




@njit(cache=True)
def _np_sum(a, n):
    """``np.sum(a[:n])``: numpy's initial 0.0 plus the pairwise sum."""
    return 0.0 + _pairwise_sum(a, 0, n)


@njit(cache=True)
def _hp_frame(buf, o_hp, L, i, win):
    """The frame ending at sample ``i`` from the ``hp`` ring, as
    :func:`~vibrospeed.signal.standstill._frame_levels` transforms it: NaN as 0, less its mean,
    times the window; and whether at least half its samples are finite."""
    fr = np.empty(L)
    p = (i + 1) % L
    good = 0
    for j in range(L):
        v = buf[o_hp + (p + j) % L]
        if np.isfinite(v):
            good += 1
        else:
            v = 0.0
        fr[j] = v
    m = _np_sum(fr, L) / L
    for j in range(L):
        fr[j] = (fr[j] - m) * win[j]
    return fr, 2 * good >= L


@njit(cache=True)
def _median_level(a, wsum):
    """Broadband level from the bins' magnitudes ``a`` (``|X|``, numpy's): ``2 sqrt(median
    |X|^2) / sum(w)``, the middle power or the mean of the two middle ones (NaN if any power
    is NaN). The powers are sorted by insertion (tens of bins; numba's ``np.sort`` takes
    seconds to compile)."""
    n = a.size
    P = np.empty(n)
    for j in range(n):
        v = a[j] * a[j]
        if np.isnan(v):
            return np.nan
        m = j
        while m > 0 and P[m - 1] > v:
            P[m] = P[m - 1]
            m -= 1
        P[m] = v
    h = n // 2
    med = P[h] if n % 2 else (P[h - 1] + P[h]) / 2
    return 2.0 * np.sqrt(med) / wsum


@njit(cache=True, error_model="numpy")
def _motion(buf, o_lp, Lm, i):
    """Body-motion level of the window ending at sample ``i`` (its last ``min(i + 1, Lm)``
    samples in the ``lp`` ring): the RMS residual from a least-squares line through its
    finite samples, NaN where fewer than ``Lm // 2`` are (``motion_level`` /
    ``line_residual`` of :mod:`vibrospeed.signal.standstill` for one window, with the window's
    own mean taken out first, in the same sums)."""
    nw = min(i + 1, Lm)
    y = np.empty(nw)
    t = np.empty(nw)
    m = 0
    first = i - nw + 1
    for j in range(nw):
        v = buf[o_lp + (first + j) % Lm]
        if np.isfinite(v):
            y[m] = v
            t[m] = j
            m += 1
    if m:
        mean = _np_sum(y, m) / m
        for j in range(m):
            y[j] = y[j] - mean
    w = np.empty(m)
    k = float(m)  # the sum of m ones, exact
    sy = _np_sum(y, m)
    for j in range(m):
        w[j] = y[j] * y[j]
    syy = _np_sum(w, m)
    st = _np_sum(t, m)
    for j in range(m):
        w[j] = t[j] * t[j]
    stt = _np_sum(w, m)
    for j in range(m):
        w[j] = t[j] * y[j]
    sty = _np_sum(w, m)
    my, mt = sy / k, st / k
    vy = syy / k - my * my
    vt = stt / k - mt * mt
    cv = sty / k - mt * my
    res = vy - cv * cv / vt
    if res < 0.0:  # np.maximum(res, 0.0): NaN stays
        res = 0.0
    return np.nan if k < Lm // 2 else np.sqrt(res)


def _log10(v: float) -> float:
    """``_log_level`` of one level: numpy's log10 (its vectorised one, which the batch run
    uses, is not libm's), NaN where the level is NaN or not above 0."""
    return float(np.log10(v)) if v > 0 else math.nan


def _rfft(fr: np.ndarray) -> np.ndarray:
    """``np.fft.rfft(fr)`` (``fr`` 1-D float64), through its gufunc where this numpy has it."""
    if _RFFT_EVEN is None:
        return np.fft.rfft(fr)
    n = fr.size
    return (_RFFT_ODD if n % 2 else _RFFT_EVEN)(fr, 1, out=np.empty(n // 2 + 1, np.complex128))


def _broadband(plan: StreamPlan, buf: np.ndarray, i: int) -> float:
    """log10 of the broadband level of the frame ending at sample ``i`` (NaN: none), as
    :func:`~vibrospeed.signal.standstill._frame_levels` gives it."""
    fr, good = _hp_frame(buf, plan.o_hp, plan.L, i, plan.win)
    if not good:
        return math.nan
    return _log10(_median_level(np.abs(_rfft(fr)[plan.b0 : plan.b1]), plan.wsum))


@njit(cache=True)
def _frame(hist, total, last, run, lgb, lgm, rule, centres):
    """:func:`~vibrospeed.signal.standstill._frame_step` with the rule as a plain tuple (a
    NamedTuple argument costs a microsecond per call to type): ``(run, still)``, the level
    state updated in place."""
    return _frame_step(hist, total, last, run, lgb, lgm, _Rule(*rule), centres)


def stream_step(plan: StreamPlan, state: StreamState, x: float) -> tuple[StreamState, bool]:
    """One raw sample of one axis (NaN = missing): the causal decision at this sample, as
    :func:`~vibrospeed.signal.standstill.standstill` (``causal=True``) gives it for the
    samples so far. Why: a device has no whole log; the detector keeps one frame of samples,
    one body-motion window and two level histograms (bounded memory). ``state`` is left as it
    is."""
    buf = state.buf.copy()
    if not _advance(plan.k, buf, float(x)):
        return _new(StreamState, (buf,) + state[1:]), state.still  # no frame ends here
    i = int(buf[_COUNT]) - 1  # a frame ends here
    lgb = _broadband(plan, buf, i)
    lgm = _log10(_motion(buf, plan.o_lp, plan.Lm, i)) if plan.lp_sos is not None else math.nan
    hist, total, last = state.hist.copy(), state.total.copy(), state.last.copy()
    run, still = _frame(hist, total, last, state.run, lgb, lgm, plan.rule_t, _CENTRES)
    still = bool(still)
    return StreamState(buf, hist, total, last, run, still), still


class LagStream:
    """The causal detector with a delay of ``lag`` s on one axis, one raw sample at a time: the
    decisions of :func:`~vibrospeed.signal.standstill.standstill` (``causal=True, lag=lag``)
    for a device that reports each sample ``lag`` s late (the fixed-lag smoother's stops,
    :class:`vibrospeed.estimators.grid.lagged.LaggedTracker`).

    :meth:`push` takes a sample (NaN = missing) and returns the decisions (bool) that the lag
    now allows, oldest first; :meth:`finish` those left at the recording's end. The per-frame
    rule is the batch one (the compiled ``_frame_step``, :func:`_lag_plan`);
    as in :func:`stream_step` the body-motion window's line is fitted to its own samples (the
    batch run centres the whole log first: the same residual up to rounding). Memory: one
    frame, one body-motion window and the frames of one lag. ``lag = 0``: the causal detector.
    """

    def __init__(self, dt: float, band: tuple[float, float], lag: float = 0.0) -> None:
        _check_lag(lag, True)
        self.plan = plan = stream_plan(dt, band)
        self.lag = _lag_plan(lag, dt, FRAME_S, HOP_S, plan.lp_sos is not None)
        self.rule = plan.rule._replace(dwell=0)  # each frame's own decision; the dwell below
        self._rule_t = tuple(self.rule)
        self.dwell = plan.rule.dwell
        self._buf = _init_buf(plan)  # filters and rings (stream_step's, stepped in place)
        self._hist, self._total = np.zeros((2, _BINS)), np.zeros(2)
        self._last = np.zeros(2, np.bool_)
        self._run = 0
        self.count = 0  # samples pushed
        self._pending: list[tuple[int, float]] = []  # (frame end, log10 level): motion due
        self._flags: list[bool] = []  # frame k's flag at [k - self._f0]
        self._starts: list[int] = []  # the first frame of frame k's standing run
        self._f0 = 0
        self._final: dict[int, bool] = {}  # frame -> declared standing (the dwell applied)
        self._next_final = 0  # first frame whose declaration is not yet final
        self._next = 0  # first sample not yet decided

    def _frame_of(self, i: int, n_frames: int | None = None) -> int:
        """The frame that decides sample ``i`` (-1: none; at the end, the last one)."""
        p = self.plan
        k = i + self.lag.shift - (p.L - 1)
        j = -1 if k < 0 else k // p.hop
        return j if n_frames is None else min(j, n_frames - 1)

    def _flag(self, lgb: float, i: int) -> None:
        """Frame's flag, its body-motion window ending at sample ``i``."""
        p = self.plan
        lgm = _log10(_motion(self._buf, p.o_lp, p.Lm, i)) if p.lp_sos is not None else math.nan
        self._run, f = _frame(self._hist, self._total, self._last, self._run, lgb, lgm,
                              self._rule_t, _CENTRES)
        k = self._f0 + len(self._flags)
        prev = self._flags[-1] if self._flags else False
        self._starts.append(self._starts[-1] if (prev and f) else k)
        self._flags.append(bool(f))

    def _declare(self, end: bool) -> None:
        """Final declarations of the frames whose look-ahead is complete (``end``: all)."""
        n = self._f0 + len(self._flags)
        while self._next_final < n:
            j = self._next_final
            last = min(j + self.lag.ahead, n - 1)
            if not end and j + self.lag.ahead > n - 1:
                # not all its look-ahead frames are in: final only if its run has ended
                if all(self._flags[m - self._f0] for m in range(j + 1, n)):
                    break
            seen_to = j
            while seen_to < last and self._flags[seen_to + 1 - self._f0]:
                seen_to += 1
            f = self._flags[j - self._f0]
            self._final[j] = f and seen_to - self._starts[j - self._f0] + 1 > self.dwell
            self._next_final += 1

    def _decisions(self, n_frames: int | None = None) -> list[bool]:
        out = []
        while self._next < self.count:
            j = self._frame_of(self._next, n_frames)
            if j < 0:
                out.append(False)
            elif j in self._final:
                out.append(self._final[j])
            else:
                break
            self._next += 1
        # no later sample reads a frame before this one (at the end they read the last one)
        need = min(self._frame_of(self._next), self._next_final - 1)
        for j in [j for j in self._final if j < need]:
            del self._final[j]
        drop = min(min(self._next_final, need) - self._f0, len(self._flags) - 1)
        if drop > 0:  # the last frame's flag and run start stay: the next frame's run reads it
            del self._flags[:drop], self._starts[:drop]
            self._f0 += drop
        return out

    def push(self, x: float) -> list[bool]:
        """One raw sample; the decisions of the samples now decided, oldest first."""
        p, i = self.plan, self.count
        if _advance(p.k, self._buf, float(x)):
            self._pending.append((i, _broadband(p, self._buf, i)))  # a frame ends here
        self.count = i + 1
        flagged = False
        while self._pending and self._pending[0][0] + self.lag.extra <= i:
            self._flag(self._pending.pop(0)[1], i)
            flagged = True
        if flagged:  # only a new frame's flag makes a declaration final
            self._declare(False)
        elif self._next < i:
            return []  # the samples before this one still wait for their frame
        else:
            j = self._frame_of(i)
            if j >= 0 and j not in self._final:
                return []  # this one waits for its frame too
        return self._decisions()

    def finish(self) -> list[bool]:
        """The decisions of the samples left: the last frames' body-motion windows end at the
        last sample (as the batch run's do at the log's end)."""
        i = self.count - 1
        while self._pending:
            self._flag(self._pending.pop(0)[1], i)
        self._declare(True)
        n_frames = self._f0 + len(self._flags)
        return self._decisions(n_frames)
