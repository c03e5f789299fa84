"""Algebraic differentiators: polynomial exactness, the seed's closed forms, delay, streaming."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.errors import ParameterError
from vibrospeed.signal import differentiation as d


def _poly_derivative(coef, n, t):
    """n-th derivative of sum_k coef[k] t^k at t (independent reference via numpy)."""
    return np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(coef, n))


@pytest.mark.parametrize(
    "n,N,kappa,mu,xi,L",
    [(0, 1, 0, 0, 0.0, 21), (1, 1, 0, 0, 0.0, 21), (1, 2, 1, 1, 0.3, 31),
     (2, 3, 0.5, -0.5, 0.0, 41),
     (0, 4, 2, 0, 0.5, 51), (3, 4, 0, 0, 0.2, 61), (1, 3, 0, 0, 0.5, 25)],
)
def test_exact_for_polynomials_up_to_degree_N(n, N, kappa, mu, xi, L):
    dt = 0.01
    cfg = d.Config(n=n, N=N, L=L, dt=dt, kappa=kappa, mu=mu, xi=xi)
    rng = np.random.default_rng(1)
    t = np.arange(200) * dt
    for deg in range(N + 1):
        coef = np.zeros(deg + 1)
        coef[:] = rng.normal(size=deg + 1)
        x = np.polynomial.polynomial.polyval(t, coef)
        _, y = d.run(cfg, x)
        ref = _poly_derivative(coef, n, t - cfg.delay)
        k = slice(L - 1, None)  # full windows only (the start is padded with x[0])
        scale = max(1.0, np.abs(ref[k]).max())
        np.testing.assert_allclose(y[k], ref[k], atol=1e-8 * scale * cfg.window ** -n)


def test_not_exact_beyond_degree_N():
    cfg = d.Config(n=1, N=1, L=21, dt=0.01)
    t = np.arange(100) * 0.01
    _, y = d.run(cfg, t**2)
    assert np.abs(y[30:] - 2 * t[30:]).max() > 1e-3


def test_paper_closed_form_kernels():
    """Seed section III, N = 1, nu = 2 on [0, T]:
    a0 = 2/T^2 (2T - 3 tau), a1 = -6/T^3 (T - 2 tau)."""
    assert d.paper_kappa_mu(1, 2) == (0.0, 0.0)
    kappa, mu = d.paper_kappa_mu(1, 2)
    T = 0.37
    u = np.linspace(0.0, T, 11)  # physical time in the window
    tau = u / T
    # x_hat^(n) = T^-n int_0^1 g(tau) x(tau T) dtau = int_0^T [g(u/T) / T^(n+1)] x(u) du
    k0 = d.jacobi_kernel(tau, 0, 1, kappa, mu, 0.0) / T
    k1 = d.jacobi_kernel(tau, 1, 1, kappa, mu, 0.0) / T**2
    np.testing.assert_allclose(k0, 2.0 / T**2 * (2 * T - 3 * u), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(k1, -math.factorial(3) / T**3 * (T - 2 * u), rtol=1e-12, atol=1e-9)


def test_discrete_kernel_converges_to_continuous():
    for n, N, kappa, mu, xi in [(0, 1, 0, 0, 0.0), (1, 1, 0, 0, 0.0), (1, 3, 1, 2, 0.25)]:
        L = 2001
        tau = np.arange(L) / (L - 1)
        h = d.fir_kernel(L, n, N, kappa, mu, xi) * (L - 1)
        g = d.jacobi_kernel(tau, n, N, kappa, mu, xi)
        inner = slice(1, -1)
        assert np.abs(h[inner] - g[inner]).max() < 1e-3 * np.abs(g).max()


@given(
    n=st.integers(0, 2), extra=st.integers(0, 2), kappa=st.floats(-0.5, 3), mu=st.floats(-0.5, 3),
    xi=st.floats(0, 1), L=st.integers(12, 60),
)
@settings(max_examples=40, deadline=None)
def test_kernel_reproduces_monomials(n, extra, kappa, mu, xi, L):
    N = n + extra
    h = d.fir_kernel(L, n, N, kappa, mu, xi)
    tau = np.arange(L) / (L - 1)
    for deg in range(N + 1):
        ref = math.factorial(deg) / math.factorial(deg - n) * xi ** (deg - n) if deg >= n else 0.0
        assert abs(h @ tau**deg - ref) < 1e-8 * max(1.0, np.abs(h).sum())


def test_exact_point_minimal_estimator_and_delay():
    # minimal estimator N = n: xi* = (mu + n + 1) / (kappa + mu + 2n + 2)
    for n, kappa, mu in [(0, 0, 0), (1, 0, 0), (1, 2, 1), (2, 0.5, 3)]:
        ref = (mu + n + 1) / (kappa + mu + 2 * n + 2)
        assert d.exact_point(n, n, kappa, mu) == pytest.approx(ref)
    # at xi*, the causal estimate is also exact for degree N + 1, delayed by xi* T_w
    xi = d.exact_point(1, 1)
    assert xi == pytest.approx(0.5)
    cfg = d.Config(n=1, N=1, L=41, dt=0.005, xi=xi)
    assert cfg.delay == pytest.approx(0.5 * 40 * 0.005)
    t = np.arange(300) * cfg.dt
    _, y = d.run(cfg, 3 * t**2 - t)
    np.testing.assert_allclose(y[40:], 6 * (t[40:] - cfg.delay) - 1, atol=1e-9)
    # measured lag of a slow sine matches the stated delay
    cfg0 = d.Config(n=0, N=0, L=41, dt=0.005, xi=d.exact_point(0, 0))
    x = np.sin(2 * np.pi * 0.5 * t)
    _, y0 = d.run(cfg0, x)
    lags = np.arange(0, 41)
    err = [np.abs(y0[100:] - np.sin(2 * np.pi * 0.5 * (t[100:] - k * cfg0.dt))).max() for k in lags]
    assert lags[int(np.argmin(err))] * cfg0.dt == pytest.approx(cfg0.delay)


def test_run_equals_step_and_batch():
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.normal(size=300))
    cfg = d.Config(n=1, N=2, L=25, dt=0.01)
    _, y_run = d.run(cfg, x)
    st_ = d.init(cfg)
    taps = cfg.taps()
    y_step = []
    for v in x:
        st_, y = d.step(cfg, st_, v, taps)
        y_step.append(y)
    np.testing.assert_array_equal(y_run, np.array(y_step))
    np.testing.assert_allclose(d.apply(cfg, x), y_run, rtol=1e-12, atol=1e-9)
    # chunked equals whole
    s1, a = d.run(cfg, x[:137])
    _, b = d.run(cfg, x[137:], s1)
    np.testing.assert_array_equal(np.concatenate([a, b]), y_run)


def test_centred_mode_aligns_output():
    cfg_c = d.Config(n=1, N=2, L=21, dt=0.01, xi=0.5, mode="centred")
    cfg_k = d.Config(n=1, N=2, L=21, dt=0.01, xi=0.5)
    t = np.arange(200) * 0.01
    x = np.sin(3 * t)
    yc = d.apply(cfg_c, x)
    yk = d.apply(cfg_k, x)
    np.testing.assert_array_equal(yc[: 200 - 10], yk[10:])
    assert np.isnan(yc[-10:]).all()
    assert cfg_c.delay == 0.0
    err = np.abs(yc[20:-10] - 3 * np.cos(3 * t[20:-10])).max()
    assert err < 0.04  # O(T_w^2 x^(3)) truncation of the symmetric window
    assert err < 0.1 * np.abs(yk[20:-10] - 3 * np.cos(3 * t[20:-10])).max()  # causal: lag
    with pytest.raises(ParameterError, match="integer"):
        d.Config(L=20, xi=0.5, mode="centred")


def test_nan_gives_nan_and_keeps_state():
    cfg = d.Config(n=0, N=1, L=5, dt=0.1)
    x = np.array([1.0, 1.0, np.nan, 1.0, 1.0])
    _, y = d.run(cfg, x)
    assert np.isnan(y[2]) and np.allclose(y[[0, 1, 3, 4]], 1.0)


def test_noise_attenuation_matches_kernel_norm():
    cfg = d.Config(n=0, N=1, L=51, dt=0.01)
    rng = np.random.default_rng(7)
    x = rng.normal(size=200_000)
    y = d.apply(cfg, x)[100:]
    g = d.noise_gain(cfg)
    assert np.std(y) == pytest.approx(g, rel=0.02)
    # the seed's N = 1 value kernel has continuous gain sqrt(4 / L): 4 = int_0^1 (4 - 6 tau)^2
    assert g == pytest.approx(np.sqrt(4.0 / 50), rel=0.05)


def test_bad_parameters():
    with pytest.raises(ParameterError):
        d.Config(n=2, N=1)
    with pytest.raises(ParameterError):
        d.Config(L=2, N=3)
    with pytest.raises(ParameterError):
        d.Config(kappa=-1.0)
    with pytest.raises(ParameterError):
        d.Config(xi=1.5)
    with pytest.raises(ParameterError):
        d.paper_kappa_mu(1, 1)
