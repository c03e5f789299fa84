"""fuse walked through on real-recording situations: the standstill column (a stop the tracker
reports while GPS says the vehicle moves) and a log too slow to carry a wheel line."""

from __future__ import annotations

import numpy as np

from vibrospeed.estimators import fuse
from vibrospeed.types import Recording, Track

FS = 100.0


def _drive(T=30.0, fs=FS, seed=0):
    """0-6 s standing, 6-10 s accelerating at 1.925 m/s^2, then 7.7 m/s; ``ax`` the
    acceleration plus noise, GPS at 1 Hz (the true speed, 9 satellites)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    v = np.clip((t - 6.0) * 1.925, 0.0, 7.7)
    a = np.where((t >= 6.0) & (t < 10.0), 1.925, 0.0)
    g = np.full(t.size, np.nan)
    g[::int(fs)] = v[::int(fs)]
    ch = {"ax": a + 0.05 * rng.normal(size=t.size), "ay": rng.normal(size=t.size),
          "gps_speed": g, "gps_sats": np.full(t.size, 9.0), "speed_true": v}
    return Recording(t, ch, source="drive.csv")


def test_standstill_column_is_the_fused_stop_not_the_trackers():
    """The Hungary drive rsq_q2_00 had standstill=1 at 34-37 s beside a GPS speed of 7.7 m/s:
    the filter had vetoed the tracker's stop (source gps), but the column was the tracker's.
    The column is fuse's stop (source 3); the tracker's own is standstill_vib."""
    rec = _drive()
    t = rec.t
    claim_stop = (t < 6.0) | ((t >= 16.0) & (t < 20.0))  # the second one: a smooth cruise
    vib = Track.from_omega(t, np.zeros(t.size), np.full(t.size, 5.0), method="grid",
                           extras={"has_signal": np.zeros(t.size),
                                   "standstill": claim_stop.astype(np.float64)})
    tr = fuse.estimate(rec, vibration=vib)
    cruise = (t >= 16.0) & (t < 20.0)
    assert np.all(np.abs(tr.speed[cruise] - 7.7) < 0.2)
    assert not np.any(tr.extras["standstill"][cruise] > 0.5)
    assert np.array_equal(tr.extras["standstill"] > 0.5, tr.extras["source"] == fuse.SRC_STANDSTILL)
    stop = (t >= 0.5) & (t < 5.5)
    assert np.mean(tr.extras["standstill"][stop] > 0.5) > 0.95
    assert np.array_equal(tr.extras["standstill_vib"], claim_stop.astype(np.float64))


def test_a_log_too_slow_for_a_wheel_line_fuses_gps_and_the_accelerometer():
    """quat_orient_corolla (AndroSensor, 16.67 Hz) picked fuse by default and failed with the
    tracker's "16.67 Hz is too low for omega up to 120 rad/s": GPS and the accelerometer are
    there, so fuse runs on them with its vibration part off and a note that says so."""
    import pytest

    from vibrospeed.errors import ParameterError

    rec = _drive(fs=50.0 / 3.0)
    tr = fuse.estimate(rec)
    assert any("16.67 Hz is too low for omega up to omega_max = 120 rad/s" in n
               and "vibration part off" in n
               and "omega_max=51" in n for n in tr.notes)
    assert not any("learned wheel radius" in n or "omega is left empty" in n for n in tr.notes)
    assert np.all(tr.extras["has_signal"] == 0) and np.all(np.isnan(tr.extras["omega_vib"]))
    assert not np.any(tr.extras["source"] == fuse.SRC_VIBRATION)
    moving = rec.t >= 12.0
    assert np.all(np.abs(tr.speed[moving] - 7.7) < 0.3)
    assert np.isnan(tr.omega).all()  # no radius learned: no wheel speed
    online = fuse.estimate(rec, params={"online": "true"})  # the posterior read needs none
    assert np.all(np.abs(online.speed[moving] - 7.7) < 0.5)
    # without GPS nothing but the accelerometer would be left: one line that says so
    nogps = rec.with_channels(gps_speed=np.full(len(rec), np.nan))
    with pytest.raises(ParameterError, match=r"drive.csv: sample rate 16.67 Hz .* no GPS speed"):
        fuse.estimate(nogps, wheel_radius=0.31)
    # an omega_max the rate cannot carry, asked for: the tracker's error stands
    with pytest.raises(ParameterError, match="lower omega_max"):
        fuse.estimate(rec, params={"omega_max": 100.0})


def test_a_lateral_accel_axis_is_noted_with_the_axis_that_follows_gps():
    """A phone lying flat (phyphox: y forward) under fuse's default accel_axis=x: the Hungary
    drive rsq_q3_00 left its 1 Hz GPS by up to 11.7 m/s, without a word. The speed changes
    of x hardly correlate with the GPS speed's, those of y do: a note names y."""
    rng = np.random.default_rng(3)
    fs = 50.0
    t = np.arange(0.0, 80.0, 1.0 / fs)
    v = 10.0 + 3.0 * np.sin(2 * np.pi * t / 20.0)
    along = np.gradient(v, t)
    g = np.full(t.size, np.nan)
    g[::int(fs)] = v[::int(fs)]
    rec = Recording(t, {"ax": 0.3 * rng.normal(size=t.size), "ay": along + 0.3 * rng.normal(
        size=t.size), "az": 9.81 + 0.3 * rng.normal(size=t.size), "gps_speed": g}, source="flat")
    vib = Track.from_omega(t, np.zeros(t.size), np.full(t.size, 5.0), method="grid",
                           extras={"has_signal": np.zeros(t.size)})
    notes = fuse.estimate(rec, vibration=vib).notes
    hint = [n for n in notes if "hardly follow" in n]
    assert len(hint) == 1 and "'ax'" in hint[0] and "-p accel_axis=ay " in hint[0]
    assert not any("hardly follow" in n for n in fuse.estimate(
        rec, vibration=vib, params={"accel_axis": "y"}).notes)
