"""RBPF (paper III-C): degenerate known case, step == run, seeding, convergence."""

import numpy as np
import pytest

from vibrospeed.estimators import rbpf, rbpmf
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Recording


def _signal(seed=0, n=400, omega=30.0, M=2, q_omega=4.0):
    model = HarmonicModel(M=M, dt=0.01, q_omega=q_omega, q_amp=0.001, r=0.05, p0_amp=0.1)
    y, _ = model.simulate(np.full(n, omega), np.random.default_rng(seed),
                          x0=np.tile([0.6, 0.0], M))
    return model, y


def test_particles_on_grid_without_noise_or_resampling_equal_rbpmf():
    """Degenerate case: q_omega = 0, one particle per grid point, never resample -> a bank of
    Kalman filters weighted by their likelihoods, which is the RBPMF with an identity kernel."""
    model, y = _signal(q_omega=0.0)
    grid_cfg = rbpmf.Config(model=model, n_grid=25, omega_min=20.0, omega_max=44.0)
    pf_cfg = rbpf.Config(model=model, n_particles=25, omega_min=20.0, omega_max=44.0,
                         ess_threshold=0.0)
    st = rbpf.init(pf_cfg, np.random.default_rng(1), particles=grid_cfg.grid)
    res_pf = rbpf.run(pf_cfg, y, st)
    res_pm = rbpmf.run(grid_cfg, y)
    assert not res_pf.resampled.any()
    np.testing.assert_array_equal(res_pf.final.omega, grid_cfg.grid)
    # the RBPMF floors log-weights at 600 nats below the best point; the RBPF does not
    live = res_pm.final.log_w > -500
    assert live.sum() >= 1
    np.testing.assert_allclose(res_pf.final.log_w[live], res_pm.final.log_w[live], atol=1e-9)
    np.testing.assert_allclose(np.exp(res_pf.final.log_w), np.exp(res_pm.final.log_w), atol=1e-12)
    np.testing.assert_allclose(res_pf.final.mean, res_pm.final.mean, atol=1e-10)
    np.testing.assert_allclose(res_pf.omega, res_pm.omega, atol=1e-9)
    assert abs(res_pf.omega[-1] - 30.0) < 0.6


def test_step_equals_run_and_seeded():
    model, y = _signal(seed=2, n=120)
    y[30:33] = np.nan
    cfg = rbpf.Config(model=model, n_particles=200, omega_min=10.0, omega_max=60.0,
                      scheme="systematic", seed=7)
    res = rbpf.run(cfg, y)
    st = rbpf.init(cfg)
    for k, v in enumerate(y):
        st, est = rbpf.step(cfg, st, v)
        assert est.omega == res.omega[k] and est.ess == res.ess[k]
        assert est.resampled == res.resampled[k]
    assert np.array_equal(st.omega, res.final.omega)
    # the state's generator is copied, not drawn from: the same state gives the same numbers
    again = rbpf.run(cfg, y, rbpf.init(cfg, np.random.default_rng(7)))
    assert np.array_equal(again.omega, res.omega)
    assert np.array_equal(rbpf.run(cfg, y[:5], st).omega, rbpf.run(cfg, y[:5], st).omega)
    other = rbpf.run(cfg, y, rbpf.init(cfg, np.random.default_rng(8)))
    assert not np.array_equal(other.omega, res.omega)
    assert res.resampled.any()


def test_many_particles_approach_rbpmf():
    model, y = _signal(seed=3, n=500)
    pm = rbpmf.run(rbpmf.Config(model=model, n_grid=201, omega_min=20.0, omega_max=45.0), y)
    pf = rbpf.run(rbpf.Config(model=model, n_particles=2000, omega_min=20.0, omega_max=45.0,
                              scheme="systematic", seed=4), y)
    assert np.sqrt(np.mean((pf.omega[200:] - pm.omega[200:]) ** 2)) < 0.3
    assert np.all(pf.omega_lo[200:] <= pf.omega_hi[200:])


def test_estimate_runs_and_records_seed():
    t = np.arange(0, 6, 0.01)
    ay = np.sin(40 * t) + 0.5 * np.sin(80 * t) + 0.2 * np.random.default_rng(0).normal(size=t.size)
    tr = rbpf.estimate(Recording(t, {"ay": ay}), params={"n_particles": 300, "seed": 3})
    assert tr.params["seed"] == 3 and tr.method == "rbpf"
    assert np.all(np.isfinite(tr.omega)) and tr.extras["ess"].max() <= 300 + 1e-9


def test_estimate_in_chunks_with_progress_equals_one_run():
    from vibrospeed.estimators import common, rbpf
    from vibrospeed.types import Recording

    t = np.arange(1200) / 100.0
    rec = Recording(t, {"ay": np.cos(40.0 * t) + 0.5 * np.cos(80.0 * t)})
    params = {"n_particles": 200, "seed": 3}
    whole = rbpf.estimate(rec, params=params)
    orig = common.run_in_chunks
    common.run_in_chunks = lambda fn, n, **kw: orig(fn, n, **{**kw, "chunk": 500})
    try:
        chunked = rbpf.estimate(rec, params=params, progress=True)
    finally:
        common.run_in_chunks = orig
    np.testing.assert_array_equal(chunked.omega, whole.omega)
    np.testing.assert_array_equal(chunked.extras["ess"], whole.extras["ess"])


def _weighted_band(om, w, q):
    """Plain-python reference: the smallest particles whose cumulative weight reaches q and 1 -
    q (particles in increasing omega)."""
    pairs = sorted(zip(om, w, strict=True))
    acc, lo, hi = 0.0, None, None
    for o, wi in pairs:
        acc += wi
        if lo is None and acc >= q:
            lo = o
        if hi is None and acc >= 1 - q:
            hi = o
    return lo, hi


def test_band_holds_the_mean_when_one_particle_carries_the_weight():
    """ESS ~ 1: one particle holds 98.5 % of the weight, so both quantiles of the level-0.98
    band are that particle while the weighted mean lies above it; the band is widened to the
    mean, and where the quantiles hold the mean it is theirs (a plain weighted-quantile loop)."""
    model = HarmonicModel(dt=0.01, M=2, q_omega=4.0, q_amp=0.01, r=0.1, p0_amp=1.0)
    n = model.n_lin
    for w in ([0.005, 0.985, 0.006, 0.004], [0.2, 0.3, 0.25, 0.25]):
        om = np.array([98.2, 99.063, 100.5, 101.0])
        lw = np.log(np.array(w))
        mean, cov = np.zeros((4, n)), np.broadcast_to(np.eye(n), (4, n, n)).copy()
        out = np.empty(6)
        rbpf._measure(om, lw, mean, cov, np.nan, model.H, model.r, 0.01, 0.99, np.empty(4), out)
        mu = float(np.dot(w, om))
        lo, hi = _weighted_band(om, w, 0.01)
        assert out[0] == pytest.approx(mu, rel=1e-14)
        assert out[2] == pytest.approx(min(lo, mu), rel=1e-14)
        assert out[3] == pytest.approx(max(hi, mu), rel=1e-14)
        assert out[2] <= out[0] <= out[3]
    assert lo == 98.2 and hi == 101.0  # the spread weights: the quantiles, not widened


def test_band_holds_omega_on_a_cart_drive():
    """cart seed 4, 100 particles: at t = 0.17 s the band was 99.063-99.063 with omega 99.077."""
    from vibrospeed import sim

    rec = sim.simulate("cart", seed=4, duration=20)
    tr = rbpf.estimate(rec, params={"n_particles": 100})
    assert np.all(tr.omega_lo <= tr.omega) and np.all(tr.omega <= tr.omega_hi)
