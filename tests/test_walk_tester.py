"""A vehicle tester's walkthrough: evaluation against references with gaps and other radii,
``fuse``'s radius carried between drives (``radius_from``): numbers against hand-computed ones."""

import numpy as np
import pytest

from vibrospeed.eval.metrics import evaluate
from vibrospeed.types import Recording, Track

# -- evaluate ------------------------------------------------------------------------------------


def test_a_dropped_reference_is_no_truth_not_a_straight_line():
    """A 10 s stretch of NaN in a 10 Hz reference (10 m/s before, 30 m/s after) is not bridged:
    the estimate there (held at 10 m/s) is not scored against a made-up 10 -> 30 ramp."""
    t = np.arange(0.0, 30.0, 0.1)
    v = np.where(t < 20.0, 10.0, 30.0)
    ref = np.where((t >= 10.0) & (t < 20.0), np.nan, v)
    truth = Recording(t, {"speed_true": ref}, source="ref.csv")
    est = Track.from_speed(t, np.where(t < 20.0, 10.0, 30.0) + 0.2, np.full(t.size, 0.1))
    m = evaluate(est, truth)
    assert m.unit == "m/s"
    assert m.n == 200  # the 100 samples of the gap are not scored (before: all 300)
    assert m.rmse == pytest.approx(0.2)
    assert m.bias == pytest.approx(0.2)


def test_a_short_nan_run_in_the_reference_is_still_bridged():
    """Two NaN samples in a 100 Hz reference (3 periods < 5) are interpolated as before."""
    t = np.arange(0.0, 2.0, 0.01)
    ref = 5.0 + t
    ref[50:52] = np.nan
    truth = Recording(t, {"speed_true": ref})
    m = evaluate(Track.from_speed(t, 5.0 + t, np.full(t.size, 0.1)), truth)
    assert m.n == t.size and m.rmse == pytest.approx(0.0, abs=1e-12)


def test_rmse_speed_is_the_speed_error_when_the_track_has_another_radius():
    """A fuse track whose learned radius (0.1 m) is not the truth's wheel (0.3 m): its speed is
    0.5 m/s high throughout, so the speed RMSE is 0.5 m/s, whatever its omega column says
    (before: the omega error times 0.1 m, 2.2 m/s here)."""
    t = np.arange(0.0, 10.0, 0.1)
    v = 10.0 + t
    truth = Recording(t, {"omega_true": v / 0.3, "speed_true": v}, wheel_radius=0.3)
    est = Track.from_speed(t, v + 0.5, np.full(t.size, 0.2), wheel_radius=0.1)
    m = evaluate(est, truth)
    assert m.unit == "rad/s"  # scored as wheel speeds (the truth has omega_true)
    assert m.rmse_speed == pytest.approx(0.5)
    # omega_true with the truth's radius, no speed_true: the same
    truth2 = Recording(t, {"omega_true": v / 0.3}, wheel_radius=0.3)
    assert evaluate(est, truth2).rmse_speed == pytest.approx(0.5)
