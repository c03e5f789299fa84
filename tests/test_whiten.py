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
    assert P[np.argmin(np.abs(f - 12.0))] / floor > 3  # the line stands out


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
