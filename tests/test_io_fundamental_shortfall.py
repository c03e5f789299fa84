"""io.timebase.fundamental_shortfall: one sentence for a rate too slow for the fundamental,
in the grid tracker's error (check_fundamental) and in fuse's note on a slow log (_too_slow)."""

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid
from vibrospeed.estimators.fuse.method import _too_slow
from vibrospeed.io.timebase import fundamental_shortfall
from vibrospeed.types import Recording


def test_the_sentence_and_its_limit():
    assert fundamental_shortfall(100.0, 314.0) is None  # pi * 100 = 314.159...
    assert fundamental_shortfall(100.0, 315.0, "do x") == (
        "sample rate 100 Hz is too low for omega up to omega_max = 315 rad/s "
        "(the fundamental needs fs > 100.3 Hz; do x)")  # 315 / pi = 100.27 Hz


def test_fuses_note_and_the_grid_trackers_error_say_it_alike():
    fs = 50.0 / 3.0  # an AndroSensor log: pi fs = 52.36 rad/s, below the default 120 rad/s
    t = np.arange(100) / fs
    y = np.sin(2 * np.pi * 2.0 * t)
    rec = Recording(t, {"ay": y, "ax": 0.1 * y, "az": 0.2 * y}, source="slow.csv")
    sentence = ("sample rate 16.67 Hz is too low for omega up to omega_max = 120 rad/s "
                "(the fundamental needs fs > 38.2 Hz")  # 120 / pi = 38.197 Hz
    # floor(52.36) - 1 = 51 rad/s: tracked below Nyquist
    assert _too_slow(rec, {}) == f"{sentence}; -p omega_max=51 tracks the lines below it)"
    assert _too_slow(rec, {"omega_min": "60"}) == f"{sentence})"  # 51 is no range above 60
    assert _too_slow(rec, {"omega_max": "50"}) is None  # asked for: the tracker's own error
    with pytest.raises(ParameterError) as exc:
        grid.estimate(rec, params={"omega_max": 120.0})
    # the hint where the note has its own: inside the parenthesis
    assert str(exc.value) == f"slow.csv: {sentence}; lower omega_max below 52.36 rad/s)"
