"""Subharmonic summation (Hermes 1988) and the paper's favourable scoring."""

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import shs
from vibrospeed.types import Recording


def _harmonics(omega, orders, amps, n=200, dt=0.01, noise=0.0, seed=0):
    t = np.arange(n) * dt
    rng = np.random.default_rng(seed)
    y = sum(a * np.cos(k * omega * t + rng.uniform(0, 6))
            for k, a in zip(orders, amps, strict=True))
    return y + noise * rng.normal(size=n)


@pytest.mark.parametrize("omega", [23.0, 37.5, 52.0])
def test_finds_missing_fundamental(omega):
    cfg = shs.Config()
    x = _harmonics(omega, [2, 3, 4], [1.0, 1.0, 0.8], noise=0.1)
    assert abs(np.abs(np.fft.rfft(x * np.hanning(x.size), 4096))[
        int(round(omega / (2 * np.pi) / (100 / 4096)))] ) < 20  # fundamental really absent
    est, _ = shs.batch_estimate(cfg, x)
    assert est == pytest.approx(omega, abs=0.3)


def test_pure_tone_and_harmonic_series():
    cfg = shs.Config()
    assert shs.batch_estimate(cfg, _harmonics(41.0, [1], [1.0]))[0] == pytest.approx(41.0, abs=0.2)
    est, _ = shs.batch_estimate(cfg, _harmonics(66.0, [1, 2, 3], [1.0, 0.6, 0.4], noise=0.3))
    assert est == pytest.approx(66.0, abs=0.3)


def test_step_equals_run():
    cfg = shs.Config(batch=100)
    y = np.concatenate([_harmonics(w, [1, 2], [1, 0.5], n=100, seed=i)
                        for i, w in enumerate([30, 35, 40, 45])])[:370]
    res = shs.run(cfg, y)
    st = shs.init(cfg)
    got = []
    for v in y:
        st, est = shs.step(cfg, st, v)
        if np.isfinite(est.omega):
            got.append(est.omega)
    assert np.array_equal(np.array(got), res.omega) and len(got) == 3
    np.testing.assert_allclose(res.omega, [30, 35, 40], atol=0.5)
    assert st.count == res.final.count == 70
    r1 = shs.run(cfg, y[:150])
    r2 = shs.run(cfg, y[150:], r1.final)
    assert np.array_equal(np.r_[r1.omega, r2.omega], res.omega)
    assert list(r2.start) == [-50, 50]


def test_favourable_score():
    est = np.array([30.0, 14.0, 50.0, np.nan, 33.0])
    tru = np.array([31.0, 29.0, 30.0, 30.0, 30.0])
    s = shs.favourable_score(est, tru, tol=5.0)
    assert (s.kept, s.total, s.halved) == (3, 4, 1)
    np.testing.assert_allclose(s.corrected, [30.0, 28.0, np.nan, np.nan, 33.0])
    assert s.rmse == pytest.approx(np.sqrt((1 + 1 + 9) / 3))
    np.testing.assert_allclose(shs.batch_means(np.arange(10.0), np.array([0, 5]), 5), [2, 7])


def test_estimate_and_errors():
    t = np.arange(0, 6, 0.01)
    ay = np.cos(45 * t) + 0.5 * np.cos(90 * t)
    tr = shs.estimate(Recording(t, {"ay": ay}), params={"prefilter": "thesis-hp"})
    assert np.nanmax(np.abs(tr.omega - 45)) < 0.5
    assert np.isnan(tr.omega_std).all() and np.nanmax(tr.extras["batch_id"]) == 2
    with pytest.raises(ParameterError, match="less than one period"):
        shs.Config(batch=50, omega_min=5.0)
    with pytest.raises(ParameterError, match="Nyquist"):
        shs.Config(dt=0.05)


@pytest.mark.parametrize(("fs", "omega_min", "batch", "noted"), [
    (100.0, 10.0, 200, False), (400.0, 10.0, 800, False), (100.0, 2.0, 315, True),
    (400.0, 2.0, 1257, True)])
def test_default_batch_is_two_seconds_or_one_period_of_omega_min(fs, omega_min, batch, noted):
    # the paper's 200 samples at 100 Hz are 2 s; at 400 Hz a 200-sample batch (0.5 s) held less
    # than one period of the default range's floor and was refused
    t = np.arange(0, 16, 1 / fs)
    ay = np.cos(20 * t) + 0.5 * np.cos(40 * t)
    params = {"prefilter": "thesis-hp", "omega_min": omega_min, "omega_max": 30.0}
    tr = shs.estimate(Recording(t, {"ay": ay}), params=params)
    assert tr.params["batch"] == batch == shs.default_batch(1 / fs, params)[0]
    assert batch * (1 / fs) >= min(2.0, 2 * np.pi / omega_min) - 1e-12
    assert any("one period of omega_min" in n for n in tr.notes) == noted
    assert np.nanmax(np.abs(tr.omega - 20)) < 0.5
    # the default is the explicit batch, number for number
    same = shs.estimate(Recording(t, {"ay": ay}), params={**params, "batch": batch})
    np.testing.assert_array_equal(tr.omega, same.omega)
