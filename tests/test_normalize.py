"""Running-RMS normalisation: scale invariance and convergence to unit power."""

import numpy as np

from vibrospeed.signal.normalize import running_rms_normalize


def test_scale_invariant_and_unit_power():
    rng = np.random.default_rng(0)
    x = rng.normal(size=5000)
    a = running_rms_normalize(x, 0.01, 5.0)
    b = running_rms_normalize(1e-3 * x, 0.01, 5.0)
    np.testing.assert_allclose(a, b, rtol=1e-9)
    assert abs(np.mean(a[1000:] ** 2) - 1.0) < 0.1


def test_nan_passes_and_is_causal():
    x = np.sin(np.arange(2000) * 0.3)
    x[100:120] = np.nan
    y = running_rms_normalize(x, 0.01, 2.0)
    assert np.all(np.isnan(y[100:120])) and np.all(np.isfinite(y[120:]))
    y2 = running_rms_normalize(np.concatenate([x[:1500], np.full(500, 100.0)]), 0.01, 2.0)
    np.testing.assert_array_equal(y[:1500], y2[:1500])  # the future does not change the past
