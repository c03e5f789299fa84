"""The checkpointed grid smoother and Viterbi (forward state kept every K samples, segments
recomputed backwards) equal the whole-log passes bitwise."""

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.estimators import grid, rbpmf
from vibrospeed.estimators.grid import app
from vibrospeed.estimators.grid import smoother as gs
from vibrospeed.estimators.grid import viterbi as gv
from vibrospeed.models.harmonic import HarmonicModel

FIELDS = ("omega", "omega_std", "omega_map", "omega_lo", "omega_hi", "p_null", "p_half",
          "p_double", "p_third", "p_triple", "omega_mode", "p_mode")


def _emissions(n=900, seed=0):
    """Emissions of the RBPMF on a two-harmonic line that steps 30 -> 38 rad/s, with a gap,
    the "no line" state and jumps on (every transition term in play)."""
    model = HarmonicModel(M=2, dt=0.01, q_omega=4.0, q_amp=0.001, r=0.05, p0_amp=0.1)
    om = np.where(np.arange(n) < n // 2, 30.0, 38.0)
    y, _ = model.simulate(om, np.random.default_rng(seed), x0=np.tile([0.6, 0.0], 2))
    y[200:230] = np.nan
    cfg = rbpmf.Config(model=model, n_grid=30, omega_min=20.0, omega_max=50.0,
                       jump_rate=0.5, off_rate=0.2, on_rate=1.0)
    res = rbpmf.run(cfg, y, return_grid_loglik=True)
    assert res.grid_loglik.dtype == np.float32
    return cfg, res.grid_loglik


def same(a, b):
    assert a.dtype == b.dtype and a.shape == b.shape
    assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("K", [1, 7, 128, 899, 900, 5000])
def test_checkpointed_smoother_equals_whole_log(K):
    cfg, gll = _emissions()
    whole = gs.smooth(cfg, gll, return_posterior=True, checkpoint=None)
    part = gs.smooth(cfg, gll, return_posterior=True, checkpoint=K)
    for f in FIELDS:
        same(getattr(part, f), getattr(whole, f))
    same(part.posterior, whole.posterior)
    # the posterior is a distribution where the smoother says there is a line
    s = whole.posterior.sum(axis=1) + whole.p_null
    np.testing.assert_allclose(s, 1.0, atol=1e-5)


@pytest.mark.parametrize("K", [1, 5, 333, 900, None])
def test_checkpointed_viterbi_equals_whole_log(K):
    cfg, gll = _emissions(seed=1)
    whole = gv.viterbi(cfg, gll, checkpoint=None)
    part = gv.viterbi(cfg, gll, checkpoint=K)
    same(part.state, whole.state)
    same(part.omega, whole.omega)
    assert part.log_joint == whole.log_joint and np.isfinite(whole.log_joint)


def test_float32_emissions_are_not_copied_and_give_the_float64_numbers():
    cfg, gll = _emissions(seed=2)
    a = gs.smooth(cfg, gll, checkpoint=100)
    b = gs.smooth(cfg, gll.astype(np.float64), checkpoint=None)
    for f in FIELDS:
        same(getattr(a, f), getattr(b, f))
    same(gv.viterbi(cfg, gll).state, gv.viterbi(cfg, gll.astype(np.float64)).state)
    np.testing.assert_array_equal(gs.filtered(cfg, gll), gs.filtered(cfg, gll.astype(float)))


def test_fixed_lag_block_equals_smoothing_the_log_cut_at_the_block_horizon():
    cfg, gll = _emissions(seed=3)
    lag = 0.7
    L = int(round(lag / cfg.model.dt))
    fl = gs.fixed_lag(cfg, gll, lag=lag)
    n = gll.shape[0]
    for s0 in range(0, n, L):
        cut = gs.smooth(cfg, gll[: min(s0 + 2 * L, n)], checkpoint=None)
        for f in FIELDS:
            same(getattr(fl, f)[s0 : s0 + L], getattr(cut, f)[s0 : s0 + L])


def test_grid_estimate_on_a_short_drive_is_unchanged_by_the_checkpoints(monkeypatch):
    rec = sim.simulate("car", seed=1, duration=40)  # 4000 samples: several segments of 1000
    params = {"n_grid": 60}
    orig_s = gs.smooth
    monkeypatch.setattr(app.grid_smoother, "smooth",
                        lambda *a, **k: orig_s(*a, **{**k, "checkpoint": 1000}))
    part = grid.estimate(rec, axis="y", params=params)
    monkeypatch.setattr(app.grid_smoother, "smooth",
                        lambda *a, **k: orig_s(*a, **{**k, "checkpoint": None}))
    whole = grid.estimate(rec, axis="y", params=params)
    for f in ("omega", "omega_lo", "omega_hi", "omega_std", "speed"):
        same(getattr(part, f), getattr(whole, f))
    assert set(part.extras) == set(whole.extras)
    for k in whole.extras:
        same(np.asarray(part.extras[k]), np.asarray(whole.extras[k]))


def test_bad_checkpoint():
    cfg, gll = _emissions(n=50)
    with pytest.raises(ValueError, match="checkpoint"):
        gs.smooth(cfg, gll, checkpoint=0)
    with pytest.raises(ValueError, match="checkpoint"):
        gv.viterbi(cfg, gll, checkpoint=0)
