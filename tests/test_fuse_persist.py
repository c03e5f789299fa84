"""GPS that disagrees with the filter's speed for longer than a receiver jump pulls it back
(``Config.gps_persist``); a jump shorter than that stays weighted down."""

from __future__ import annotations

import math

import numpy as np

from vibrospeed.estimators import fuse


def _drive(g_of_t):
    """25 Hz fusion samples, a 10 Hz receiver reporting ``g_of_t``, an accelerometer reading
    0 throughout (it misses whatever change the receiver reports)."""
    t = np.arange(0.0, 12.0, 0.04)
    g = np.full(t.size, np.nan)
    fix = np.unique(np.round(np.arange(0.0, 12.0, 0.1) / 0.04).astype(int))
    fix = fix[fix < t.size]
    g[fix] = g_of_t(t[fix])
    return {"t": t, "accel": np.zeros(t.size), "gps_speed": g}


def _run(cfg, arrays):
    st = fuse.init(cfg, 10.0, p0_speed=0.01)
    return fuse.run(cfg, arrays, state=st)[1]


def test_persistent_disagreement_is_the_filters():
    # the receiver reports 20 m/s from 2 s on; the accelerometer saw no acceleration
    arrays = _drive(lambda t: np.where(t < 2.0, 10.0, 20.0))
    t = arrays["t"]
    late = (t >= 4.0) & (t < 12.0)
    o = _run(fuse.Config(), arrays)
    o_never = _run(fuse.Config(gps_persist=math.inf), arrays)
    # weighted down as an outlier at every fix, the speed is still far from the fixes
    assert np.max(np.abs(o_never.speed[late] - 20.0)) > 5.0
    # taken as the filter's drift after 1.5 s and 8 fixes: on the fixes and inside its band
    assert np.max(np.abs(o.speed[late] - 20.0)) < 0.1
    after = (t >= 3.6) & (t < 12.0)
    assert np.all(np.abs(o.speed[after] - 20.0) <= 2.326 * o.speed_std[after] + 0.1)


def test_short_jump_stays_an_outlier():
    # a receiver jump of +3 m/s for 1 s (paper section VI-c): shorter than gps_persist, so
    # the rule does not act and the speed moves as with the rule off
    arrays = _drive(lambda t: np.where((t >= 4.0) & (t < 5.0), 13.0, 10.0))
    o = _run(fuse.Config(), arrays)
    o_never = _run(fuse.Config(gps_persist=math.inf), arrays)
    np.testing.assert_allclose(o.speed, o_never.speed, rtol=0, atol=1e-12)
    assert np.max(np.abs(o.speed - 10.0)) < 1.0


def _drive_1hz(g_of_t, seconds=30.0):
    """As :func:`_drive` with a 1 Hz receiver (a phone's)."""
    t = np.arange(0.0, seconds, 0.04)
    g = np.full(t.size, np.nan)
    fix = np.round(np.arange(0.0, seconds, 1.0) / 0.04).astype(int)
    g[fix] = g_of_t(t[fix])
    return {"t": t, "accel": np.zeros(t.size), "gps_speed": g}


def test_a_slow_receivers_disagreement_needs_enough_fixes():
    # 1 Hz: a 5 s offset (5 fixes, longer than gps_persist) may be the receiver's own error
    # (a phone's last seconds): weighted down as with the rule off; from the 8th fix on the
    # same side (2^-7 by chance with white errors) it is the filter's
    short = _drive_1hz(lambda t: np.where((t >= 4.0) & (t < 9.0), 20.0, 10.0))
    o = _run(fuse.Config(), short)
    o_never = _run(fuse.Config(gps_persist=math.inf), short)
    np.testing.assert_allclose(o.speed, o_never.speed, rtol=0, atol=1e-12)
    long = _drive_1hz(lambda t: np.where(t >= 4.0, 20.0, 10.0))
    o = _run(fuse.Config(), long)
    o_never = _run(fuse.Config(gps_persist=math.inf), long)
    t = long["t"]
    # the rule acts at the 8th fix on the same side (11 s)
    before = t < 4.0 + fuse.core.PERSIST_FIXES - 1
    np.testing.assert_allclose(o.speed[before], o_never.speed[before], rtol=0, atol=1e-12)
    late = (t >= 4.0 + fuse.core.PERSIST_FIXES) & (t < 14.0)
    assert np.max(np.abs(o.speed[late] - 20.0)) < 0.5  # between 1 Hz fixes it drifts a little
    assert np.max(np.abs(o_never.speed[late] - 20.0)) > 1.0
