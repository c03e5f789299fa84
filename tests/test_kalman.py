"""Stacked Kalman primitives: compiled kernels vs NumPy references vs a loop of single filters."""

import numpy as np
import pytest

from vibrospeed.estimators import kalman
from vibrospeed.models.harmonic import HarmonicModel


def _random_spd(rng, N, n):
    A = rng.normal(size=(N, n, n))
    return A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(n)


def test_rotation_blocks_equal_model_F():
    model = HarmonicModel(M=4, dt=0.01)
    om = np.array([0.0, 13.3, 97.0, 250.0])
    out = np.empty((om.size, 4, 2, 2))
    kalman.rotation_blocks(om, 4, 0.01, out)
    np.testing.assert_array_equal(out, kalman.blocks_from_F(model.F(om)))


def test_predict_blocks_equals_dense_reference():
    rng = np.random.default_rng(0)
    model = HarmonicModel(M=3, dt=0.01)
    N, n = 7, 6
    m = rng.normal(size=(N, n))
    P = _random_spd(rng, N, n)
    om = rng.uniform(10, 120, N)
    F = model.F(om)
    m_ref, P_ref = kalman.predict(m, P, F, model.Q_lin)
    m2, P2 = m.copy(), P.copy()
    kalman.predict_blocks(m2, P2, kalman.blocks_from_F(F), model.Q_lin)
    np.testing.assert_allclose(m2, m_ref, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(P2, P_ref, rtol=1e-12, atol=1e-13)
    assert np.array_equal(P2, np.swapaxes(P2, 1, 2))


def test_update_scalar_equals_reference_and_loop():
    rng = np.random.default_rng(1)
    model = HarmonicModel(M=3)
    N, n = 5, 6
    m = rng.normal(size=(N, n))
    P = _random_spd(rng, N, n)
    y, r = 0.7, 0.05
    m_ref, P_ref, ll_ref, nu, S = kalman.update(m, P, model.H, r, y)
    # independent: joint Gaussian conditioning with explicit inverse
    for k in range(N):
        h = model.H
        S_k = h @ P[k] @ h + r
        K = P[k] @ h / S_k
        np.testing.assert_allclose(m_ref[k], m[k] + K * (y - h @ m[k]), rtol=1e-12)
        np.testing.assert_allclose(P_ref[k], (np.eye(n) - np.outer(K, h)) @ P[k], atol=1e-12)
        np.testing.assert_allclose(
            ll_ref[k], -0.5 * np.log(2 * np.pi * S_k) - 0.5 * (y - h @ m[k]) ** 2 / S_k
        )
    m2, P2, ll2 = m.copy(), P.copy(), np.empty(N)
    kalman.update_scalar(m2, P2, model.H, r, y, ll2)
    np.testing.assert_allclose(m2, m_ref, rtol=1e-13)
    np.testing.assert_allclose(P2, P_ref, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ll2, ll_ref, rtol=1e-13)


def test_nan_measurement_is_prediction_only():
    rng = np.random.default_rng(2)
    m = rng.normal(size=(3, 4))
    P = _random_spd(rng, 3, 4)
    m2, P2, ll = m.copy(), P.copy(), np.empty(3)
    kalman.update_scalar(m2, P2, np.array([1.0, 0, 1, 0]), 0.1, np.nan, ll)
    assert np.array_equal(m2, m) and np.array_equal(P2, P) and np.all(ll == 0)


@pytest.mark.parametrize("seed", [3, 4])
def test_kalman_filter_consistent_on_model_data(seed):
    """A KF at the true omega on data drawn from the model: normalised innovations ~ N(0, 1)."""
    rng = np.random.default_rng(seed)
    model = HarmonicModel(M=2, dt=0.01, q_amp=0.01, r=0.05, p0_amp=0.1)
    y, _ = model.simulate(np.full(4000, 40.0), rng)
    m = np.zeros((1, 4))
    P = np.eye(4)[None] * model.p0_amp
    B = kalman.blocks_from_F(model.F(np.array([40.0])))
    ph = np.empty(4)
    z = []
    for v in y:
        _, nu, S = kalman.update_one(m[0], P[0], model.H, model.r, v, ph)
        z.append(nu / np.sqrt(S))
        kalman.predict_blocks(m, P, B, model.Q_lin)
    z = np.array(z[100:])
    assert abs(np.mean(z)) < 0.1
    assert 0.9 < np.var(z) < 1.1


def _spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


@pytest.mark.parametrize("n", [2, 5, 7])
def test_dense_predict_equals_numpy(n):
    rng = np.random.default_rng(n)
    x, P, F, qd = rng.normal(size=n), _spd(rng, n), rng.normal(size=(n, n)), rng.random(n)
    xr, Pr = F @ x, F @ P @ F.T + np.diag(qd)
    kalman.dense_predict(x, P, F, qd)
    np.testing.assert_allclose(x, xr, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(P, Pr, rtol=1e-12, atol=1e-10)
    assert np.array_equal(P, P.T)


@pytest.mark.parametrize("keep", [(-1, -1), (2, -1), (0, 3)])
def test_row_update_is_the_joseph_form(keep):
    """Against the textbook Joseph form in NumPy; with the optimal gain it equals the short
    form ``P - P h' h P / S``; a kept ("consider") state keeps its mean and variance."""
    rng = np.random.default_rng(7)
    n = 6
    x, P, h = rng.normal(size=n), _spd(rng, n), rng.normal(size=n)
    z, r = 0.7, 0.3
    S = h @ P @ h + r
    k = P @ h / S
    for i in keep:
        if i >= 0:
            k[i] = 0.0
    A = np.eye(n) - np.outer(k, h)
    Pr = A @ P @ A.T + r * np.outer(k, k)
    xr = x + k * (z - h @ x)
    x1, P1 = x.copy(), P.copy()
    nu = kalman.row_update(x1, P1, h, z, r, *keep)
    assert nu == pytest.approx(z - h @ x, rel=1e-13)
    np.testing.assert_allclose(x1, xr, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(P1, Pr, rtol=1e-11, atol=1e-11)
    assert np.array_equal(P1, P1.T)
    if keep == (-1, -1):
        np.testing.assert_allclose(P1, P - np.outer(P @ h, P @ h) / S, rtol=1e-10, atol=1e-10)
    for i in keep:
        if i >= 0:
            assert x1[i] == x[i] and P1[i, i] == pytest.approx(P[i, i], rel=1e-12)
