"""The grid trackers' within-mode spread ``omega_mode_std``: the root-mean-square distance of
omega from the mode's mean over the mode's basin, against a brute-force computation from the
posterior; step == run, checkpointed smoother == whole-log smoother, the Track column."""

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.grid import method as gm
from vibrospeed.estimators.grid import smoother as gs
from vibrospeed.estimators.grid.filter import tables
from vibrospeed.models.harmonic import HarmonicModel


def brute_spread(w, g, rel, ab, omega_mode, u):
    """``(mode, p_mode, spread)`` from grid weights ``w`` by plain loops: a window
    ``|omega - g_j| <= max(ab, rel g_j)`` whose mass most exceeds a flat posterior's
    (``sum (w_i - W u_i)``, ``W = sum(w)``, prior ``u``; ties within 1e-9 W: the one whose
    mean is nearest the reported ``omega_mode``), its mean, its basin (the windows reached by
    non-increasing window excess), the share of the mass the basin's windows cover and the RMS
    distance of omega from the window's mean over them."""
    w = np.asarray(w, np.float64)
    N = g.size
    W = sum(w)
    hw = [max(ab, rel * g[j]) for j in range(N)]
    m = [sum(w[i] - W * u[i] for i in range(N) if abs(g[i] - g[j]) <= hw[j]) for j in range(N)]

    def mean(j):
        inw = [i for i in range(N) if abs(g[i] - g[j]) <= hw[j]]
        return sum(w[i] * g[i] for i in inw) / sum(w[i] for i in inw)

    eps = 1e-9 * W
    cands = [j for j in range(N) if m[j] >= max(m) - eps]
    jb = min(cands, key=lambda j: abs(mean(j) - omega_mode))
    mode = mean(jb)
    a = b = jb
    while a > 0 and m[a - 1] <= m[a] + eps:
        a -= 1
    while b < N - 1 and m[b + 1] <= m[b] + eps:
        b += 1
    cover = [i for i in range(N) if g[a] - hw[a] <= g[i] <= g[b] + hw[b]]
    mass = sum(w[i] for i in cover)
    spread = np.sqrt(sum(w[i] * (g[i] - mode) ** 2 for i in cover) / mass)
    return mode, mass / W, spread


def _two_tones(n=600):
    rng = np.random.default_rng(3)
    t = np.arange(n) * 0.01
    y = 0.6 * np.sin(45 * t) + 0.45 * np.sin(30 * t + 1.0) + 0.2 * rng.normal(size=t.size)
    model = HarmonicModel(M=1, dt=0.01, q_omega=4.0, q_amp=0.001, r=0.05, p0_amp=0.1)
    return y, rbpmf.Config(model=model, n_grid=120, omega_min=10.0, omega_max=70.0)


def test_filter_spread_is_the_brute_force_of_its_posterior_and_step_equals_run():
    y, cfg = _two_tones()
    res = rbpmf.run(cfg, y)
    st = rbpmf.init(cfg)
    g = cfg.grid
    split = 0
    for k, v in enumerate(y):
        st, est = rbpmf.step(cfg, st, v)
        s = est.extras["omega_mode_std"]
        assert s == res.omega_mode_std[k]  # bitwise
        if k % 5 == 0 or res.p_mode[k] < 0.9:
            mode, p, ref = brute_spread(est.posterior, g, cfg.amb_rel, cfg.amb_abs,
                                          est.omega_mode, tables(cfg).u)
            assert abs(mode - est.omega_mode) < 1e-9 * mode
            assert abs(p - est.p_mode) < 1e-9
            assert abs(ref - s) < 1e-9 * max(1.0, ref)
            split += est.p_mode < 0.9
    assert split >= 3  # split posteriors (the start) were among the checked ones


def test_spread_of_a_two_bump_posterior_is_the_bump_width():
    """Bumps of sd 1.5 rad/s at 30 (mass 0.35) and 45 (0.65): the mixture's std is ~7.4
    rad/s, the spread within the mode the bump's own 1.5 rad/s."""
    _, cfg = _two_tones()
    g = cfg.grid
    w = 0.35 * np.exp(-0.5 * ((g - 30) / 1.5) ** 2) + 0.65 * np.exp(-0.5 * ((g - 45) / 1.5) ** 2)
    w /= w.sum()
    st0 = rbpmf.init(cfg)
    _, est = rbpmf.step(cfg, st0._replace(log_w=np.log(w)), np.nan)
    mix = np.sqrt(0.35 * 0.65 * 15.0 ** 2 + 1.5 ** 2)
    assert abs(est.omega_std - mix) < 0.05
    assert abs(est.extras["omega_mode_std"] - 1.5) < 0.05
    ref = brute_spread(w, g, cfg.amb_rel, cfg.amb_abs, est.omega_mode, tables(cfg).u)[2]
    assert abs(est.extras["omega_mode_std"] - ref) < 1e-12


def _emissions(n=900, seed=0):
    model = HarmonicModel(M=2, dt=0.01, q_omega=4.0, q_amp=0.001, r=0.05, p0_amp=0.1)
    om = np.where(np.arange(n) < n // 2, 30.0, 38.0)
    y, _ = model.simulate(om, np.random.default_rng(seed), x0=np.tile([0.6, 0.0], 2))
    y[200:230] = np.nan
    cfg = rbpmf.Config(model=model, n_grid=30, omega_min=20.0, omega_max=50.0,
                       jump_rate=0.5, off_rate=0.2, on_rate=1.0)
    return cfg, rbpmf.run(cfg, y, return_grid_loglik=True).grid_loglik


def test_smoothed_spread_is_the_brute_force_of_the_smoothed_posterior():
    cfg, gll = _emissions()
    sm = gs.smooth(cfg, gll, return_posterior=True)
    g = cfg.grid
    for k in range(0, 900, 11):  # the posterior comes back as float32: loose tolerances
        _, _, ref = brute_spread(sm.posterior[k], g, cfg.amb_rel, cfg.amb_abs,
                                 sm.omega_mode[k], tables(cfg).u)
        assert abs(ref - sm.omega_mode_std[k]) < 1e-4 * max(1.0, ref)
    lag = gs.fixed_lag(cfg, gll, lag=0.5, return_posterior=True)
    for k in range(0, 900, 13):
        _, _, ref = brute_spread(lag.posterior[k], g, cfg.amb_rel, cfg.amb_abs,
                                 lag.omega_mode[k], tables(cfg).u)
        assert abs(ref - lag.omega_mode_std[k]) < 1e-4 * max(1.0, ref)


@pytest.mark.parametrize("K", [1, 128, 900])
def test_checkpointed_smoother_spread_equals_whole_log(K):
    cfg, gll = _emissions()
    whole = gs.smooth(cfg, gll, checkpoint=None)
    part = gs.smooth(cfg, gll, checkpoint=K)
    assert np.array_equal(whole.omega_mode_std, part.omega_mode_std)


@pytest.mark.parametrize("smooth", ["fb", "none"])
def test_track_column(smooth):
    """The grid Track carries the column (rad/s), offline and causal; on a drive's line it is
    a small part of omega."""
    rec = sim.simulate("car", seed=1, duration=40)
    tr = gm.estimate(rec, axis="y", params={"smooth": smooth})
    s = tr.extras["omega_mode_std"]
    assert s.shape == tr.omega.shape and np.all(np.isfinite(s)) and np.all(s >= 0)
    # where a line is likely (at the smoother's claim level, whatever the mode's own) and one
    # mode holds it
    line = (1.0 - tr.extras["p_null"] >= 0.9) & (tr.extras["p_mode"] > 0.9)
    assert line.mean() > 0.1
    assert np.median(s[line] / tr.omega[line]) < 0.05


def test_a_core_compiled_for_another_row_layout_is_refused(monkeypatch):
    """numba's cache of the compiled core does not follow summary.py: a core that writes a
    different number of columns per sample than this version reads is a clear error, not
    shifted columns."""
    import dataclasses

    import vibrospeed.estimators.grid.filter as filt

    cfg = dataclasses.replace(rbpmf.Config.from_paper_table1(0.01), n_grid=20)
    y = np.sin(0.5 * np.arange(50))
    filt.run(cfg, y)  # the layouts agree
    monkeypatch.setattr(filt, "N_OUT_FIXED", filt.N_OUT_FIXED - 1)
    with pytest.raises(RuntimeError, match="stale numba cache"):
        filt.run(cfg, y)
