"""fuse's speed band from the accelerometer error the drive shows (``Config.band_psd``): the
speed stays the filter's to the bit, the band's covariance is the error covariance of an
estimate made with the filter's gains (checked against impulse responses of the filter's own
estimate), and the density learned from the fixes recovers a known white noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import fuse, get
from vibrospeed.models.gps_riss import transition


@pytest.fixture(scope="module")
def car():
    """A short simulated car drive and its smoothed and causal grid tracks (fuse's settings)."""
    rec = sim.simulate("car", seed=2, duration=20)
    off = get("grid").estimate(rec, axis="y", params=dict(fuse.TRACKER_DEFAULTS))
    on = get("grid").estimate(rec, axis="y", params={**fuse.TRACKER_DEFAULTS, "smooth": "none"})
    return rec, off, on


@pytest.mark.parametrize("online", [False, True])
def test_speed_bitwise_unchanged_band_wider(car, online):
    rec, off, on = car
    vib = on if online else off
    base = fuse.estimate(rec, vibration=vib, params={"online": online, "band_psd": "off"})
    wide = fuse.estimate(rec, vibration=vib, params={"online": online, "band_psd": 2.0})
    learned = fuse.estimate(rec, vibration=vib, params={"online": online})  # the default
    same = fuse.estimate(rec, vibration=vib, params={"online": online,
                                                      "band_psd": fuse.Config().acc_psd})
    for tr in (wide, learned, same):
        assert np.array_equal(tr.speed, base.speed)
        assert np.array_equal(tr.extras["radius"], base.extras["radius"])
    # the band at the filter's own density is its own covariance (online the same
    # arithmetic; offline another recursion through the smoother's pinv of the predictions)
    np.testing.assert_allclose(same.speed_std, base.speed_std, rtol=0 if online else 1e-3)
    # a noisier accelerometer: never narrower, and wider where the accelerometer carries it
    assert np.all(wide.speed_std >= base.speed_std * (1 - 1e-9))
    assert np.max(wide.speed_std / base.speed_std) > 1.5


def _linear_case(band):
    """A linear run: accelerometer at 10 Hz, GPS fixes every 0.5 s, none from 1.2 s to 2.4 s;
    the GPS error not clipped into the variance (``e_max=0``) and no extra lag (its variance
    0), so the gains do not depend on the data."""
    cfg = fuse.Config(e_max=0.0, gps_lag_std=0.0, q_gps_lag=0.0, band_psd="off")
    t = np.round(np.arange(0.0, 3.0, 0.1), 10)
    fix = (np.abs(t / 0.5 - np.round(t / 0.5)) < 1e-9) & ~((t > 1.1) & (t < 2.5))
    fix[0] = False
    st = fuse.init(cfg, 10.0, p0_speed=0.04)
    return cfg, t, fix, st


def _drive_errors(cfg, t, fix, st, x0, w, va, vg):
    """The filter's and the smoother's state errors ``x_true - x_est`` (2, n_samples, n) for
    the initial state ``x0``, process noises ``w`` (n_samples, n), accelerometer and GPS errors
    ``va``, ``vg``."""
    Ac, _, _ = cfg._arrays()
    xs = np.empty((t.size, x0.size))
    x = x0.copy()
    xs[0] = x
    for k in range(1, t.size):
        x = transition(Ac, t[k] - t[k - 1]) @ x + w[k]
        xs[k] = x
    acc = xs[:, fuse.IA] + xs[:, fuse.IB] + va
    acc[0] = math.nan
    g = np.where(fix, xs[:, fuse.IG] + vg, math.nan)
    o = fuse.run(cfg, {"t": t, "accel": acc, "gps_speed": g}, state=st)[1]
    return np.stack([xs - o.xf, xs - fuse.smooth(cfg, o)[0]])


def test_band_covariance_is_the_error_covariance_of_the_filters_gains():
    band = 1.7  # the accelerometer's true density; the gains assume acc_psd = 0.1
    cfg, t, fix, st = _linear_case(band)
    Ac, qc, _ = cfg._arrays()
    n, N = st.x.size, t.size
    dts = np.diff(t, prepend=t[0])
    zero = (np.zeros((N, n)), np.zeros(N), np.zeros(N))
    assert np.allclose(_drive_errors(cfg, t, fix, st, st.x.copy(), *zero), 0.0, atol=1e-9)
    # every independent error source as a unit impulse times its std: the estimate is linear
    # in them, so the error covariance is the sum of the responses' outer products
    eps = 1e-4
    resp = []
    lam, U = np.linalg.eigh(st.P)
    for j in range(n):
        if lam[j] > 0:
            resp.append(_drive_errors(cfg, t, fix, st, st.x + eps * math.sqrt(lam[j]) * U[:, j],
                                      *zero) / eps)
    for k in range(1, N):
        for i in range(n):
            if qc[i] > 0:
                w = np.zeros((N, n))
                w[k, i] = eps * math.sqrt(qc[i] * dts[k])
                resp.append(_drive_errors(cfg, t, fix, st, st.x, w, *zero[1:]) / eps)
        va = np.zeros(N)
        va[k] = eps * math.sqrt(band / dts[k])
        resp.append(_drive_errors(cfg, t, fix, st, st.x, zero[0], va, zero[2]) / eps)
        if fix[k]:
            vg = np.zeros(N)
            vg[k] = eps * math.sqrt(cfg.r_gps)
            resp.append(_drive_errors(cfg, t, fix, st, st.x, zero[0], zero[1], vg) / eps)
    R = np.stack(resp)  # (sources, 2, N, n)
    ref, ref_s = np.einsum("sfkn,sfkm->fknm", R, R)
    cfg_b = fuse.Config(e_max=0.0, gps_lag_std=0.0, q_gps_lag=0.0, band_psd=band)
    o = fuse.run(cfg_b, {"t": t, "accel": np.where(np.arange(N) > 0, 0.0, math.nan),
                         "gps_speed": np.where(fix, 10.0, math.nan)}, state=st)[1]
    iv = fuse.IV
    np.testing.assert_allclose(o.speed_std[1:], np.sqrt(ref[1:, iv, iv]), rtol=1e-5)
    np.testing.assert_allclose(o.Pbf[1:, :5, :5], ref[1:, :5, :5], rtol=1e-4, atol=1e-9)
    # in the GPS gap the band grows past the filter's own
    gap = (t > 1.4) & (t < 2.4)
    assert np.all(o.speed_std[gap] > 1.5 * np.sqrt(o.Pf[gap, iv, iv]))
    # offline: the smoothed estimate's error covariance
    Pbs = fuse.smooth_band(cfg_b, o)
    np.testing.assert_allclose(np.sqrt(Pbs[1:, iv, iv]), np.sqrt(ref_s[1:, iv, iv]), rtol=1e-5)
    np.testing.assert_allclose(Pbs[1:, :5, :5], ref_s[1:, :5, :5], rtol=1e-4, atol=1e-9)
    assert fuse.smooth_band(cfg, fuse.run(cfg, {"t": t}, state=st)[1]) is None
    assert fuse.Config().band_psd == "learned"


def test_step_carries_the_band_as_run():
    cfg, t, fix, st = _linear_case(1.0)
    cfg = fuse.Config(band_psd=1.0)
    acc = 0.3 * np.sin(t)
    g = np.where(fix, 10.0 + 0.1 * t, math.nan)
    o = fuse.run(cfg, {"t": t, "accel": acc, "gps_speed": g}, state=st)[1]
    s = st
    for k in range(t.size):
        s, est = fuse.step(cfg, s, (t[k], acc[k], g[k], math.nan, math.nan, math.nan, False,
                                    False))
        assert est.speed == o.speed[k]
        assert est.speed_std == pytest.approx(o.speed_std[k], rel=1e-12)
    assert s.Pb is not None and s.Pb[0, 0] > s.P[0, 0]


def _synthetic(q, seed, duration=1500.0, fs=25.0, fix_rate=5.0):
    """A drive whose accelerometer has a white error of density ``q`` and an offset of
    0.2 m/s^2; a receiver at ``fix_rate`` Hz with a 0.1 m/s error."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / fs)
    v = 15.0 + 5.0 * np.sin(2 * np.pi * t / 60.0) + 2.0 * np.sin(2 * np.pi * t / 17.0)
    dt = 1.0 / fs
    acc = np.diff(v, prepend=v[0]) / dt + 0.2 + rng.normal(0.0, math.sqrt(q / dt), t.size)
    acc[0] = math.nan
    g = np.full(t.size, math.nan)
    every = int(round(fs / fix_rate))
    g[::every] = v[::every] + rng.normal(0.0, 0.1, g[::every].size)
    return t, acc, g


@pytest.mark.parametrize(("q", "seed"), [(0.5, 0), (2.8, 1), (0.05, 2)])
def test_learned_density_recovers_white_noise(q, seed):
    t, acc, g = _synthetic(q, seed)
    est = fuse.learn_acc_psd(t, acc, g)
    assert est == pytest.approx(q, rel=0.2)
    if seed == 0:
        causal = fuse.learn_acc_psd_causal(t, acc, g)
        assert np.isnan(causal[t < 5.0]).all()  # nothing learned before the first estimate
        assert causal[-1] == est  # the last estimate has seen every pair
        # from the checkpoint before 750 s on: the fixes up to it (the pairs at the edge
        # aside); checkpoints every 5 s, then every 2 % of the elapsed time
        from vibrospeed.estimators.fuse.band import next_checkpoint

        cs = [t[0] + 5.0]
        while cs[-1] < 750.0:
            cs.append(next_checkpoint(cs[-1], t[0]))
        c = cs[-2]
        assert 735.0 < c <= 750.0 and cs[-1] - c == pytest.approx(0.02 * (c - t[0]))
        upto = t <= c
        k = np.searchsorted(t, c)
        assert causal[k] == pytest.approx(fuse.learn_acc_psd(t[upto], acc[upto], g[upto]),
                                          rel=0.01)
        assert causal[k] == causal[np.searchsorted(t, cs[-1]) - 1]  # held until the next


def test_learned_density_needs_fix_pairs():
    t, acc, g = _synthetic(0.5, 0, duration=20.0, fix_rate=0.5)
    assert fuse.learn_acc_psd(t, acc, g) is None  # 10 fixes: fewer than 20 pairs per interval
    assert np.isnan(fuse.learn_acc_psd_causal(t, acc, g)).all()


def test_band_psd_validated():
    for bad in ("sometimes", -1.0, 0.0, math.inf):
        with pytest.raises(ParameterError, match="band_psd"):
            fuse.Config(band_psd=bad)
