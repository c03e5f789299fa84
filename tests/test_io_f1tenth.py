"""F1/10 FrictionMaps reader on the shared runs: axes, units, irregular time, bad input."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vibrospeed.errors import ReaderError
from vibrospeed.io.f1tenth import read_f1tenth
from vibrospeed.types import WHEEL_CHANNELS

ROOT = Path(__file__).resolve().parents[2] / "shared/datasets/f1tenth_frictionmaps"
pytestmark = pytest.mark.skipif(not ROOT.exists(), reason="F1/10 data not available")


@pytest.fixture(scope="module")
def rec():
    return read_f1tenth(ROOT / "DS1")


def test_layout_units_and_irregular_time(rec):
    raw = pd.read_csv(ROOT / "DS1" / "imuData.csv")
    assert len(rec) == len(raw)
    for name in ("ax", "ay", "gz", "speed_true", *WHEEL_CHANNELS):
        assert name in rec
    assert not rec.is_uniform(0.05) and np.all(np.diff(rec.t) > 0)
    np.testing.assert_allclose(rec["gz"], np.deg2rad(raw["wz"].to_numpy()))
    np.testing.assert_allclose(rec["ay"], 9.80665 * raw["ax"].to_numpy())  # 'ax' is lateral
    np.testing.assert_allclose(rec["wheel_omega_fl"] * rec.wheel_radius, rec["speed_odom"])


def test_axes_by_kinematics(rec):
    v = rec["speed_odom"]
    ok = np.isfinite(v)
    assert np.corrcoef(rec["ay"][ok], (v * rec["gz"])[ok])[0, 1] > 0.8  # a_y ~ v * yaw rate
    k = np.ones(5) / 5
    dv = np.gradient(np.convolve(v[ok], k, "same"), rec.t[ok])
    assert np.corrcoef(np.convolve(rec["ax"][ok], k, "same"), dv)[0, 1] > 0.5


def test_particle_filter_speed_is_plausible(rec):
    s, o = rec["speed_true"], rec["speed_odom"]
    ok = np.isfinite(s) & np.isfinite(o)
    assert ok.mean() > 0.95
    assert np.corrcoef(s[ok], o[ok])[0, 1] > 0.5
    assert np.nanpercentile(np.abs(s), 99) < 8.0  # pose jumps of the localisation aside


def test_bad_input(tmp_path):
    with pytest.raises(ReaderError, match="not a directory"):
        read_f1tenth(tmp_path / "none")
    with pytest.raises(ReaderError, match="imuData.csv"):
        read_f1tenth(tmp_path)
    (tmp_path / "imuData.csv").write_text(",s,ns,ax,ay,wz\n0,1,0,0,0,0\n0,1,5,0,0,0\n0,0,0,0,0,0\n")
    with pytest.raises(ReaderError, match="line 4"):
        read_f1tenth(tmp_path)
    (tmp_path / "imuData.csv").write_text(",s,ns,ax,ay\n0,1,0,0,0\n")
    with pytest.raises(ReaderError, match="column 'wz'"):
        read_f1tenth(tmp_path)


def test_detect_and_auto_format(tmp_path):
    from vibrospeed import io
    from vibrospeed.io.f1tenth import detect

    assert detect(ROOT / "DS1") and detect(ROOT / "DS1" / "imuData.csv")
    assert not detect(ROOT / "DS1" / "commandData.csv") and not detect(ROOT)
    assert not detect(tmp_path) and not detect(tmp_path / "nope")
    for f in ("imuData.csv", "odomData.csv", "pfPoseData.csv"):
        (tmp_path / f).write_text(",s,ns,x\n0,1,0,0\n")
    assert not detect(tmp_path)  # no IMU columns
    assert io.detect_format(ROOT / "DS2") == "f1tenth"
    assert len(io.read(ROOT / "DS1")) == len(pd.read_csv(ROOT / "DS1" / "imuData.csv"))
