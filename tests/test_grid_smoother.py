"""Grid smoother (issue 7): forward pass = filter, forward-backward and Viterbi vs brute force,
fixed lag vs truncated smoothing, and the smoother's gain on a frequency step."""

import dataclasses
import itertools

import numpy as np

from mode_reference import check_mode
from vibrospeed.estimators import grid_smoother as gs
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.grid.filter import tables
from vibrospeed.models.harmonic import HarmonicModel


def _cfg(n_grid=30, **kw):
    model = HarmonicModel(M=2, dt=0.01, q_omega=4.0, q_amp=0.001, r=0.05, p0_amp=0.1)
    return rbpmf.Config(model=model, n_grid=n_grid, omega_min=20.0, omega_max=50.0, **kw)


def _signal(n=600, seed=0):
    model = HarmonicModel(M=2, dt=0.01, q_omega=4.0, q_amp=0.001, r=0.05, p0_amp=0.1)
    om = np.where(np.arange(n) < n // 2, 30.0, 38.0)
    y, _ = model.simulate(om, np.random.default_rng(seed), x0=np.tile([0.6, 0.0], 2))
    return om, y


def _dense_T(cfg):
    """Full (N+1) x (N+1) transition matrix built independently from the exact kernel rows."""
    k = cfg.kern
    N = k.grid.size
    eps, p_off, p_on, _ = cfg.rates()
    u = k.widths / k.widths.sum()
    K = np.zeros((N, N))
    for j in range(N):
        for d in range(2 * k.B + 1):
            i = j + d - k.B
            if 0 <= i < N:
                K[i, j] = k.kb[j, d]
    T = np.zeros((N + 1, N + 1))
    T[:N, :N] = (1 - eps - p_off) * K + eps * u[None, :]
    T[:N, N] = p_off
    T[N, :N] = p_on * u
    T[N, N] = 1 - p_on
    return T


def _prior(cfg):
    st = rbpmf.init(cfg)
    return np.exp(np.append(st.log_w, st.log_w_null))


def test_forward_pass_reproduces_filter_weights():
    _, y = _signal()
    y[100:105] = np.nan
    cfg = _cfg(jump_rate=0.5, off_rate=0.2, on_rate=1.0)
    res = rbpmf.run(cfg, y, return_posterior=True, return_grid_loglik=True)
    alpha = gs.filtered(cfg, res.grid_loglik)
    np.testing.assert_allclose(alpha[:, :-1], res.posterior, atol=2e-5)
    np.testing.assert_allclose(alpha[:, -1], res.p_null, atol=2e-5)


def test_forward_backward_equals_dense_hmm():
    _, y = _signal(n=300, seed=1)
    cfg = _cfg(n_grid=20, jump_rate=0.5, off_rate=0.2, on_rate=1.0)
    res = rbpmf.run(cfg, y, return_grid_loglik=True)
    L = np.exp(res.grid_loglik.astype(np.float64))
    T = _dense_T(cfg)
    n = L.shape[0]
    a = np.empty_like(L)
    prev = _prior(cfg)
    for t in range(n):
        x = prev * L[t]
        a[t] = x / x.sum()
        prev = a[t] @ T
    b = np.ones_like(L)
    for t in range(n - 2, -1, -1):
        x = T @ (L[t + 1] * b[t + 1])
        b[t] = x / x.max()
    g = a * b
    g /= g.sum(axis=1, keepdims=True)
    sm = gs.smooth(cfg, res.grid_loglik, return_posterior=True)
    np.testing.assert_allclose(sm.posterior, g[:, :-1], atol=1e-5)
    np.testing.assert_allclose(sm.p_null, g[:, -1], atol=1e-5)
    grid = cfg.grid
    mean_sig = (g[:, :-1] @ grid) / g[:, :-1].sum(axis=1)
    np.testing.assert_allclose(sm.omega, mean_sig, atol=1e-3)


def test_viterbi_equals_brute_force():
    rng = np.random.default_rng(2)
    cfg = dataclasses.replace(_cfg(n_grid=4, jump_rate=2.0, off_rate=5.0, on_rate=8.0),
                              kernel="exact")
    n = 5
    gll = rng.normal(0, 2, size=(n, 5)).astype(np.float32)
    lT = np.log(_dense_T(cfg))
    lp = np.log(_prior(cfg))
    best, arg = -np.inf, None
    for path in itertools.product(range(5), repeat=n):
        v = lp[path[0]] + gll[0, path[0]] + sum(
            lT[path[t - 1], path[t]] + gll[t, path[t]] for t in range(1, n))
        if v > best:
            best, arg = v, path
    vit = gs.viterbi(cfg, gll)
    assert tuple(vit.state) == arg
    assert abs(vit.log_joint - best) < 1e-4
    assert np.isnan(vit.omega[vit.state == 4]).all()


def test_grid_estimate_omega_map_follows_a_claimed_line():
    from vibrospeed import sim
    from vibrospeed.estimators import grid

    rec = sim.simulate("cart", seed=1, duration=30)
    tr = grid.estimate(rec, params={"omega_min": 2, "omega_max": 30})
    om = tr.extras["omega_map"]
    hs = tr.extras["has_signal"] > 0.5
    assert hs.mean() > 0.4
    assert np.isfinite(om).all()
    truth = rec["omega_true"]
    assert np.mean(np.abs(om[hs] - truth[hs]) <= np.maximum(0.1 * truth[hs], 0.4)) > 0.9


def test_fixed_lag_equals_smoother_on_truncated_data():
    _, y = _signal(n=500, seed=3)
    cfg = _cfg(jump_rate=0.2)
    res = rbpmf.run(cfg, y, return_grid_loglik=True)
    lag = 1.0  # 100 samples: block 0 uses samples 0..199
    fl = gs.fixed_lag(cfg, res.grid_loglik, lag=lag)
    tr = gs.smooth(cfg, res.grid_loglik[:200])
    np.testing.assert_allclose(fl.omega[:100], tr.omega[:100], atol=1e-9)
    whole = gs.fixed_lag(cfg, res.grid_loglik, lag=10.0)
    np.testing.assert_allclose(whole.omega, gs.smooth(cfg, res.grid_loglik).omega, atol=1e-9)


def test_smoother_beats_filter_on_a_step():
    om, y = _signal(n=800, seed=4)
    cfg = _cfg(n_grid=60)
    res = rbpmf.run(cfg, y, return_grid_loglik=True)
    sm = gs.smooth(cfg, res.grid_loglik)
    vit = gs.viterbi(cfg, res.grid_loglik)
    sl = slice(380, 480)  # just after the step 30 -> 38 at sample 400
    ef = np.mean(np.abs(res.omega[sl] - om[sl]))
    es = np.mean(np.abs(sm.omega[sl] - om[sl]))
    assert es < 0.7 * ef
    assert np.mean(np.abs(vit.omega[100:] - om[100:]) < 1.5) > 0.95
    assert np.all(sm.omega_lo <= sm.omega) and np.all(sm.omega <= sm.omega_hi)


def test_estimate_smooth_and_lag_columns():
    from vibrospeed.types import Recording

    t = np.arange(0, 12, 0.01)
    rng = np.random.default_rng(5)
    ay = np.sin(60 * t) + 0.6 * np.sin(120 * t + 1) + 0.3 * rng.normal(size=t.size)
    ay[t > 8] = rng.normal(size=(t > 8).sum())  # the line stops: no signal
    for mode in ("fb", "lag"):
        tr = rbpmf.estimate(Recording(t, {"ay": ay}), params={"improved": "true", "smooth": mode})
        ex = tr.extras
        for k in ("confidence", "has_signal", "p_half", "p_double", "omega_map"):
            assert ex[k].shape == t.shape
        assert np.all(ex["has_signal"][(t > 2) & (t < 7)] == 1.0)
        assert np.mean(ex["has_signal"][t > 9.5]) < 0.2
        assert np.median(tr.omega_hi[t > 9.5] - tr.omega_lo[t > 9.5]) > 50  # band widened
        assert abs(np.median(tr.omega[(t > 2) & (t < 7)]) - 60) < 1


def test_smoothed_mode_is_the_highest_mass_window_of_the_smoothed_posterior():
    cfg = _cfg()
    _, y = _signal(n=300, seed=4)
    res = rbpmf.run(cfg, y, return_grid_loglik=True)
    sm = gs.smooth(cfg, res.grid_loglik, return_posterior=True)
    g = cfg.grid
    for k in range(20, 300, 7):  # the posterior comes back as float32: loose tolerances
        check_mode(sm.posterior[k], g, cfg.amb_rel, cfg.amb_abs, sm.omega_mode[k],
                   sm.p_mode[k], tables(cfg).u, tol=1e-4)
    # a peaked, unimodal smoothed posterior: mode mean = mean
    one = (sm.p_mode > 1 - 1e-9) & (sm.omega_std < 0.25)
    assert one.sum() > 100
    np.testing.assert_allclose(sm.omega_mode[one], sm.omega[one], atol=0.02)
