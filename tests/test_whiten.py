"""Adaptive pre-whitening (:mod:`vibrospeed.signal.whiten`)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal as sps

from vibrospeed.signal import whiten as wh

FS = 100.0


def red_with_line(n, rng, line_hz=12.0, amp=0.05):
    """Body-motion-like red noise (integrated white) plus a line and a white floor."""
    t = np.arange(n) / FS
    return (np.cumsum(rng.normal(size=n)) * 0.01 + amp * np.sin(2 * np.pi * line_hz * t)
            + rng.normal(0, 0.01, n))


def test_step_equals_apply_bitwise_with_nans():
    rng = np.random.default_rng(0)
    x = red_with_line(2500, rng)
    x[700:720] = np.nan
    y = wh.apply(x, FS)
    state, ys = wh.init(), []
    for v in x:
        state, o = wh.step(state, v, FS)
        ys.append(o)
    np.testing.assert_array_equal(y, np.array(ys))
    assert np.isnan(y[700:720]).all() and np.isfinite(np.delete(y, range(700, 720))).all()


def test_background_flat_line_kept():
    rng = np.random.default_rng(1)
    y = wh.apply(red_with_line(12000, rng), FS)[2000:]
    f, P = sps.welch(y, fs=FS, nperseg=512)
    floor = np.median(P[(f > 1) & (f < 45)])
    # the red background (100x the floor at 1 Hz before) is within a factor 3 of flat
    low = np.median(P[(f > 0.5) & (f < 3)])
    assert 1 / 3 < low / floor < 3
    # the steady line stands ~27 dB over the floor in the input; the background is capped at
    # PEAK_MAX (6 dB) over its 3 Hz median, so the FIR takes at most ~6 dB off the line
    assert P[np.argmin(np.abs(f - 12.0))] / floor > 10 ** 1.8


def test_white_input_passes_nearly_unchanged_in_shape():
    rng = np.random.default_rng(2)
    x = rng.normal(size=6000)
    y = wh.apply(x, FS)[1000:]
    assert np.corrcoef(x[1000:], y)[0, 1] > 0.9
    assert np.std(y) == pytest.approx(1.0, rel=0.2)  # the input's power kept


def test_scale_comes_through():
    rng = np.random.default_rng(3)
    x = red_with_line(3000, rng)
    np.testing.assert_allclose(wh.apply(1e-3 * x, FS), 1e-3 * wh.apply(x, FS), rtol=1e-9,
                               atol=1e-15)


def test_identity_until_a_segment_is_seen():
    x = np.arange(1.0, 101.0)
    np.testing.assert_array_equal(wh.apply(x, FS)[:100], x)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.one_of(st.floats(-1e3, 1e3), st.just(float("nan"))), min_size=0,
                max_size=600))
def test_any_input_gives_finite_where_finite(values):
    x = np.array(values, dtype=float)
    y = wh.apply(x, FS)
    assert y.shape == x.shape
    assert np.array_equal(np.isnan(y), np.isnan(x))


def test_old_states_stay_valid_when_stepped_again():
    """The history storage is shared between successive states: stepping an old state again
    (a branch) or keeping it must not change what it, or the states after it, give."""
    rng = np.random.default_rng(4)
    x = red_with_line(1500, rng)
    state, states, ys = wh.init(), [], []
    for v in x:
        states.append(state)
        state, o = wh.step(state, v, FS)
        ys.append(o)
    # a branch from sample 700 with other data, then the main line replayed from its states
    branch = states[700]
    for v in rng.normal(size=300):
        branch, _ = wh.step(branch, v, FS)
    for k in (0, 699, 700, 701, 1200):
        _, o = wh.step(states[k], x[k], FS)
        assert o == ys[k]
    replay = states[700]
    for k in range(700, 1500):
        replay, o = wh.step(replay, x[k], FS)
        assert o == ys[k]


@settings(max_examples=25, deadline=None)
@given(st.lists(st.one_of(st.floats(-1e3, 1e3), st.just(float("nan"))), min_size=0,
                max_size=400),
       st.sampled_from([1.0, 2.5, 7.0, 100.0]))
def test_step_equals_apply_any_input_and_rate(values, fs):
    """Bitwise, also where the window W is shorter than the FIR (fs = 1 Hz: W = 6 samples)."""
    x = np.array(values, dtype=float)
    y = wh.apply(x, fs)
    state, ys = wh.init(), []
    for v in x:
        state, o = wh.step(state, v, fs)
        ys.append(o)
    np.testing.assert_array_equal(y, np.array(ys, dtype=float).reshape(y.shape))


def test_blocks_fade_from_the_previous_filter():
    """Reference: every block's FIR run over the whole signal with scipy.signal.lfilter, the
    output faded linearly from the previous block's FIR to the block's own."""
    rng = np.random.default_rng(4)
    x = red_with_line(3000, rng)
    W, B, _ = wh._sizes(FS)
    ref = np.empty_like(x)
    prev = (np.r_[1.0, np.zeros(wh.ORDER)], 1.0)
    for b0 in range(0, x.size, B):
        a, gain = wh.predictor(x[max(0, b0 - W) : b0], FS)
        new = gain * sps.lfilter(a, [1.0], x)[b0 : b0 + B]
        old = prev[1] * sps.lfilter(prev[0], [1.0], x)[b0 : b0 + B]
        lam = (np.arange(new.size) + 1.0) / B
        ref[b0 : b0 + B] = new if np.array_equal(a, prev[0]) and gain == prev[1] else (
            (1 - lam) * old + lam * new)
        prev = (a, gain)
    np.testing.assert_allclose(wh.apply(x, FS), ref, rtol=1e-9, atol=1e-12)


def _sweeping_line_gain_db(seed):
    """dB by which the whitener raises a sweeping line's power over the rest of the signal: a
    line swept 8 -> 30 -> 8 Hz every 10 s (a kart's corners) on red body motion and a white
    floor; the line is measured by demodulation at its known phase."""
    rng = np.random.default_rng(seed)
    n = 6000
    t = np.arange(n) / FS
    phase = 2 * np.pi * np.cumsum(19 + 11 * np.sin(2 * np.pi * t / 10)) / FS
    x = 0.3 * np.sin(phase) + rng.normal(0, 0.01, n) + np.cumsum(rng.normal(size=n)) * 0.01

    def snr(z):
        base = np.convolve(z * np.exp(-1j * phase), np.ones(25) / 25, "same")[1500:]
        line = 2 * np.real(base * np.exp(1j * phase[1500:]))
        return np.mean(np.abs(base) ** 2) / np.var(z[1500:] - line)

    return 10 * np.log10(snr(wh.apply(x, FS)) / snr(x))


def test_a_sweeping_line_stays_out_of_the_background(monkeypatch):
    """The per-segment median keeps a line that sweeps through the window out of the
    background; Welch's mean over the segments (the reference, patched in) lets it in."""
    median = [_sweeping_line_gain_db(s) for s in (1, 2, 3)]
    welch = sps.welch
    monkeypatch.setattr(sps, "welch", lambda *a, **k: welch(*a, **{**k, "average": "mean"}))

    def mean_predictors(z, w0, w1, fs):  # the scipy reference, with Welch's mean
        rows = [wh.predictor_reference(z[a:b], fs) for a, b in zip(w0, w1, strict=True)]
        return (np.array([r[0] for r in rows]).reshape(-1, wh.ORDER + 1),
                np.array([r[1] for r in rows], dtype=np.float64))

    monkeypatch.setattr(wh, "_predictors", mean_predictors)
    mean = [_sweeping_line_gain_db(s) for s in (1, 2, 3)]
    assert all(m > r + 2.5 for m, r in zip(median, mean, strict=True)), (median, mean)
