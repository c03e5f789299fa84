"""``fuse`` with a fixed lag (``params={"lag": S}``): the grid tracker's fixed-lag smoother
read by the forward filter with the offline reading of lines (they do not trail the speed)."""

import math

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import fuse, get


@pytest.fixture(scope="module")
def drive():
    rec = sim.simulate("car", seed=2, duration=60)
    g = rec.channel("gps_speed").copy()
    g[(rec.t >= 30.0) & (rec.t < 50.0)] = np.nan  # an outage after the radius is learned
    rec.channels["gps_speed"] = g
    return rec


def test_lag_runs_the_fixed_lag_tracker_and_the_forward_filter(drive):
    out = fuse.estimate(drive, params={"lag": 2})
    trk = get("grid").estimate(drive, params={**fuse.TRACKER_DEFAULTS, "smooth": "lag",
                                              "lag": 2.0})
    np.testing.assert_array_equal(out.extras["omega_vib"], trk.omega)
    # the lines are read as offline (no lag, no acceleration limit, claimed lines only), by
    # the forward filter: the numbers of an online run given that track and those settings
    offline = fuse.Config()
    ref = fuse.estimate(drive, vibration=trk, params={
        "online": True, "vib_lag": offline.vib_lag, "vib_spread": offline.vib_spread,
        "vib_amax": offline.vib_amax, "vib_soft": offline.vib_soft,
        "vib_measure": offline.vib_measure})
    np.testing.assert_array_equal(out.speed, ref.speed)
    np.testing.assert_array_equal(out.speed_std, ref.speed_std)
    assert out.params["lag"] == 2.0 and out.params["online"] is True
    assert out.params["vib_lag"] == 0.0 and out.params["vib_amax"] == math.inf
    # in the outage the wheel's lines are taken (the causal tracker's are not, here) and the
    # speed stays within 3 % of the truth
    v = drive.channel("speed_true")
    m = (drive.t >= 31.0) & (drive.t < 50.0)
    assert np.mean(out.extras["source"][m] == fuse.SRC_VIBRATION) > 0.3
    assert np.mean(np.abs(out.speed[m] - v[m]) <= 0.03 * v[m]) > 0.95
    assert abs(out.params["learned_radius"] / drive.meta["config"]["wheel_radius"] - 1.0) < 0.01


@pytest.mark.parametrize("bad", [0, -1.0, "x", True, math.inf, math.nan])
def test_lag_must_be_a_positive_delay(drive, bad):
    with pytest.raises(ParameterError, match="lag must be a delay in s > 0"):
        fuse.estimate(drive, params={"lag": bad})
