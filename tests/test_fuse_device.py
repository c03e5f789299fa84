"""``fuse`` on a device (:class:`vibrospeed.estimators.fuse.device.FuseTracker`): fed one IMU
sample at a time it gives the numbers of the batch forward filter
``fuse.estimate(rec, params={"online": True})``, with a late first fix, a tunnel, a weak sky,
stops and wheel lines; the band density learned as fixes come equals the batch causal one."""

import math

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import fuse
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.fuse.band import learn_acc_psd_causal
from vibrospeed.estimators.fuse.device import FuseTracker, _Band, config_for
from vibrospeed.types import Recording

P = {"n_grid": 40, "omega_min": 2, "omega_max": 30}
R = 0.08  # the cart's wheel radius


def _drive(duration=20.0, gps=True):
    """A stop-and-go cart with GPS at 10 Hz from 2.5 s, a tunnel 8-14 s, 5 satellites 16-18 s."""
    r = sim.simulate("stop_and_go", seed=5, duration=duration)
    t = r.t
    ch = {c: r[c] for c in ("ax", "ay", "az")}
    if gps:
        rng = np.random.default_rng(5)
        g = np.full(t.size, np.nan)
        idx = np.arange(250, t.size, 10)
        g[idx] = r["speed_true"][idx] + rng.normal(0.0, 0.03, idx.size)
        g[(t >= 8) & (t < 14)] = np.nan
        ch["gps_speed"] = g
        ch["gps_sats"] = np.where((t >= 16) & (t < 18), 5.0, 9.0)
    return Recording(t, ch)


def _feed(rec, dev, sign=1.0, n=None):
    """Every sample through ``dev`` (``ax`` times ``sign`` as the longitudinal one): the
    Estimates in sample order and the first sample whose update returned any; with ``n``, the
    first ``n`` samples and no finish: the ``(k, Estimate)`` pairs returned by then."""
    nan = np.full(len(rec), np.nan)
    g, s = (rec.channels.get(c, nan) for c in ("gps_speed", "gps_sats"))
    ax, ay, az = rec["ax"], rec["ay"], rec["az"]
    out, first = [], None
    for i in range(len(rec)):
        if n is not None and i == n:
            return out, first
        got = dev.update(rec.t[i], sign * ax[i], ay[i], g[i], s[i], (ax[i], az[i]))
        if got and first is None:
            first = i
        out += got
    out += dev.finish()
    assert [k for k, _ in out] == list(range(len(rec)))
    return [e for _, e in out], first


def _assert_batch(out, track):
    np.testing.assert_array_equal([e.speed for e in out], track.speed)
    np.testing.assert_array_equal([e.speed_std for e in out], track.speed_std)
    for k in ("source", "radius", "radius_std", "offset", "harmonic", "omega_vib",
              "standstill_vib"):
        np.testing.assert_array_equal([float(e.extras[k]) for e in out], track.extras[k],
                                      err_msg=k)
    np.testing.assert_array_equal([e.standstill for e in out], track.extras["standstill"])
    np.testing.assert_array_equal([e.has_signal for e in out], track.extras["has_signal"])


@pytest.fixture(scope="module")
def drive():
    rec = _drive()
    track = fuse.estimate(rec, params={"online": True, **P}, wheel_radius=R)
    cfg, tc = config_for(rec, params=P, wheel_radius=R)
    return rec, track, cfg, tc


def test_device_is_the_batch_forward_filter_sample_by_sample(drive):
    rec, track, cfg, tc = drive
    src = np.bincount(track.extras["source"].astype(int), minlength=4)
    assert np.all(src > 100)  # inertial (tunnel), gps, vibration and stops all occur
    dev = FuseTracker(cfg, tc, level=start_level(rec["ay"], tc.tracker.model.dt))
    out, first = _feed(rec, dev)
    _assert_batch(out, track)
    # nothing final before the first fix (the filter starts at its speed; a negative one is
    # no fix, as the readers take it)
    assert first == np.flatnonzero(rec["gps_speed"] >= 0)[0] > 250
    # omega: the speed over the radius learned so far, where it is known
    r = np.array([e.extras["radius"] for e in out])
    known = np.array([e.extras["radius_std"] for e in out]) < cfg.octave_rel * r
    assert known[-1]
    np.testing.assert_allclose([e.omega for e in out][-1], track.speed[-1] / r[-1], rtol=1e-15)
    assert np.isnan(np.array([e.omega for e in out])[~known]).all()


def test_a_backwards_accelerometer_read_with_its_sign(drive):
    rec, track, cfg, tc = drive
    dev = FuseTracker(cfg, tc, level=start_level(rec["ay"], tc.tracker.model.dt),
                      accel_axis="-x")
    out, _ = _feed(rec, dev, sign=-1.0)  # the longitudinal sample mounted backwards
    np.testing.assert_array_equal([e.speed for e in out], track.speed)
    wrong = FuseTracker(cfg, tc, level=start_level(rec["ay"], tc.tracker.model.dt))
    got, _ = _feed(rec, wrong, sign=-1.0, n=800)  # the tunnel starts at 8 s
    i = [k for k, _ in got]
    assert np.max(np.abs(np.array([e.speed for _, e in got]) - track.speed[i])) > 0.1


def test_without_gps_given_a_radius():
    rec = _drive(duration=12.0, gps=False)
    with pytest.raises(ParameterError, match="needs a radius"):
        config_for(rec, params=P)
    track = fuse.estimate(rec, params={"online": True, **P}, wheel_radius=R)
    cfg, tc = config_for(rec, params=P, wheel_radius=R)
    assert (cfg.radius0, cfg.radius_std0) == (R, 0.01 * R)
    level = start_level(rec["ay"], tc.tracker.model.dt)
    out, first = _feed(rec, FuseTracker(cfg, tc, level=level, v0=0.0))
    _assert_batch(out, track)
    assert first < 10  # started at once, no fix to wait for
    assert np.mean(track.extras["source"] == fuse.SRC_VIBRATION) > 0.2


def test_band_density_as_the_fixes_come_is_the_batch_causal_one():
    """Fusion samples at 25 Hz, fixes at about 10 Hz with jitter (a pair's partner hangs on the
    next fix), a 9 s gap and a block without acceleration: per sample the density of
    :func:`learn_acc_psd_causal` on the whole arrays."""
    rng = np.random.default_rng(1)
    t = np.cumsum(np.full(2500, 0.04)) + 0.013
    a = rng.normal(0.0, 1.0, t.size)
    v = np.cumsum(a * 0.04) + rng.normal(0.0, 0.05, t.size)
    a = a + rng.normal(0.0, 1.5, t.size)  # the accelerometer's error: 0.09 (m/s^2)^2 s
    a[700] = np.nan
    fix = (rng.random(t.size) < 0.35) & ~((t > 40) & (t < 49))
    g = np.where(fix, v, np.nan)
    ref = learn_acc_psd_causal(t, a, g)
    assert np.isfinite(ref[-1]) and np.unique(ref[np.isfinite(ref)]).size > 5
    band, got, waits = _Band(), [], []
    queue = []
    for k in range(t.size):
        band.add(t[k], a[k], g[k])
        queue.append(k)
        while len(queue) > 1:  # the newest may be the last
            q = band.density(t[queue[0]], t[k], False)
            if q is None:
                break
            waits.append(t[k] - t[queue[0]])
            got.append(q)
            queue.pop(0)
    band.finish()
    got += [band.density(t[j], t[-1], j == t.size - 1) for j in queue]
    np.testing.assert_array_equal(got, ref)
    assert 0.5 < max(waits) <= 3.2 + 0.04  # waited for a partner's next fix, 0.4 T at most


def test_bad_input_one_line_errors(drive):
    rec, _, cfg, tc = drive
    dev = FuseTracker(cfg, tc, level=0.0)
    dev.update(0.0, 0.1, 9.8, others=(0.1, 0.2))
    for args, kw, msg in [
        ((0.0, 0.1, 9.8), {"others": (0.1, 0.2)}, "sample 1: time 0.0 s is not after"),
        ((0.01, "x", 9.8), {"others": (0.1, 0.2)}, "sample 1: accel must be a number"),
        ((0.01, 0.1, "y"), {"others": (0.1, 0.2)}, "sample 1: vib must be a number"),
        ((0.01, 0.1, 9.8), {"others": (0.1,)}, "sample 1: 1 sample.s. in others"),
        ((0.01, 0.1, (9.8, 1.0)), {"others": (0.1, 0.2)}, "2 vibration sample"),
        ((math.nan, 0.1, 9.8), {"others": (0.1, 0.2)}, "sample 1: time nan"),
        ((0.01, 0.1, 9.8), {"others": (0.1, "z")}, "sample 1: others must be numbers"),
    ]:
        with pytest.raises(InputError, match=msg) as exc:
            dev.update(*args, **kw)
        assert "\n" not in str(exc.value)
    assert dev.n == 1  # refused samples change nothing
    dev.update(0.01, 0.1, 9.8, others=(0.1, 0.2))
    dev.finish()
    with pytest.raises(InputError, match="update after finish"):
        dev.update(0.02, 0.1, 9.8, others=(0.1, 0.2))
    with pytest.raises(InputError, match="fewer than 2 samples"):
        FuseTracker(cfg, None, dt=0.01).finish()
    with pytest.raises(InputError, match="sample 0: others given but no tracker"):
        FuseTracker(cfg, None, dt=0.01).update(0.0, 0.1, others=(0.1,))
    with pytest.raises(ParameterError, match="fuse Config"):
        FuseTracker(tc, tc)
    with pytest.raises(ParameterError, match="sample period"):
        FuseTracker(cfg, None)
    with pytest.raises(ParameterError, match="v0"):
        FuseTracker(cfg, None, dt=0.01, v0=math.inf)
    with pytest.raises(ParameterError, match="online=true"):
        config_for(rec, params={**P, "online": False})


def test_a_tracker_pickled_mid_stream_continues_with_the_batch_numbers():
    """A device that saves the tracker (pickle, the grid tracker inside it too) and loads it
    after a restart gets the batch numbers for the rest of the drive."""
    import pickle

    rec = _drive(duration=6.0)
    track = fuse.estimate(rec, params={"online": True, **P}, wheel_radius=R)
    cfg, tc = config_for(rec, params=P, wheel_radius=R)
    dev = FuseTracker(cfg, tc, level=start_level(rec["ay"], tc.tracker.model.dt))
    half = 320  # after the first fix: the filter has started, blocks are waiting
    out, _ = _feed(rec, dev, n=half)
    assert out and dev.blocks
    dev = pickle.loads(pickle.dumps(dev))
    g, s = rec["gps_speed"], rec["gps_sats"]
    ax, ay, az = rec["ax"], rec["ay"], rec["az"]
    for i in range(half, len(rec)):
        out += dev.update(rec.t[i], ax[i], ay[i], g[i], s[i], (ax[i], az[i]))
    out += dev.finish()
    assert [k for k, _ in out] == list(range(len(rec)))
    _assert_batch([e for _, e in out], track)
