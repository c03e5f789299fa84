"""Pre-filters: thesis eq. 2.7 coefficients, streaming == batch, steady-state start, NaN."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal as sps

from vibrospeed.errors import ParameterError
from vibrospeed.signal import prefilter as pf


def test_thesis_bandpass_matches_eq_2_7():
    b, a = sps.sos2tf(pf.design("thesis-bp", 100.0))
    np.testing.assert_allclose(b, [0.0396, 0, -0.0791, 0, 0.0396], atol=6e-5)
    np.testing.assert_allclose(a, [1, -3.330, 4.192, -2.384, 0.522], atol=6e-4)


@pytest.mark.parametrize("preset", ["thesis-hp", "thesis-bp", "thesis-hplp", "paper-hp"])
def test_gain_at_passband_and_dc(preset):
    fs = 100.0
    sos = pf.design(preset, fs, M=2)
    w, h = sps.sosfreqz(sos, worN=[0.0, 2 * np.pi * 1e-9], fs=2 * np.pi * fs)
    assert abs(h[0]) < 1e-6  # all presets remove gravity / DC
    # -3 dB at the high-pass corner (4 rad/s; 8 Hz for the paper's)
    corner = 2 * np.pi * 8.0 if preset == "paper-hp" else 4.0
    _, hc = sps.sosfreqz(sos, worN=[corner], fs=2 * np.pi * fs)
    if preset != "thesis-hplp":
        assert abs(hc[0]) == pytest.approx(1 / np.sqrt(2), rel=0.05)


def test_lowpass_cutoff_per_M():
    fs = 100.0
    for M, wc in pf.THESIS_LP_CUTOFF.items():
        lp = pf.design("thesis-hplp", fs, M=M)[-1:]
        _, h = sps.sosfreqz(lp, worN=[wc], fs=2 * np.pi * fs)
        assert abs(h[0]) == pytest.approx(1 / np.sqrt(2), rel=0.02)


def test_constant_input_gives_no_transient():
    x = np.full(500, 9.80665)  # gravity on z
    y = pf.apply(pf.design("thesis-hp", 100.0), x)
    assert np.max(np.abs(y)) < 1e-9


@settings(max_examples=30, deadline=None)
@given(st.lists(st.one_of(st.floats(-50, 50), st.just(float("nan"))), min_size=1, max_size=80))
def test_streaming_equals_batch(xs):
    sos = pf.design("thesis-hplp", 100.0, M=2)
    x = np.array(xs)
    y = pf.apply(sos, x)
    s = pf.init(sos)
    ys = []
    for v in x:
        s, o = pf.step(sos, s, v)
        ys.append(o)
    np.testing.assert_array_equal(np.isnan(y), np.isnan(x))
    np.testing.assert_array_equal(ys, y)  # bitwise: step() follows sosfilt's operation order


def test_bad_cutoff_and_preset():
    with pytest.raises(ParameterError, match="cut-off"):
        pf.design("paper-hp", 10.0)  # 8 Hz above Nyquist of 5 Hz
    with pytest.raises(ParameterError, match="unknown pre-filter"):
        pf.design("nope", 100.0)
