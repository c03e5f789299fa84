"""io.timebase.check_fundamental: the one "fundamental above Nyquist" check and its wording,
used by the grid tracker (grid.app.prepare) and the aided RBPMF tracker alike."""

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import aided_grid, grid
from vibrospeed.io.timebase import check_fundamental
from vibrospeed.types import Recording


def test_the_limit_is_pi_fs_and_the_message_names_source_rate_range_and_need():
    check_fundamental(100.0, 314.0, "a.csv")  # pi * 100 = 314.159...: just below, fine
    with pytest.raises(ParameterError) as exc:
        check_fundamental(100.0, 315.0, "a.csv")
    msg = str(exc.value)
    # 315 / pi = 100.27 Hz needed; pi * 100 = 314.2 rad/s the most this rate carries
    assert msg == ("a.csv: sample rate 100 Hz is too low for omega up to omega_max = 315 rad/s "
                   "(the fundamental needs fs > 100.3 Hz; lower omega_max below 314.2 rad/s)")
    with pytest.raises(ParameterError, match=r"^sample rate 10 Hz"):  # no source: no prefix
        check_fundamental(10.0, 10.0 * np.pi)  # equal to the limit: refused


def _slow_log() -> Recording:
    """A 20 Hz log (pi fs = 62.8 rad/s) that knows its wheel radius."""
    t = np.arange(200) / 20.0
    y = np.sin(2 * np.pi * 3.0 * t)
    return Recording(t, {"ay": y, "ax": 0.1 * y, "az": 0.2 * y}, source="slow.csv",
                     wheel_radius=0.3)


def test_grid_and_the_aided_rbpmf_tracker_refuse_alike():
    rec = _slow_log()
    want = ("slow.csv: sample rate 20 Hz is too low for omega up to omega_max = 70 rad/s "
            "(the fundamental needs fs > 22.28 Hz; lower omega_max below 62.83 rad/s)")
    with pytest.raises(ParameterError) as g:
        grid.estimate(rec, params={"omega_max": 70.0})
    with pytest.raises(ParameterError) as a:
        aided_grid.estimate(rec, params={"omega_max": 70.0}, kind="rbpmf")
    with pytest.raises(ParameterError) as ag:
        aided_grid.estimate(rec, params={"omega_max": 70.0}, kind="grid")
    assert str(g.value) == str(a.value) == str(ag.value) == want
