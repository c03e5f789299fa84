"""The online pipeline gives the batch estimate() numbers sample by sample."""

import numpy as np
import pytest

from vibrospeed.estimators import ekf
from vibrospeed.estimators.online import OnlineTracker
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal.normalize import running_rms_normalize
from vibrospeed.types import Recording


def test_online_equals_batch_estimate():
    rng = np.random.default_rng(3)
    n = 1500
    t = np.arange(n) / 100.0
    ay = 0.05 * np.cos(11.0 * t) + 0.03 * np.cos(22.0 * t) + 0.01 * rng.normal(size=n) + 0.2
    ay[300:310] = np.nan
    rec = Recording(t, {"ay": ay})
    track = ekf.estimate(rec, axis="y", params={"omega0": "10.5"})
    model = HarmonicModel(dt=float(np.median(np.diff(t))), **ekf.UNIT_RMS_MODEL)
    from vibrospeed.estimators.common import start_level

    cfg = ekf.Config(model, omega0=10.5, omega_min=2.0)
    trk = OnlineTracker(ekf, cfg, level=start_level(ay, 0.01))
    om = np.array([trk.update(v).omega for v in ay])
    np.testing.assert_allclose(om, track.omega, rtol=0, atol=1e-9)
    assert abs(np.mean(om[-300:]) - 11.0) < 0.5


def test_normalizer_step_equals_batch():
    from vibrospeed.signal import normalize as nz

    x = np.random.default_rng(1).normal(size=300) * 7
    x[5] = np.nan
    s = nz.init()
    out = []
    for v in x:
        s, o = nz.step(s, v, 0.01, 1.0)
        out.append(o)
    np.testing.assert_array_equal(np.array(out), running_rms_normalize(x, 0.01, 1.0))


def test_chunked_estimate_with_progress_equals_whole():
    from vibrospeed.estimators import common

    rng = np.random.default_rng(0)
    n = 2500
    t = np.arange(n) / 100.0
    rec = Recording(t, {"ay": np.cos(11.0 * t) + 0.1 * rng.normal(size=n)})
    whole = ekf.estimate(rec)
    calls = []
    orig = common.run_in_chunks

    def small_chunks(fn, n, **kw):
        calls.append(n)
        return orig(fn, n, **{**kw, "chunk": 700})

    common.run_in_chunks = small_chunks
    try:
        chunked = ekf.estimate(rec, progress=True)
    finally:
        common.run_in_chunks = orig
    assert calls == [n]
    np.testing.assert_array_equal(chunked.omega, whole.omega)
    np.testing.assert_array_equal(chunked.omega_std, whole.omega_std)


def test_online_grid_trackers_equal_their_causal_estimate():
    from vibrospeed.estimators import grid, rbpmf
    from vibrospeed.estimators.common import start_level

    rng = np.random.default_rng(7)
    n = 700
    t = np.arange(n) / 100.0
    ay = 0.2 * np.cos(30.0 * t) + 0.1 * np.cos(60.0 * t) + 0.05 * rng.normal(size=n) + 9.8
    rec = Recording(t, {"ay": ay})
    for mod, params in ((rbpmf, {"n_grid": 40}),
                        (grid, {"n_grid": 40, "smooth": "none", "comb_window": 1.0})):
        track = mod.estimate(rec, axis="y", params=params)
        cfg = mod.config_for(rec, axis="y", params=params)
        trk = OnlineTracker(mod, cfg, level=start_level(ay, 0.01))
        om = np.array([trk.update(v).omega for v in ay])
        np.testing.assert_allclose(om, track.omega, rtol=0, atol=1e-9)


def test_online_grid_with_several_comb_axes_equals_its_causal_estimate():
    from vibrospeed.estimators import grid
    from vibrospeed.estimators.common import start_level

    rng = np.random.default_rng(8)
    n = 600
    t = np.arange(n) / 100.0
    ay = 0.2 * np.cos(30.0 * t) + 0.05 * rng.normal(size=n) + 0.3
    az = 0.1 * np.cos(60.0 * t) + 0.1 * np.cos(90.0 * t) + 0.05 * rng.normal(size=n) + 9.8
    ax = 0.05 * rng.normal(size=n)
    rec = Recording(t, {"ax": ax, "ay": ay, "az": az})
    params = {"n_grid": 40, "smooth": "none", "comb_window": 1.0, "comb_axes": "all"}
    track = grid.estimate(rec, axis="z", params=params)
    cfg = grid.config_for(rec, axis="z", params=params)
    assert cfg.comb_axes == ("az", "ax", "ay")  # the tracked axis first
    cols = [rec[c] for c in cfg.comb_axes]
    trk = OnlineTracker(grid, cfg, level=[start_level(c, 0.01) for c in cols])
    om = np.array([trk.update(s).omega for s in np.column_stack(cols)])
    np.testing.assert_allclose(om, track.omega, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="3 sample"):
        trk.update(1.0)


def test_ekf_config_for_gives_the_online_tracker_the_batch_filters_numbers():
    """``ekf.config_for``: the config ``estimate`` runs (without the comb check, which the
    online tracker does not compute), so the online tracker repeats ``estimate``'s numbers."""
    from vibrospeed import sim
    from vibrospeed.estimators.common import start_level

    rec = sim.simulate("cart", seed=3, duration=20)
    p = {"omega0": 9.0, "comb": False}
    track = ekf.estimate(rec, axis="y", params=p)
    cfg = ekf.config_for(rec, params=p)
    assert cfg.model.dt == pytest.approx(0.01) and not cfg.acquire
    assert cfg == ekf.config_for(rec, params={"omega0": 9.0})  # online: never the comb check
    ay = rec.channel("ay")
    trk = OnlineTracker(ekf, cfg, level=start_level(ay, cfg.model.dt))
    got = np.array([trk.update(a).omega for a in ay])
    np.testing.assert_array_equal(got, track.omega)
