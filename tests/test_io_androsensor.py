"""AndroSensor reader on the quat_orient_corolla trip, and the refusal of vibration methods."""

from pathlib import Path

import numpy as np
import pytest

from vibrospeed import io
from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.estimators import ekf

TRIP = Path(__file__).resolve().parents[2] / "shared/datasets/quat_orient_corolla"
ACC = TRIP / "accel.2020-10-15-21.csv"


@pytest.mark.skipif(not ACC.exists(), reason="quat_orient_corolla not available")
def test_real_trip_units_gps_and_refusal():
    rec = io.read(ACC)  # auto-detected
    assert abs(rec.fs - 16.7) < 0.5
    assert 9.0 < np.median(rec["az"]) < 10.5  # gravity on the device z axis (phone flat-ish)
    v = rec["gps_speed"][np.isfinite(rec["gps_speed"])]
    assert 250 < v.size < 400 and 0 <= v.min() and v.max() < 30  # km/h -> m/s
    assert np.all(rec["gps_sats"][np.isfinite(rec["gps_sats"])] >= 4)
    with pytest.raises(ParameterError, match="too low"):
        ekf.estimate(io.timebase.resample_uniform(rec), axis="y")


def test_synthetic_pair_and_errors(tmp_path):
    acc = tmp_path / "accel.trip.csv"
    acc.write_text("Time since start in ms ,ACCELEROMETER X (m/s²),ACCELEROMETER Y (m/s²),"
                   "ACCELEROMETER Z (m/s²)\n" + "".join(f"{k * 10},0.1,0.2,9.8\n"
                                                         for k in range(100)))
    (tmp_path / "gps.trip.csv").write_text(
        "Time since start in ms ,LOCATION Latitude : ,LOCATION Longitude : ,LOCATION Speed ( Kmh),"
        "LOCATION ORIENTATION (°),Satellites in range,LOCATION Altitude ( m)\n"
        "204,1,2,36.0,0,9,5\n503,1,2,72.0,0,10,5\n")
    rec = io.read(acc)
    assert rec.t[1] == pytest.approx(0.01)
    g = rec["gps_speed"]
    assert g[20] == pytest.approx(10.0) and g[50] == pytest.approx(20.0)
    assert np.count_nonzero(np.isfinite(g)) == 2 and rec["gps_sats"][50] == 10
    bad = tmp_path / "accel.bad.csv"
    bad.write_text(acc.read_text().replace("0.2,9.8\n", "x,9.8\n", 1))
    with pytest.raises(ReaderError, match="line 2"):
        io.read(bad, "androsensor")


def test_fixes_in_an_accelerometer_gap_and_on_one_sample(tmp_path):
    """The accelerometer stops for 5 s while GPS goes on at 1 Hz: each fix is placed once at its
    own time on a row of its own (the accelerometer NaN there), not piled onto the gap's edge
    samples; two fixes 2 ms apart share a sample, and the one dropped is noted."""
    ta = [k * 60 for k in range(200) if not 3000 <= k * 60 < 8000]  # ms, ~16.7 Hz
    acc = tmp_path / "accel.trip.csv"
    acc.write_text("Time since start in ms ,ACCELEROMETER X (m/s²),ACCELEROMETER Y (m/s²),"
                   "ACCELEROMETER Z (m/s²)\n" + "".join(f"{k},0.1,0.2,9.8\n" for k in ta))
    fixes = [(1000, 36.0), (1002, 54.0), (3500, 72.0), (5500, 90.0), (7500, 108.0)]
    (tmp_path / "gps.trip.csv").write_text(
        "Time since start in ms ,LOCATION Latitude : ,LOCATION Longitude : ,LOCATION Speed ( Kmh),"
        "LOCATION ORIENTATION (°),Satellites in range,LOCATION Altitude ( m)\n"
        + "".join(f"{t},1,2,{v},0,9,5\n" for t, v in fixes))
    rec = io.read(acc)
    g = rec["gps_speed"]
    fin = np.isfinite(g)
    np.testing.assert_allclose(rec.t[fin], [1.02, 3.5, 5.5, 7.5])  # 1.0/1.002 -> sample 1.02
    np.testing.assert_allclose(g[fin], [15.0, 20.0, 25.0, 30.0])
    added = np.isin(rec.t, [3.5, 5.5, 7.5])
    assert len(rec) == len(ta) + 3 and np.all(np.isnan(rec["ay"][added]))
    assert np.all(rec["ay"][~added] == 0.2)
    notes = "\n".join(rec.notes)
    assert "3 valid GPS fix(es) inside accelerometer gaps" in notes
    assert "1 GPS fix(es) fell on the same accelerometer sample" in notes
    assert "1 time gap(s) longer than 3 periods, longest 5.1 s (first at t = 2.94 s)" in notes
