"""The grid method without its "no line" state (``off_rate=0``, the paper's switching-free
filter) on a drive with stops: the stops still apply, and nothing is claimed."""

import numpy as np

from vibrospeed.estimators import grid
from vibrospeed.sim import simulate


def test_without_the_null_state_stops_still_apply():
    rec = simulate("random", seed=0, duration=30)
    lo, hi = rec.meta["omega_range"]
    tr = grid.estimate(rec, params={"off_rate": 0, "omega_min": lo, "omega_max": hi,
                                    "n_grid": 60})
    still = tr.extras["standstill"] > 0.5
    assert "has_signal" not in tr.extras
    assert still.any() and not still.all()
    assert np.all(tr.omega[still] == 0.0)
    standing = rec["omega_true"] == 0
    assert np.mean(standing[still]) > 0.9  # declared where the truth stands
