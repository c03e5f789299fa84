"""A device's walk through the online API: the causal standstill detector one sample at a time
(:func:`vibrospeed.signal.standstill_stream.stream_step`) and the online tracker with it, against
the causal batch run."""

import pickle

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.estimators import ekf, grid
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.online import OnlineTracker
from vibrospeed.signal import standstill as ss
from vibrospeed.signal import standstill_stream as sst

P = {"smooth": "none", "omega_min": 2, "omega_max": 30}


def test_stream_step_gives_the_causal_detectors_decisions():
    rec = sim.simulate("stop_and_go", seed=5, duration=60)
    ch = {c: rec[c].copy() for c in ("ax", "ay", "az")}
    for c in ch.values():
        c[1000:1030] = np.nan
    ch["ax"][2600:2900] = np.nan  # a sensor that drops samples
    X = np.column_stack([ch["ay"], ch["ax"], ch["az"]])
    band = (2.0, 90.0)
    ref = ss.standstill(X, 0.01, band, causal=True)
    assert 0.03 < ref.mean() < 0.5  # the drive has stops the detector finds
    plan = sst.stream_plan(0.01, band)
    sts = [sst.stream_init(plan) for _ in range(3)]
    got = np.zeros(len(X), bool)
    for i, row in enumerate(X):
        flags = []
        for j in range(3):
            if i == 3000:  # saved and restored mid-drive
                sts[j] = pickle.loads(pickle.dumps(sts[j]))
            sts[j], f = sst.stream_step(plan, sts[j], row[j])
            flags.append(f)
        got[i] = all(flags)
    np.testing.assert_array_equal(got, ref)


def test_online_tracker_with_standstill_is_the_causal_estimate_at_stops_too():
    rec0 = sim.simulate("stop_and_go", seed=2, duration=40)
    ch = {c: rec0[c].copy() for c in ("ax", "ay", "az")}
    for c in ch.values():
        c[1000:1030] = np.nan
    from vibrospeed.types import Recording

    rec = Recording(rec0.t, ch)
    track = grid.estimate(rec, axis="y", params=P)
    still = track.extras["standstill"] > 0.5
    assert 0.03 < still.mean() < 0.5
    cfg = grid.config_for(rec, params=P)
    lvl = start_level(ch["ay"], 0.01)
    trk = OnlineTracker(grid, cfg, level=lvl, standstill=3)
    plain = OnlineTracker(grid, cfg, level=lvl)
    est, old = [], []
    for i, (a, x, z) in enumerate(zip(ch["ay"], ch["ax"], ch["az"], strict=True)):
        if i == 2500:
            trk.state = pickle.loads(pickle.dumps(trk.state))
        est.append(trk.update(a, (x, z)))
        old.append(plain.update(a))
    for k in ("omega", "omega_lo", "omega_hi", "omega_std"):
        np.testing.assert_array_equal([getattr(e, k) for e in est], getattr(track, k))
    np.testing.assert_array_equal([e.standstill for e in est], track.extras["standstill"])
    np.testing.assert_array_equal([e.has_signal for e in est], track.extras["has_signal"])
    # without the detector: no stops (NaN), the tracker's guess there
    assert np.isnan([e.standstill for e in old]).all()
    assert min(e.omega for e, s in zip(old, still, strict=True) if s) > 0


def test_online_standstill_with_all_comb_axes_and_refusals():
    rec = sim.simulate("stop_and_go", seed=2, duration=25)
    p = {**P, "comb_axes": "all", "n_grid": 60}
    track = grid.estimate(rec, axis="y", params=p)
    cfg = grid.config_for(rec, params=p)
    trk = OnlineTracker(grid, cfg, level=[start_level(rec[c], 0.01) for c in cfg.comb_axes],
                        standstill=3)
    got = [trk.update(row) for row in np.column_stack([rec[c] for c in cfg.comb_axes])]
    np.testing.assert_array_equal([e.omega for e in got], track.omega)
    np.testing.assert_array_equal([e.standstill for e in got], track.extras["standstill"])
    with pytest.raises(ValueError, match="expected 0 sample"):
        trk.update((0.1, 0.2, 9.8), (0.0,))
    other = OnlineTracker(grid, cfg, level=0.0)
    with pytest.raises(ValueError, match="no standstill part"):
        trk.state = other.state  # saved without the detectors
        trk.update((0.1, 0.2, 9.8))
    with pytest.raises(ValueError, match="search range"):
        OnlineTracker(ekf, ekf.config_for(rec, params={"omega0": 9.0}), standstill=3)


def test_a_time_gap_fed_as_nan_samples_is_the_estimate_with_nan_in_the_gap():
    """docs/guide.md: the online tracker has no clock; one NaN per missing period gives the
    numbers of ``estimate`` on the uniform time line with NaN in the gap (what
    :func:`vibrospeed.io.resample_uniform` makes of a file's gap)."""
    from vibrospeed.types import Recording

    rec = sim.simulate("cart", seed=4, duration=20)
    ay = rec["ay"].copy()
    ay[800:1100] = np.nan  # 3 s without samples: t jumps from 7.99 to 11.00 s
    track = grid.estimate(Recording(rec.t, {"ay": ay}), axis="y", params=P)
    cfg = grid.config_for(rec, params=P)
    trk = OnlineTracker(grid, cfg, level=start_level(ay, 0.01))
    got = []
    for i, a in enumerate(rec["ay"]):
        if 800 <= i < 1100:
            continue  # the device got nothing here ...
        if i == 1100:  # ... and learns from the next time stamp that 300 periods passed
            gap = int(round((rec.t[1100] - rec.t[799]) / cfg.tracker.model.dt)) - 1
            assert gap == 300
            got += [trk.update(np.nan).omega for _ in range(gap)]
        got.append(trk.update(a).omega)
    np.testing.assert_array_equal(got, track.omega)
    # the same samples joined without the NaN are not that estimate
    join = OnlineTracker(grid, cfg, level=start_level(ay, 0.01))
    joined = np.array([join.update(a).omega for a in rec["ay"][np.isfinite(ay)]])
    assert np.max(np.abs(joined[800:] - track.omega[1100:])) > 0.5
