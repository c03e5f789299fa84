"""fuse across a stretch without accelerometer samples while GPS goes on: the GPS receiver's
extra lag is not taught by GPS alone, and the vibration tracker's prediction in the stretch is
not a line."""

from __future__ import annotations

import numpy as np
import pytest

from vibrospeed.estimators import fuse
from vibrospeed.models.gps_riss import simulate_receiver
from vibrospeed.types import Recording, Track

R = 0.3


def _drive(T=60.0, fs=100.0, gap=(20.0, 40.0), seed=0):
    """Speed ``12 + 4 sin(2 pi t / 20)``, paper-receiver GPS at 10 Hz throughout, ax / ay NaN
    in ``gap``."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    v = 12.0 + 4.0 * np.sin(2 * np.pi * t / 20.0)
    hole = (t >= gap[0]) & (t < gap[1])
    ax = np.where(hole, np.nan, np.gradient(v, t) + 0.1 + 0.2 * rng.normal(size=t.size))
    ay = np.where(hole, np.nan, rng.normal(size=t.size))
    g = np.full(t.size, np.nan)
    g[::10] = simulate_receiver(t, v, fuse.Config().lag)[::10] + rng.normal(0, 0.1, t[::10].size)
    ch = {"ax": ax, "ay": ay, "speed_true": v, "gps_speed": g, "gps_sats": np.full(t.size, 9.0)}
    return Recording(t, ch, source="gap"), hole


def test_gps_without_the_accelerometer_leaves_the_extra_lag_alone():
    """The extra lag is a consider state at fusion samples without an accelerometer mean: its
    mean stays put (its transition is the identity) and its variance grows by ``q_gps_lag dt``
    per sample exactly; with the accelerometer it learns."""
    rec, hole = _drive()
    cfg = fuse.Config()
    ends = fuse.fusion_samples(rec.t, np.isfinite(rec["gps_speed"]), cfg.fuse_rate)
    arrays = {"t": rec.t[ends], "accel": fuse.method._block_mean(rec["ax"], ends),
              "gps_speed": rec["gps_speed"][ends], "gps_sats": rec["gps_sats"][ends]}
    _, o = fuse.run(cfg, arrays)
    off = np.isnan(arrays["accel"])
    idx = np.flatnonzero(off)
    assert idx.size > 400 and np.all(np.diff(idx) == 1)
    k0 = idx[0] - 1  # the last sample with the accelerometer
    np.testing.assert_array_equal(o.xf[idx, -1], o.xf[k0, -1])
    dt = np.diff(arrays["t"][k0:idx[-1] + 1])
    want = o.Pf[k0, -1, -1] + cfg.q_gps_lag * np.cumsum(dt)
    np.testing.assert_allclose(o.Pf[idx, -1, -1], want, rtol=1e-9)
    assert np.ptp(o.xf[:k0, -1]) > 1e-3  # learned where the accelerometer is


def test_no_line_where_the_vibration_axis_has_no_sample():
    """A tracker predicts through NaN samples and may go on claiming its last line there (the
    grid tracker does); fuse takes no line and no stop where the vibration axis is NaN, and the
    speed follows GPS there."""
    rec, hole = _drive()
    v = rec["speed_true"]
    om = v / R
    i0 = int(np.argmax(hole))
    om = np.where(hole, om[i0], om)  # the tracker's stale line in the hole
    vib = Track.from_omega(rec.t, om, np.full(om.size, 0.2), method="grid",
                           extras={"has_signal": np.ones(om.size)})
    tr = fuse.estimate(rec, vibration=vib, wheel_radius=R)
    used = np.isfinite(tr.extras["harmonic"])  # k of the wheel-frequency update; NaN: none
    assert np.mean(used[~hole]) > 0.5
    assert not np.any(used[hole])
    assert not np.any(tr.extras["source"][hole] == fuse.SRC_VIBRATION)
    err = np.abs(tr.speed - v)[hole]
    assert np.sqrt(np.mean(err ** 2)) < 0.15


@pytest.mark.slow
def test_a_minute_without_the_accelerometer_costs_no_more_than_gps_alone():
    """Simulated car, every IMU channel NaN for 60 s, GPS throughout: the offline fused speed
    there is at least as good as gps-riss's (GPS and accelerometer, here GPS alone) and its band
    holds the truth."""
    from vibrospeed import sim
    from vibrospeed.estimators import get

    r = sim.simulate("car", seed=1, duration=120)
    k = (r.t >= 30) & (r.t < 90)
    for c in ("ax", "ay", "az", "gx", "gy", "gz"):
        r.channels[c] = np.where(k, np.nan, r[c])
    truth = r["speed_true"]
    tr = get("fuse").estimate(r)
    ref = get("gps-riss").estimate(r)
    for lo, hi in ((30, 90), (90, 120)):
        m = (r.t >= lo) & (r.t < hi)
        rmse = np.sqrt(np.mean((tr.speed[m] - truth[m]) ** 2))
        rmse_gps = np.sqrt(np.mean((ref.speed[m] - truth[m]) ** 2))
        assert rmse <= rmse_gps
        inband = np.mean((truth[m] >= tr.speed_lo[m]) & (truth[m] <= tr.speed_hi[m]))
        assert inband >= 0.9


def test_the_smoothed_speed_is_projected_onto_zero(monkeypatch):
    """Offline, where the RTS smoother leaves ``v < 0`` (here a GPS that reports -1 m/s, an
    app's "no fix", read unconverted through the API) the smoothed state is projected onto
    ``v = 0`` as the filter projects its own (``x <- x - P[:, v] v / P_vv``, P unchanged); the
    band keeps ``speed_lo <= speed <= speed_hi``."""
    from dataclasses import replace

    from vibrospeed import sim
    from vibrospeed.estimators.fuse import method

    r = sim.simulate("car", seed=1, duration=120)
    g = r["gps_speed"].copy()
    g[(r.t >= 40) & (r.t < 70) & np.isfinite(g)] = -1.0
    r.channels["gps_speed"] = g
    seen = {}

    def spy(cfg, o):
        seen["cfg"], seen["o"] = cfg, o
        seen["out"] = fuse.smooth(cfg, o)
        return seen["out"]

    monkeypatch.setattr(method, "smooth", spy)
    tr = fuse.estimate(r)
    assert np.all(tr.speed >= 0.0)
    assert np.all((tr.speed_lo <= tr.speed) & (tr.speed <= tr.speed_hi))
    xs, Ps = seen["out"]
    raw, Praw = fuse.smooth(replace(seen["cfg"], nonneg=False), seen["o"])
    np.testing.assert_array_equal(Ps, Praw)
    neg = raw[:, 0] < 0.0
    assert neg.sum() > 10
    np.testing.assert_array_equal(xs[~neg], raw[~neg])
    want = raw[neg] - Praw[neg, :, 0] * (raw[neg, 0] / Praw[neg, 0, 0])[:, None]
    np.testing.assert_allclose(xs[neg], want, atol=1e-12)
    assert np.all(xs[neg, 0] == 0.0)
