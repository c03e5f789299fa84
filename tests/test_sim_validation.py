"""Thesis eq. 2.6 validation signal: amplitudes, frequencies, noise variances, scenario wrapper."""

from __future__ import annotations

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.sim import simulate, validation_signal
from vibrospeed.sim.validation import W0


def _ls(t, y, omega, M=3):
    cols = [np.ones_like(t)]
    for m in range(1, M + 1):
        cols += [np.cos(m * omega * t), np.sin(m * omega * t)]
    X = np.stack(cols, axis=1)
    c = np.linalg.lstsq(X, y, rcond=None)[0]
    return np.hypot(c[1::2], c[2::2]), y - X @ c


def test_w0_is_thesis_value():
    assert W0 == pytest.approx(9.11, abs=0.005)


@pytest.mark.parametrize("shared", [True, False])
def test_least_squares_amplitudes(shared):
    """Mean amplitude per harmonic ~ A_n E[cos e2] = (0.5, 0.6, 0.7) exp(-0.005)."""
    t, y = validation_signal(60_000, np.random.default_rng(3), shared_noise=shared)
    amps, _ = _ls(t, y, W0)
    np.testing.assert_allclose(amps, np.array([0.5, 0.6, 0.7]) * np.exp(-0.005), atol=0.006)


def test_residual_variance_matches_noise_variances():
    """Independent draws: var(residual) = sum_n [A_n^2 (1 - c^2) + s1^2] / 2 + var(e3).

    c = E cos e2 = exp(-0.01/2), s1^2 = 0.2^2 / 3 (uniform); a std/variance mix-up fails this.
    """
    t, y = validation_signal(60_000, np.random.default_rng(4), shared_noise=False)
    _, res = _ls(t, y, W0)
    A = np.array([0.5, 0.6, 0.7])
    c = np.exp(-0.005)
    expected = np.sum(A**2 * (1 - c**2) + 0.2**2 / 3) / 2 + 0.04
    assert res.var() == pytest.approx(expected, rel=0.03)


def test_spectrum_peaks_at_thesis_frequencies():
    t, y = validation_signal(10_000, np.random.default_rng(0))
    spec = np.abs(np.fft.rfft(y))
    f = np.fft.rfftfreq(y.size, 0.01)
    top3 = np.sort(f[np.argsort(spec)[-3:]])
    np.testing.assert_allclose(top3, [1.45, 2.9, 4.35], atol=f[1])


def test_scenario_wraps_signal():
    rec = simulate("validation", seed=5, duration=30.0)
    _, y = validation_signal(3000, np.random.default_rng(5))
    np.testing.assert_array_equal(rec["ay"], y)
    assert np.all(rec["omega_true"] == W0)
    np.testing.assert_allclose(rec["speed_true"], rec.wheel_radius * W0)
    assert rec.meta["config"]["amplitudes"] == (0.5, 0.6, 0.7)


def test_bad_arguments():
    with pytest.raises(ParameterError, match="positive integer"):
        validation_signal(0, np.random.default_rng(0))
    with pytest.raises(ParameterError, match="no GPS"):
        simulate("validation", gps_model=lambda t, v, r: (v, v))
