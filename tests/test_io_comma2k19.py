"""comma2k19 reader on the shared segment: layout, units, signs, bad input."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vibrospeed.errors import ReaderError
from vibrospeed.io.comma2k19 import read_comma2k19
from vibrospeed.types import WHEEL_CHANNELS

SEG = Path(__file__).resolve().parents[2] / "shared/datasets/comma2k19_example/segment_40"
pytestmark = pytest.mark.skipif(not SEG.exists(), reason="comma2k19 example not available")


@pytest.fixture(scope="module")
def rec():
    return read_comma2k19(SEG)


def test_channels_units_and_time(rec):
    for name in ("gz", "ax", "ay", "speed_true", "gps_speed", *WHEEL_CHANNELS):
        assert name in rec
    assert len(rec) == 4974 and rec.t[0] == 0.0 and np.all(np.diff(rec.t) > 0)
    assert 80 < rec.fs < 100  # CAN wheel speeds ~89 Hz
    assert rec.meta["L1"] > 0 and rec.wheel_radius == pytest.approx(0.362)


def test_wheel_speeds_match_decoded_can_kph(rec):
    """Independent source: the raw CAN frame 0x0aa decoded to kph, order fr fl rr rl."""
    raw = pd.read_csv(SEG / "decoded_can" / "can_0x0aa.csv")
    v_fl = rec["wheel_omega_fl"] * rec.wheel_radius
    v_rr = rec["wheel_omega_rr"] * rec.wheel_radius
    np.testing.assert_allclose(v_fl[:50], raw["ws_fl_kph"].to_numpy()[:50] / 3.6, atol=0.01)
    np.testing.assert_allclose(v_rr[:50], raw["ws_rr_kph"].to_numpy()[:50] / 3.6, atol=0.01)


def test_signs_kinematics(rec):
    # a_y ~ Vx * yaw rate (left +, CCW +) and a_x ~ dVx/dt, on smoothed signals
    k = np.ones(90) / 90
    v = rec["speed_true"]
    ok = np.isfinite(rec["ay"]) & np.isfinite(rec["gz"])
    ay = np.convolve(rec["ay"][ok], k, "valid")
    vr = np.convolve((v * rec["gz"])[ok], k, "valid")
    assert np.corrcoef(ay, vr)[0, 1] > 0.8
    ok = np.isfinite(rec["ax"])
    dv = np.convolve((np.gradient(v) / rec.dt)[ok], k, "valid")  # stamps jitter, rate does not
    assert np.corrcoef(np.convolve(rec["ax"][ok], k, "valid"), dv)[0, 1] > 0.9


def test_bad_folder(tmp_path):
    with pytest.raises(ReaderError, match="not a directory"):
        read_comma2k19(tmp_path / "nope")
    with pytest.raises(ReaderError, match="missing file"):
        read_comma2k19(tmp_path)
    d = tmp_path / "processed_log" / "CAN" / "wheel_speed"
    d.mkdir(parents=True)
    np.save(d / "t.npy", np.array([0.0, 1.0, 0.5]))
    (d / "t.npy").rename(d / "t")
    with pytest.raises(ReaderError, match="not increasing at index 2"):
        read_comma2k19(tmp_path)


def test_detect_and_auto_format(tmp_path):
    from vibrospeed import io
    from vibrospeed.io.comma2k19 import detect

    assert detect(SEG) and not detect(tmp_path) and not detect(tmp_path / "nope")
    assert not detect(SEG / "processed_log")  # a sub-folder is not a segment
    assert not detect(SEG.parents[1] / "f1tenth_frictionmaps" / "DS1")
    assert io.detect_format(SEG) == "comma2k19"
    assert len(io.read(SEG)) == 4974
