"""Detectors of the aided tracker: window standstill test, CUSUM, acceleration-mode detector."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.errors import ParameterError
from vibrospeed.signal import detectors as det


def _window_reference(y, n, mu):
    """Thesis eq. 3.1-3.3 written directly on the finite samples (NaN: repeat last decision)."""
    out = np.zeros(y.size, bool)
    seen: list[float] = []
    last = False
    for k, v in enumerate(y):
        if np.isfinite(v):
            seen.append(v)
            if len(seen) >= n:
                w = np.array(seen[-n:])
                last = bool(w.max() < w.mean() + mu and w.min() > w.mean() - mu)
            else:
                last = False
        out[k] = last
    return out


def test_window_test_matches_definition():
    rng = np.random.default_rng(1)
    # quiet (std 0.004), moving (std 0.1), quiet, with a few NaN samples
    y = np.concatenate([rng.normal(0, 0.004, 300), rng.normal(0, 0.1, 300),
                        rng.normal(0, 0.004, 300)])
    y[[5, 310, 311, 700]] = np.nan
    got = det.window_test(y)
    ref = _window_reference(y, 20, 0.019)
    np.testing.assert_array_equal(got, ref)
    # sanity: mostly standstill in the quiet parts, never in the moving part
    assert got[50:300].mean() > 0.95
    assert not got[330:600].any()
    assert not got[:19].any()  # fewer than N samples seen


def test_window_step_equals_batch():
    rng = np.random.default_rng(2)
    y = rng.normal(0, 0.01, 200)
    y[17] = np.nan
    st_ = det.window_init(20)
    steps = []
    for v in y:
        st_, d = det.window_step(st_, v)
        steps.append(d)
    np.testing.assert_array_equal(np.array(steps), det.window_test(y))
    # chunked batch (state carried) equals whole
    s2 = det.window_init(20)
    a = det.window_test(y[:77], state=s2)
    for v in y[:77]:
        s2, _ = det.window_step(s2, v)
    b = det.window_test(y[77:], state=s2)
    np.testing.assert_array_equal(np.concatenate([a, b]), det.window_test(y))


def test_cusum_hand_computed():
    # g: 0.3, 0.9, max(0,-0.3)=0, 1.8 > h -> alarm, reset 0, 0.1, 0.8
    eps = np.array([0.5, 0.8, -1.0, 2.0, 0.3, 0.9])
    res = det.cusum(eps, nu=0.2, h=1.0)
    np.testing.assert_allclose(res.g, [0.3, 0.9, 0.0, 0.0, 0.1, 0.8], atol=1e-12)
    np.testing.assert_array_equal(res.alarm, [False, False, False, True, False, False])
    assert res.final.since == 2.0
    # step-by-step gives the same
    s = det.cusum_init()
    for k, e in enumerate(eps):
        s, a = det.cusum_step(s, e, 0.2, 1.0)
        assert a == res.alarm[k]
        assert s.g == pytest.approx(res.g[k], abs=1e-12)


def test_cusum_nan_keeps_state():
    res = det.cusum(np.array([0.6, np.nan, 0.6]), nu=0.1, h=5.0)
    np.testing.assert_allclose(res.g, [0.5, 0.5, 1.0])


def test_standstill_eps_cusum_delay():
    # quiet residuals: eps ~ 1, alarm after ceil(h / (1 - nu)) samples at the earliest
    eps = det.standstill_eps(np.zeros(50), sigma_ss=0.03)
    res = det.cusum(eps, nu=0.5, h=10.0)
    first = int(np.flatnonzero(res.alarm)[0])
    assert first == 20  # g after k+1 samples = 0.5 (k+1) > 10  <=>  k+1 = 21
    loud = det.standstill_eps(np.full(50, 0.1), sigma_ss=0.03)
    assert not det.cusum(loud, nu=0.5, h=10.0).alarm.any()


@given(st.lists(st.floats(-3, 3, allow_nan=False), min_size=1, max_size=60),
       st.floats(0.0, 1.0), st.floats(0.1, 5.0))
@settings(max_examples=60, deadline=None)
def test_cusum_invariants(eps, nu, h):
    res = det.cusum(np.array(eps), nu, h)
    assert np.all(res.g >= 0) and np.all(res.g <= h)
    assert np.all(res.g[res.alarm] == 0)


def test_mode_detector_matches_definition():
    rng = np.random.default_rng(3)
    u = np.concatenate([rng.normal(0, 0.05, 100), 0.5 + rng.normal(0, 0.05, 60),
                        rng.normal(0, 0.05, 100), -0.6 + rng.normal(0, 0.05, 50)])
    res = det.accel_mode(u)
    ubar = np.array([u[k - 19:k + 1].mean() if k >= 19 else np.nan for k in range(u.size)])
    np.testing.assert_allclose(res.ubar, ubar, atol=1e-12, equal_nan=True)
    acc = np.abs(np.nan_to_num(ubar)) >= 0.2
    np.testing.assert_array_equal(res.accelerating, acc)
    boost = acc & ~np.concatenate([[False], acc[:-1]])
    np.testing.assert_array_equal(res.boost, boost)
    assert res.boost.sum() == 2
    # streaming equals batch
    s = det.mode_init()
    for k, v in enumerate(u):
        s, d = det.mode_step(s, v)
        assert d.accelerating == res.accelerating[k] and d.boost == res.boost[k]


def test_bad_parameters():
    with pytest.raises(ParameterError):
        det.window_test(np.zeros(5), n=0)
    with pytest.raises(ParameterError):
        det.cusum(np.zeros(5), 0.1, h=0.0)
    with pytest.raises(ParameterError):
        det.accel_mode(np.zeros(5), mu=-1)
