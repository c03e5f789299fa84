"""The whitener's compiled predictor against the scipy and numpy calls it reproduces.

``whiten.predictor`` and ``whiten.apply`` make the Welch median background, its running
median, the autocorrelation, Levinson's recursion and the gain without scipy's per-call
overhead; every number must be the one of ``predictor_reference`` (``scipy.signal.welch``,
``scipy.ndimage.median_filter``, ``numpy.fft.irfft``, ``scipy.linalg.solve_toeplitz``,
``scipy.signal.lfilter``) and of the block loop written with it. The one exception is the
gain's last bits: ``lfilter`` here is ``numpy.convolve``, whose short dot products go to the
machine's BLAS ``ddot`` kernel, which the compiled sum follows on FMA builds for Intel
(Haswell on); on other processors (AMD EPYC's kernel) the two differ by up to a few ulp, so the
gain, and the outputs scaled by it, are compared to :data:`GAIN_RTOL`.
"""

import numpy as np
import pytest

from vibrospeed.signal import _whiten_kernels as kern
from vibrospeed.signal import whiten as wh

#: relative difference allowed between the compiled gain and the BLAS-dependent reference's
GAIN_RTOL = 1e-13


def _history(rng, n):
    """Red body motion, a swept line, a white floor: the whitener's kind of input."""
    t = np.arange(n) / 100.0
    return (np.cumsum(rng.normal(size=n)) * 0.01
            + 0.05 * np.sin(2 * np.pi * (8.0 * t + 0.2 * t * t))
            + rng.normal(0.0, 10 ** rng.uniform(-3, 0), n))


def _apply_reference(x, fs):
    """The block loop of :func:`whiten.apply` in plain numpy with the scipy predictor."""
    x = np.asarray(x, dtype=np.float64)
    y = np.full_like(x, np.nan)
    fin = np.flatnonzero(np.isfinite(x))
    z = x[fin]
    W, B, _ = wh._sizes(fs)
    out = np.zeros(z.size)
    a = np.zeros(wh.ORDER + 1)
    a[0], gain = 1.0, 1.0
    for b0 in range(0, z.size, B):
        a_prev, gain_prev = a, gain
        a, gain = wh.predictor_reference(z[max(0, b0 - W) : b0], fs)
        for t in range(b0, min(b0 + B, z.size)):
            def fir(c, g, t=t):
                acc = 0.0
                for k in range(wh.ORDER + 1):
                    if t - k >= 0:
                        acc += c[k] * z[t - k]
                return g * acc
            new = fir(a, gain)
            if not (gain == gain_prev and np.array_equal(a, a_prev)):
                lam = ((t - b0) + 1.0) / B
                new = (1.0 - lam) * fir(a_prev, gain_prev) + lam * new
            out[t] = new
    y[fin] = out
    return y


@pytest.mark.parametrize("fs", [100.0, 400.0, 99.5, 37.3, 7.0, 6.0, 1.0])
def test_predictor_equals_scipy_bitwise(fs):
    rng = np.random.default_rng(int(fs * 10))
    W, _, seg = wh._sizes(fs)
    for n in sorted({0, seg - 1, seg, seg + 1, 3 * seg // 2, W // 2, W - 1, W, W + 37, 2 * W}):
        h = _history(rng, n)
        a, g = wh.predictor(h, fs)
        a_ref, g_ref = wh.predictor_reference(h, fs)
        np.testing.assert_array_equal(a, a_ref)
        assert g == pytest.approx(g_ref, rel=GAIN_RTOL, abs=0), (n, g, g_ref)


def test_predictor_degenerate_histories():
    ident = np.zeros(wh.ORDER + 1)
    ident[0] = 1.0
    for h in (np.zeros(500), np.ones(500), np.full(900, 3.0)):
        a, g = wh.predictor(h, 100.0)
        a_ref, g_ref = wh.predictor_reference(h, 100.0)
        np.testing.assert_array_equal(a, a_ref)
        assert g == pytest.approx(g_ref, rel=GAIN_RTOL, abs=0)
    np.testing.assert_array_equal(wh.predictor(np.zeros(500), 100.0)[0], ident)


def test_apply_equals_block_loop_reference_with_nans():
    rng = np.random.default_rng(7)
    x = _history(rng, 2600)
    x[700:730] = np.nan
    x[1500] = np.inf
    np.testing.assert_allclose(wh.apply(x, 100.0), _apply_reference(x, 100.0), rtol=GAIN_RTOL,
                               atol=0)


def test_apply_batches_change_nothing(monkeypatch):
    rng = np.random.default_rng(8)
    x = _history(rng, 4000)
    whole = wh.apply(x, 100.0)
    monkeypatch.setattr(wh, "BATCH", 3)
    np.testing.assert_array_equal(wh.apply(x, 100.0), whole)


def test_pairwise_sum_is_numpys():
    rng = np.random.default_rng(9)
    for n in [0, 1, 7, 8, 9, 127, 128, 129, 200, 257, 888, 1000, 4099]:
        x = rng.normal(size=n + 3) * 10 ** rng.uniform(-3, 3, n + 3)
        assert kern._pairwise(x, 3, n) == np.sum(x[3:])


@pytest.mark.parametrize("fs", [1.0, 6.0, 7.0])
def test_apply_at_low_rates_equals_the_reference(fs):
    """Segments shorter than the predictor (the autocorrelation has fewer than ORDER + 1 lags):
    the identity, as the scipy form."""
    rng = np.random.default_rng(int(fs))
    x = _history(rng, 400)
    x[[3, 50]] = 1000.0
    np.testing.assert_allclose(wh.apply(x, fs), _apply_reference(x, fs), rtol=GAIN_RTOL, atol=0)
