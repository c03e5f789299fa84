"""The streamed ``vibrospeed estimate`` (a long log, read in chunks and estimated in blocks)
against the whole-log path: the plot's truth and GPS overlays and the recording's notes; and
the online tracker's speed with a wheel radius against the batch Track's."""

from __future__ import annotations

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid, rbpmf
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.online import OnlineTracker

P = {"smooth": "none", "omega_min": 2, "omega_max": 30}


# ---- the online tracker's speed ------------------------------------------------------------
def test_online_speed_with_a_wheel_radius_is_the_batch_tracks():
    """``wheel_radius=``: speed, its std and band are r times omega's, bitwise the speed
    columns of the causal batch Track estimated with the same radius (stops included: 0
    there); without a radius speed stays NaN and omega is the same."""
    rec = sim.simulate("stop_and_go", seed=6, duration=22)
    r = 0.2837
    batch = grid.estimate(rec, axis="y", params=P, wheel_radius=r)
    assert (batch.extras["standstill"] > 0.5).any() and np.isfinite(batch.speed).all()
    cfg = grid.config_for(rec, params=P)
    lvl = start_level(rec["ay"], cfg.tracker.model.dt)
    trk = OnlineTracker(grid, cfg, level=lvl, standstill=3, wheel_radius=r)
    got = [trk.update(float(a), (x, z)) for a, x, z in zip(rec["ay"], rec["ax"], rec["az"],
                                                           strict=True)]
    for k in ("speed", "speed_std", "speed_lo", "speed_hi", "omega"):
        np.testing.assert_array_equal([getattr(e, k) for e in got], getattr(batch, k))
    plain = OnlineTracker(grid, cfg, level=lvl)
    old = [plain.update(float(a)) for a in rec["ay"][:300]]
    assert np.isnan([e.speed for e in old]).all()
    assert not hasattr(old[0], "speed_lo")
    np.testing.assert_array_equal([e.omega for e in old], batch.omega[:300])


def test_online_speed_rbpmf_and_a_bad_radius():
    rec = sim.simulate("cart", seed=1, duration=8)
    p = {"omega_min": 2, "omega_max": 30}
    batch = rbpmf.estimate(rec, axis="y", params=p, wheel_radius=0.3)
    cfg = rbpmf.config_for(rec, params=p)
    trk = OnlineTracker(rbpmf, cfg, level=start_level(rec["ay"], cfg.model.dt),
                        wheel_radius=0.3)
    got = [trk.update(float(a)) for a in rec["ay"]]
    np.testing.assert_array_equal([e.omega for e in got], batch.omega)
    np.testing.assert_array_equal([e.speed for e in got], batch.speed)
    np.testing.assert_array_equal([e.speed_hi for e in got], batch.speed_hi)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ParameterError, match="wheel_radius"):
            OnlineTracker(rbpmf, cfg, wheel_radius=bad)
