"""The compiled standstill stream (:mod:`vibrospeed.signal.standstill_stream`) against the
implementation before it, kept below verbatim as the reference (numpy per frame, one
``prefilter.step`` per filter and sample): every decision, every frame's log-levels and the
filters' rings bit for bit, on short simulated drives (a start from standing, two stops,
missing samples) at 100 Hz, 99.5 Hz and 51 Hz (an odd frame), with and without the body-motion
level, ``stream_step`` and ``LagStream`` with lags 0, 1 and 2 s."""

from __future__ import annotations

import functools
import pickle
from typing import Any, NamedTuple

import numpy as np
import pytest

from vibrospeed.signal import prefilter as pf
from vibrospeed.signal import standstill_stream as sst
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
    _frame_levels,
    _frame_step,
    _lag_plan,
    _line_terms,
    _log_level,
    _Rule,
    _rule,
    _samples,
    line_residual,
)
from vibrospeed.sim import simulate

# ---- the reference: vibrospeed.signal.standstill_stream as of 8935b71, verbatim ----


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
    frame and hop lengths in samples, the filters, the frame's window and bins, the rule."""

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


def stream_plan(dt: float, band: tuple[float, float]) -> StreamPlan:
    """The constants of :func:`~vibrospeed.signal.standstill.standstill` (``causal=True``) at
    sample period ``dt`` for ``band`` (rad/s)."""
    band = _band(band)
    hp, upper = _filters(dt, band)
    lp = pf.butter_sos("lowpass", upper, 1.0 / dt, 2) if upper else None
    L = _samples(FRAME_S, dt, 8)
    return StreamPlan(float(dt), (float(band[0]), float(band[1])), L, _samples(HOP_S, dt, 1),
                      _samples(MOTION_FRAME_S, dt, 3),
                      hp, lp, np.hanning(L), _band_bins(L, dt, band),
                      _rule(motion=upper > 0, dwell=int(round(CAUSAL_DWELL_S / HOP_S))))


def stream_init(plan: StreamPlan) -> StreamState:
    """Nothing seen: not standing."""
    return StreamState(pf.init(plan.hp_sos), None if plan.lp_sos is None
                       else pf.init(plan.lp_sos), np.full(plan.L, np.nan),
                       np.full(plan.Lm, np.nan), 0, np.zeros((2, _BINS)), np.zeros(2),
                       np.zeros(2, np.bool_), 0, False)


def _window_motion(w: np.ndarray, Lm: int) -> float:
    """:func:`~vibrospeed.signal.standstill.motion_level` of the one window ``w`` (the
    low-passed samples so far, at most ``Lm``): its sums made directly (a device has no whole
    log's running sums)."""
    ok = np.isfinite(w)
    y = w[ok]
    y = y - y.sum() / y.size if y.size else y  # the mean, without np.mean's cost
    t = np.arange(w.size, dtype=np.float64)[ok]
    sums = _line_terms(np.ones(y.size), y, t).sum(axis=1)[:, None]
    return float(line_residual(sums, np.zeros_like(sums), Lm)[0])


def stream_step(plan: StreamPlan, state: StreamState, x: float) -> tuple[StreamState, bool]:
    """One raw sample of one axis (NaN = missing): the causal decision at this sample, as
    :func:`~vibrospeed.signal.standstill.standstill` (``causal=True``) gives it for the
    samples so far. Why: a device has no whole log; the detector keeps one frame of samples,
    one body-motion window and two level histograms (bounded memory). ``state`` is left as it
    is."""
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
        lev = [_frame_levels(np.concatenate((hp[p:], hp[:p]))[None], plan.win, plan.sel)[0],
               np.nan]
        if plan.lp_sos is not None:
            p = (i + 1) % plan.Lm
            lev[1] = _window_motion(np.concatenate((lp[p:], lp[:p]))[max(0, plan.Lm - 1 - i):],
                                    plan.Lm)  # up to Lm samples so far
        lgb, lgm = _log_level(lev)
        run, still = _frame_step(hist, total, last, run, lgb, lgm, plan.rule, _CENTRES)
        still = bool(still)
    return StreamState(hs, ls, hp, lp, i + 1, hist, total, last, run, still), still


class LagStream:
    """The causal detector with a delay of ``lag`` s on one axis, one raw sample at a time: the
    decisions of :func:`~vibrospeed.signal.standstill.standstill` (``causal=True, lag=lag``)
    for a device that reports each sample ``lag`` s late (the fixed-lag smoother's stops,
    :class:`vibrospeed.estimators.grid.lagged.LaggedTracker`).

    :meth:`push` takes a sample (NaN = missing) and returns the decisions (bool) that the lag
    now allows, oldest first; :meth:`finish` those left at the recording's end. The per-frame
    rule is the batch one (``_frame_levels``, the compiled ``_frame_step``, :func:`_lag_plan`);
    as in :func:`stream_step` the body-motion window's line is fitted to its own samples (the
    batch run centres the whole log first: the same residual up to rounding). Memory: one
    frame, one body-motion window and the frames of one lag. ``lag = 0``: the causal detector.
    """

    def __init__(self, dt: float, band: tuple[float, float], lag: float = 0.0) -> None:
        _check_lag(lag, True)
        self.plan = plan = stream_plan(dt, band)
        self.lag = _lag_plan(lag, dt, FRAME_S, HOP_S, plan.lp_sos is not None)
        self.rule = plan.rule._replace(dwell=0)  # each frame's own decision; the dwell below
        self.dwell = plan.rule.dwell
        self._hs = pf.init(plan.hp_sos)
        self._ls = None if plan.lp_sos is None else pf.init(plan.lp_sos)
        self._hp = np.full(plan.L, np.nan)
        self._lp = np.full(plan.Lm, np.nan)
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
        lgm = np.nan
        if self.plan.lp_sos is not None:
            Lm = self.plan.Lm
            q = (i + 1) % Lm
            w = np.concatenate((self._lp[q:], self._lp[:q]))[max(0, Lm - 1 - i):]
            lgm = float(_log_level(np.array([_window_motion(w, Lm)]))[0])
        self._run, f = _frame_step(self._hist, self._total, self._last, self._run, lgb, lgm,
                                   self.rule, _CENTRES)
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
        self._hs, h = pf.step(p.hp_sos, self._hs, x)
        self._hp[i % p.L] = h
        if p.lp_sos is not None:
            self._ls, v = pf.step(p.lp_sos, self._ls, x)
            self._lp[i % p.Lm] = v
        if i >= p.L - 1 and (i - p.L + 1) % p.hop == 0:  # a frame ends here
            q = (i + 1) % p.L
            lev = _frame_levels(np.concatenate((self._hp[q:], self._hp[:q]))[None], p.win,
                                p.sel)
            self._pending.append((i, float(_log_level(lev)[0])))
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


# ---- the tests ----

#: (sample period, band rad/s, every k-th simulated 100 Hz sample): the body-motion level in
#: use (15 rad/s) or not (2 rad/s); 99.5 Hz: a 199-sample body-motion window; 51 Hz: a 51-sample
#: frame (odd rfft), a 13-sample hop
CASES = [(0.01, (15.0, 300.0), 1), (0.01, (2.0, 90.0), 1), (1 / 99.5, (15.0, 300.0), 1),
         (1 / 51, (15.0, 300.0), 2)]
IDS = ["100Hz-motion", "100Hz-no-motion", "99.5Hz", "51Hz"]


@functools.lru_cache
def _drive(k: int) -> np.ndarray:
    """ay of a 40 s stop-and-go drive from standing with two stops, every ``k``-th sample,
    with missing samples: the first few (the filters start late), a short gap, one longer
    than half a frame, single ones, an infinite one."""
    x = simulate("stop_and_go", seed=5, duration=40)["ay"][::k].copy()
    n = x.size
    x[:5] = np.nan
    x[n // 4 : n // 4 + 30 // k] = np.nan
    x[3 * n // 8 : 3 * n // 8 + 100 // k] = np.nan
    x[n // 2 : n // 2 + 100 // k : 7] = np.nan
    x[-3] = np.inf
    return x


@functools.lru_cache
def _reference(case: int) -> np.ndarray:
    dt, band, k = CASES[case]
    plan, x = stream_plan(dt, band), _drive(k)
    st, out = stream_init(plan), np.zeros(x.size, bool)
    for i, v in enumerate(x):
        st, out[i] = stream_step(plan, st, v)
    return out


def test_pairwise_sum_is_numpys():
    """The compiled sum is numpy's (pairwise, initial 0.0) bit for bit, at every length up to
    several blocks of 128."""
    rng = np.random.default_rng(0)
    for n in [*range(300), 383, 400, 513, 700, 1031, 2049]:
        a = rng.normal(size=n) * 10.0 ** rng.uniform(-6, 6, size=n)
        assert sst._np_sum(a, n) == a.sum()
        assert sst._pairwise_sum(np.r_[1e9, a], 1, n) + 0.0 == a.sum()


def test_rfft_is_numpys():
    rng = np.random.default_rng(1)
    for n in (8, 51, 100, 101, 200):
        a = rng.normal(size=n)
        np.testing.assert_array_equal(sst._rfft(a), np.fft.rfft(a))


def test_median_level_is_numpys():
    """The median power by insertion sort is numpy's sort's, ties and odd and even counts;
    NaN if any power is."""
    rng = np.random.default_rng(2)
    for n in (1, 2, 3, 10, 45, 46, 201):
        for _ in range(20):
            a = np.abs(rng.normal(size=n)) * 10.0 ** rng.uniform(-3, 3, size=n)
            a[rng.integers(n)] = a[rng.integers(n)]
            P, h = np.sort(np.abs(a) ** 2), n // 2
            med = P[h] if n % 2 else (P[h - 1] + P[h]) / 2
            assert sst._median_level(a, 1.7) == 2.0 * np.sqrt(med) / 1.7
    assert np.isnan(sst._median_level(np.array([1.0, np.nan, 2.0]), 1.0))


@pytest.mark.parametrize("case", range(len(CASES)), ids=IDS)
def test_frame_levels_and_rings_are_the_references(case):
    """At every frame's end the broadband and body-motion log-levels are the reference's
    (``_frame_levels``, ``_window_motion``) bit for bit; the filters' states and rings too."""
    dt, band, k = CASES[case]
    x = _drive(k)
    po, pn = stream_plan(dt, band), sst.stream_plan(dt, band)
    so, sn = stream_init(po), sst.stream_init(pn)
    frames = 0
    for i, v in enumerate(x):
        so, _ = stream_step(po, so, v)
        sn, _ = sst.stream_step(pn, sn, v)
        if i >= po.L - 1 and (i - po.L + 1) % po.hop == 0:
            p = (i + 1) % po.L
            want = [_log_level(_frame_levels(np.concatenate((so.hp[p:], so.hp[:p]))[None],
                                             po.win, po.sel))[0], np.nan]
            got = [sst._broadband(pn, sn.buf, i), np.nan]
            if po.lp_sos is not None:
                q = (i + 1) % po.Lm
                w = np.concatenate((so.lp[q:], so.lp[:q]))[max(0, po.Lm - 1 - i):]
                want[1] = _log_level(_window_motion(w, po.Lm))
                got[1] = sst._log10(sst._motion(sn.buf, pn.o_lp, pn.Lm, i))
            np.testing.assert_array_equal(got, want)
            frames += 1
    assert frames > 100
    np.testing.assert_array_equal(sn.hp, so.hp)
    np.testing.assert_array_equal(sn.lp, so.lp)
    for a, b in ((sn.hp_state, so.hp_state), (sn.lp_state, so.lp_state)):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_array_equal(a.zi, b.zi)
            assert a.started == b.started
    np.testing.assert_array_equal(sn.hist, so.hist)
    np.testing.assert_array_equal(sn.total, so.total)
    np.testing.assert_array_equal(sn.last, so.last)
    assert (sn.count, sn.run, sn.still) == (so.count, so.run, so.still)


@pytest.mark.parametrize("case", range(len(CASES)), ids=IDS)
def test_stream_step_decisions_are_the_references(case):
    """Every sample's decision; a state kept (or pickled) and stepped again gives the same
    (``state`` is left as it is)."""
    dt, band, k = CASES[case]
    x, want = _drive(k), _reference(case)
    assert 0.01 < want.mean() < 0.3 and not want[: x.size // 4].all()  # stops to find
    plan = sst.stream_plan(dt, band)
    st, got = sst.stream_init(plan), np.zeros(x.size, bool)
    kept = {}
    for i, v in enumerate(x):
        if i in (x.size // 3, x.size // 2 + 13):
            kept[i] = st, pickle.loads(pickle.dumps(st))
        st, got[i] = sst.stream_step(plan, st, v)
    np.testing.assert_array_equal(got, want)
    for i, states in kept.items():
        for s in states:
            for j in range(i, i + 200):
                s, f = sst.stream_step(plan, s, x[j])
                assert f == want[j]


@pytest.mark.parametrize("lag", [0.0, 1.0, 2.0])
@pytest.mark.parametrize("case", range(len(CASES)), ids=IDS)
def test_lag_stream_decisions_are_the_references(case, lag):
    """Every sample's decision with a lag, as the reference gives them out (the same samples
    at each push) and at the end."""
    dt, band, k = CASES[case]
    x = _drive(k)
    ref, new = LagStream(dt, band, lag), sst.LagStream(dt, band, lag)
    got = []
    for v in x:
        out = new.push(float(v))
        assert out == ref.push(float(v))
        got += out
    out = new.finish()
    assert out == ref.finish()
    got += out
    assert len(got) == x.size and 0.01 < np.mean(got) < 0.3
    if lag == 0:  # the causal detector
        np.testing.assert_array_equal(got, _reference(case))
