"""Marginal-likelihood fit of the RBPMF noise parameters (issue 7, part 3)."""

import dataclasses

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import fit, rbpmf
from vibrospeed.models.harmonic import HarmonicModel


def _data(r=0.02, q_amp=0.004, n=1500, seed=0):
    model = HarmonicModel(M=2, dt=0.01, q_omega=4.0, q_amp=q_amp, r=r, p0_amp=0.1)
    rng = np.random.default_rng(seed)
    om = 35.0 + np.cumsum(rng.normal(0, 0.2, n))
    y, _ = model.simulate(om, rng, x0=np.tile([0.5, 0.0], 2))
    return model, y


def test_fit_recovers_noise_levels_and_improves_likelihood():
    model, y = _data()
    start = dataclasses.replace(model, r=0.2, q_amp=0.0005)  # 10x and 1/8 of the truth
    cfg = rbpmf.Config(model=start, n_grid=40, omega_min=25.0, omega_max=45.0)
    fr = fit.fit(cfg, y, names=["r", "q_amp"], factor=2.0, min_factor=1.2)
    assert fr.loglik > fr.start_loglik + 50
    assert 0.02 / 1.6 < fr.values["r"] < 0.02 * 1.6
    assert 0.004 / 3 < fr.values["q_amp"] < 0.004 * 3
    # the optimum is a local maximum of the independent profile
    prof = fit.profile(fr.config, y, "r", fr.values["r"] * np.array([0.7, 1.0, 1.4]))
    assert prof[1] >= prof[0] and prof[1] >= prof[2]
    assert fr.loglik == pytest.approx(fit.loglik(fr.config, y))


def test_fit_through_estimate_and_errors():
    from vibrospeed.types import Recording

    t = np.arange(0, 8, 0.01)
    ay = np.sin(50 * t) + 0.4 * np.random.default_rng(1).normal(size=t.size)
    tr = rbpmf.estimate(Recording(t, {"ay": ay}), params={"fit": "r", "n_grid": 60})
    assert any("fitted by marginal likelihood" in n for n in tr.notes)
    assert tr.params["r"] != rbpmf.DEFAULT_R
    with pytest.raises(ParameterError, match="fit"):
        rbpmf.Config(fit="q_bogus")
    with pytest.raises(ParameterError, match="unknown"):
        fit.fit(rbpmf.Config(n_grid=5), np.zeros(10), names=["x"])


def test_fit_stays_within_its_span_and_warns_at_the_limit():
    model, y = _data()
    start = dataclasses.replace(model, r=0.2, q_amp=0.0005)  # r's optimum is 10x below
    cfg = rbpmf.Config(model=start, n_grid=40, omega_min=25.0, omega_max=45.0)
    fr = fit.fit(cfg, y, names=["r"], factor=2.0, min_factor=1.2, span=2.0)
    assert fr.values["r"] == pytest.approx(0.1)  # the limit start / span
    assert len(fr.warnings) == 1 and "search limit" in fr.warnings[0]
    free = fit.fit(cfg, y, names=["r"], factor=2.0, min_factor=1.2)
    assert free.warnings == [] and free.values["r"] < 0.05


def test_grid_smoother_fits_with_the_causal_filters_evidence():
    from vibrospeed.estimators import grid
    from vibrospeed.types import Recording

    t = np.arange(0, 12, 0.01)
    rng = np.random.default_rng(2)
    ay = np.sin(50 * t) + 0.5 * np.sin(100 * t) + 0.4 * rng.normal(size=t.size)
    rec = Recording(t, {"ay": ay})
    p = {"fit": "r", "n_grid": 60, "omega_min": 20.0, "omega_max": 80.0}
    tr = grid.estimate(rec, params={**p, "smooth": "fb"})
    cfg, y, _, _ = grid._prepare(rec, "y", {**p, "smooth": "none"})
    ref = fit.fit(cfg.tracker, y, names=["r"], extra=grid.evidence(cfg, y))
    assert tr.params["r"] == pytest.approx(ref.values["r"], rel=1e-12)
    causal = grid.estimate(rec, params={**p, "smooth": "none"})
    assert causal.params["r"] == pytest.approx(ref.values["r"], rel=1e-12)
