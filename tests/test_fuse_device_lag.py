"""``fuse`` on a device with a fixed lag: :class:`~vibrospeed.estimators.fuse.device.
FuseTracker` built by ``config_for(rec, params={"lag": S})`` runs the grid tracker's fixed-lag
smoother inside and, fed one IMU sample at a time, gives the numbers of the batch
``fuse.estimate(rec, params={"lag": S})`` (lines read as offline), each estimate late by the
tracker's lag."""

import math
import pickle

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import fuse, grid
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.fuse.device import FuseTracker, config_for
from vibrospeed.types import Recording

P = {"n_grid": 40, "omega_min": 2, "omega_max": 30}
R = 0.08  # the cart's wheel radius
LAG = 2.0


def _cart(duration=20.0):
    """Stop-and-go cart: GPS at 10 Hz from 2.5 s (7 satellites, 4 in 15-17 s: no valid fix),
    an outage 9-14 s, the vibration axis missing 5.0-5.3 s."""
    r = sim.simulate("stop_and_go", seed=1, duration=duration)
    t = r.t
    rng = np.random.default_rng(11)
    g = np.full(t.size, np.nan)
    idx = np.arange(250, t.size, 10)
    g[idx] = r["speed_true"][idx] + rng.normal(0.0, 0.03, idx.size)
    g[(t >= 9) & (t < 14)] = np.nan
    ay = r["ay"].copy()
    ay[(t >= 5.0) & (t < 5.3)] = np.nan
    return Recording(t, {"ax": r["ax"], "ay": ay, "az": r["az"], "gps_speed": g,
                         "gps_sats": np.where((t >= 15) & (t < 17), 4.0, 7.0)})


def _run(rec, dev, start=0, stop=None):
    """Samples ``start..stop`` through ``dev`` (finish() where ``stop`` is None): the
    ``(k, Estimate)`` pairs, the raw-input queue's longest length and each pair's delay (in
    samples, from its sample to the update that returned it)."""
    g, s = rec["gps_speed"], rec["gps_sats"]
    ax, ay, az = rec["ax"], rec["ay"], rec["az"]
    out, longest, delay = [], 0, []
    for i in range(start, len(rec) if stop is None else stop):
        got = dev.update(rec.t[i], ax[i], ay[i], g[i], s[i], (ax[i], az[i]))
        delay += [i - k for k, _ in got]
        longest = max(longest, len(dev.raw))
        out += got
    if stop is None:
        out += dev.finish()
    return out, longest, delay


def _assert_batch(out, track):
    assert [k for k, _ in out] == list(range(len(track)))  # each sample once, in order
    est = [e for _, e in out]
    np.testing.assert_array_equal([e.speed for e in est], track.speed)
    np.testing.assert_array_equal([e.speed_std for e in est], track.speed_std)
    for k in ("source", "radius", "radius_std", "offset", "harmonic", "omega_vib",
              "standstill_vib"):
        np.testing.assert_array_equal([float(e.extras[k]) for e in est], track.extras[k],
                                      err_msg=k)
    np.testing.assert_array_equal([e.standstill for e in est], track.extras["standstill"])
    np.testing.assert_array_equal([e.has_signal for e in est], track.extras["has_signal"])


@pytest.fixture(scope="module")
def drive():
    rec = _cart()
    track = fuse.estimate(rec, params={"lag": LAG, **P}, wheel_radius=R)
    cfg, tc = config_for(rec, params={"lag": LAG, **P}, wheel_radius=R)
    return rec, track, cfg, tc


def _device(rec, tc, cfg):
    return FuseTracker(cfg, tc, level=start_level(rec["ay"], tc.tracker.model.dt))


def test_config_is_the_batch_lag_run(drive):
    rec, track, cfg, tc = drive
    off = fuse.Config()
    # the lines read as offline: none of the causal settings
    assert (cfg.vib_lag, cfg.vib_spread, cfg.vib_amax, cfg.vib_soft, cfg.vib_measure) == (
        off.vib_lag, off.vib_spread, off.vib_amax, off.vib_soft, off.vib_measure)
    assert (tc.tracker.smooth, tc.tracker.lag) == ("lag", LAG)
    assert track.params["vib_amax"] == cfg.vib_amax and track.params["lag"] == LAG
    # with a lag the batch runs the forward filter whatever online says
    assert config_for(rec, params={"lag": LAG, "online": False, **P}, wheel_radius=R) == (
        cfg, tc)


def test_lag_device_is_the_batch_lag_run_sample_by_sample(drive):
    rec, track, cfg, tc = drive
    src = np.bincount(track.extras["source"].astype(int), minlength=4)
    assert np.all(src > 100)  # inertial (outage), gps, vibration and stops all occur
    dev = _device(rec, tc, cfg)
    assert isinstance(dev.trk, grid.LaggedTracker)
    out, longest, delay = _run(rec, dev)
    _assert_batch(out, track)
    # every sample waits at least the lag (the smoother's); the raw inputs kept are only
    # those the tracker has not given out: at most its longest wait
    dt = tc.tracker.model.dt
    assert min(delay) >= round(LAG / dt)
    assert longest <= round(dev.trk.max_delay / dt) + 1 and not dev.raw


def test_lag_device_pickled_mid_stream_continues(drive):
    rec, track, cfg, tc = drive
    dev = _device(rec, tc, cfg)
    half = 1130  # in the outage: the filter runs, samples wait in the tracker and blocks
    out, _, _ = _run(rec, dev, stop=half)
    assert out and dev.raw and dev.samples
    dev = pickle.loads(pickle.dumps(dev))
    rest, _, _ = _run(rec, dev, start=half)
    _assert_batch(out + rest, track)


@pytest.mark.parametrize("bad", [0, -1, "x", True, math.inf])
def test_bad_lag_one_line(drive, bad):
    rec = drive[0]
    with pytest.raises(ParameterError, match="lag must be a delay in s > 0") as exc:
        config_for(rec, params={"lag": bad, **P}, wheel_radius=R)
    assert "\n" not in str(exc.value)


def test_a_smoothed_tracker_refused(drive):
    rec, _, cfg, _ = drive
    with pytest.raises(ParameterError, match="smooth=fb"):
        FuseTracker(cfg, grid.config_for(rec, params={**P, "smooth": "fb"}))


@pytest.fixture(scope="module")
def drive_post():
    """The drive with ``vib_measure="posterior"``: the batch run and the device's configs."""
    rec = _cart()
    prm = {"lag": LAG, "vib_measure": "posterior", **P}
    track = fuse.estimate(rec, params=prm, wheel_radius=R)
    cfg, tc = config_for(rec, params=prm, wheel_radius=R)
    return rec, track, cfg, tc


def test_lag_device_reads_the_smoothed_posterior_as_the_batch(drive, drive_post):
    """With a lag and ``vib_measure="posterior"`` the device's tracker keeps its smoothed
    posterior rows and the filter reads them at the fusion samples: the batch numbers, not
    those of the mode."""
    rec, track, cfg, tc = drive_post
    assert cfg.vib_measure == "posterior" and track.params["vib_measure"] == "posterior"
    assert cfg.vib_sep == fuse.Config().vib_sep  # the offline reading, as the batch
    dev = _device(rec, tc, cfg)
    assert dev.trk.posterior and dev.post
    out, _, _ = _run(rec, dev)
    _assert_batch(out, track)
    assert np.abs(track.speed - drive[1].speed).max() > 0.1  # the posterior was read
    _, _, cfg_mode, tc_mode = drive
    assert not _device(rec, tc_mode, cfg_mode).trk.posterior  # vib_measure=mode keeps none


def test_lag_device_with_the_posterior_pickled_mid_stream_continues(drive_post):
    rec, track, cfg, tc = drive_post
    dev = _device(rec, tc, cfg)
    half = 1130
    out, _, _ = _run(rec, dev, stop=half)
    # blocks wait for the filter, the open block's closing estimate holds its posterior row
    assert out and dev.blocks and dev._last[-1].extras["posterior"].dtype == np.float32
    dev = pickle.loads(pickle.dumps(dev))
    rest, _, _ = _run(rec, dev, start=half)
    _assert_batch(out + rest, track)


def test_a_log_too_slow_for_a_wheel_line_runs_without_a_tracker_with_a_lag_too():
    """At 20 Hz no wheel line fits the default range: with or without a lag the device has no
    tracker and gives the batch run's numbers (GPS and the accelerometer alone)."""
    rec = sim.simulate("car", seed=2, duration=20)
    idx = np.arange(0, len(rec), 5)
    slow = Recording(rec.t[idx], {k: v[idx] for k, v in rec.channels.items()}, source="slow")
    for prm in ({"lag": 2}, {"online": True}):
        want = fuse.estimate(slow, params=prm)
        cfg, tc = config_for(slow, params=prm)
        assert tc is None
        dev = FuseTracker(cfg, tc, dt=float(np.median(np.diff(slow.t))))
        out = []
        for i in range(len(slow)):
            out += dev.update(slow.t[i], slow["ax"][i], math.nan, slow["gps_speed"][i],
                              slow["gps_sats"][i])
        out += dev.finish()
        assert [k for k, _ in out] == list(range(len(slow)))
        np.testing.assert_array_equal([e.speed for _, e in out], want.speed)
