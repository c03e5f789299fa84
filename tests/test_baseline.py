"""The STFT harmonic-sum baseline (:mod:`vibrospeed.eval.baseline`)."""

import numpy as np

from vibrospeed.eval.baseline import stft_harmonic_sum


def test_finds_a_comb_and_its_causal_version_lags_by_half_a_window():
    dt = 0.01
    t = np.arange(0, 30, dt)
    om = np.where(t < 15, 40.0, 60.0)
    th = np.cumsum(om) * dt
    rng = np.random.default_rng(0)
    y = np.cos(th) + 0.6 * np.cos(2 * th) + 0.3 * np.cos(3 * th) + 0.3 * rng.normal(size=t.size)
    off = stft_harmonic_sum(y, dt, 10.0, 120.0)
    cau = stft_harmonic_sum(y, dt, 10.0, 120.0, causal=True)
    spacing = 110.0 / 299
    for est in (off, cau):
        assert np.all(np.abs(est[(t > 3) & (t < 13)] - 40.0) <= spacing)
        assert np.all(np.abs(est[t > 18.5] - 60.0) <= spacing)
    assert np.isnan(cau[: 299]).all() and np.isfinite(off).all()
    # the causal change comes ~1.5 s after the offline one (a window's half)
    t_off = t[np.argmax(off > 50)]
    t_cau = t[np.argmax(cau > 50)]
    assert 1.0 < t_cau - t_off < 2.0


def test_aliased_harmonics_are_folded():
    dt = 1 / 50.0  # Nyquist 157 rad/s: the 2nd and 3rd harmonics of 70 rad/s alias
    t = np.arange(0, 20, dt)
    th = 70.0 * t
    y = np.cos(th) + np.cos(2 * th) + np.cos(3 * th)
    est = stft_harmonic_sum(y, dt, 10.0, 120.0)
    assert abs(np.median(est) - 70.0) < 0.5


def test_short_input_is_nan():
    assert np.isnan(stft_harmonic_sum(np.zeros(100), 0.01, 10.0, 120.0)).all()
