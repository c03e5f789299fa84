"""GPS fixes inside accelerometer gaps, the same for every reader with GPS: each valid fix gets a
row of its own and one note (timebase.merge_fix_rows); a "no fix" (-1 speed) gets no row and its
note once (_common.negative_as_no_fix, not again in finish)."""

import numpy as np
import pytest

from vibrospeed import io
from vibrospeed.io._common import negative_as_no_fix
from vibrospeed.io.timebase import merge_fix_rows

TA = np.round(np.arange(1000) * 0.01, 2)
TA = TA[(TA < 3.0) | (TA >= 8.0)]  # accelerometer at 100 Hz, silent in [3, 8) s
FIXES = [(0.5, 4.0), (3.5, 5.0), (4.5, -1.0), (5.5, 6.0), (6.5, 7.0), (9.0, 9.0)]  # (s, m/s)
IN_GAP = [3.5, 5.5, 6.5]  # the valid fixes inside the gap; 4.5 s is -1: no fix


def _phyphox(d):
    d.mkdir()
    (d / "Accelerometer.csv").write_text(
        '"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)"\n'
        + "".join(f"{t!r},0.5,1.0,9.81\n" for t in TA.tolist()))
    (d / "Location.csv").write_text(
        '"Time (s)","Latitude (°)","Longitude (°)","Height (m)","Velocity (m/s)",'
        '"Direction (°)","Horizontal Accuracy (m)","Vertical Accuracy (°)"\n'
        + "".join(f"{t},47.6,17.6,110,{v},0,5,5\n" for t, v in FIXES))
    return d


def _sensorlogger(d):
    d.mkdir()
    ns = 1_700_000_000 * 10**9
    (d / "TotalAcceleration.csv").write_text(
        "time,seconds_elapsed,z,y,x\n"
        + "".join(f"{ns + round(t * 1e9)},{t!r},9.81,1.0,0.5\n" for t in TA.tolist()))
    (d / "Location.csv").write_text(
        "time,seconds_elapsed,horizontalAccuracy,speed,altitude,longitude,latitude\n"
        + "".join(f"{ns + round(t * 1e9)},{t},3.0,{v},120,17.6,47.6\n" for t, v in FIXES))
    return d


def _androsensor(d):
    d.mkdir()
    acc = d / "accel.trip.csv"
    acc.write_text("Time since start in ms ,ACCELEROMETER X (m/s²),ACCELEROMETER Y (m/s²),"
                   "ACCELEROMETER Z (m/s²)\n"
                   + "".join(f"{round(t * 1000)},0.5,1.0,9.81\n" for t in TA.tolist()))
    (d / "gps.trip.csv").write_text(
        "Time since start in ms ,LOCATION Latitude : ,LOCATION Longitude : ,LOCATION Speed ( Kmh),"
        "LOCATION ORIENTATION (°),Satellites in range,LOCATION Altitude ( m)\n"
        + "".join(f"{round(t * 1000)},1,2,{v * 3.6 if v >= 0 else -1},0,9,5\n"
                  for t, v in FIXES))
    return acc


def _sensorfusion(d):
    d.mkdir()
    t0 = 1_446_211_006_000
    lines = [(round(t * 1000), "ACC\t0.5\t1.0\t9.81") for t in TA.tolist()]
    lines += [(round(t * 1000), "GPS\t58.1\t15.57\t100") for t, v in FIXES if v >= 0]
    p = d / "sensorLog.txt"
    p.write_text("".join(f"{t0 + ms}\t{s}\n" for ms, s in sorted(lines)))
    return p


def _rosbag(d):
    pytest.importorskip("rosbags")
    from test_io_rosbag import _write  # IMU 100 Hz for 2 s, GNSS at 10 Hz

    return _write(d / "bag", imu_gap=range(60, 140))


# reader -> (builder, fix times that get a row of their own, master name in the note)
CASES = {
    "phyphox": (_phyphox, IN_GAP, "accelerometer"),
    "sensorlogger": (_sensorlogger, IN_GAP, "accelerometer"),
    "androsensor": (_androsensor, IN_GAP, "accelerometer"),
    "sensorfusion": (_sensorfusion, IN_GAP, "accelerometer"),
    "rosbag": (_rosbag, list(np.arange(65, 140, 10) * 0.01), "IMU"),
}


@pytest.mark.parametrize("fmt", sorted(CASES))
def test_one_gap_note_per_reader(tmp_path, fmt):
    """Every reader with GPS gives the same single note (count, gap threshold = 3 median
    periods of the 100 Hz master = 0.03 s, master NaN there) and the added times in meta."""
    build, want, master = CASES[fmt]
    rec = io.read(build(tmp_path / "log"), fmt)
    note = (f"{len(want)} valid GPS fix(es) inside {master} gaps (intervals > 3 median periods, "
            f"0.03 s) kept on rows of their own at the fix times, the {master} NaN there "
            "(their times in meta 'fix_rows')")
    assert [n for n in rec.notes if "fix(es) inside" in n] == [note]
    np.testing.assert_allclose(rec.meta["fix_rows"], want, atol=1e-9)
    added = np.isin(np.round(rec.t, 6), np.round(want, 6))
    assert added.sum() == len(want) and np.all(np.isnan(rec["ax"][added]))
    assert np.all(np.isfinite(rec["ax"][~added]))
    assert sum("time gap(s)" in n for n in rec.notes) == 1  # the master's one gap, once


@pytest.mark.parametrize("fmt", ["phyphox", "sensorlogger", "androsensor"])
def test_a_no_fix_inside_a_gap_gets_no_row(tmp_path, fmt):
    """The -1 fix at 4.5 s (inside the gap) is no fix: no row of its own, gps_speed NaN
    everywhere near it, and the -1 note given once (by the reader, not again by finish)."""
    build, want, _ = CASES[fmt]
    rec = io.read(build(tmp_path / "log"), fmt)
    assert len(rec) == TA.size + len(want)
    assert not np.any(np.abs(rec.t - 4.5) < 0.5)  # rows at 3.5 and 5.5 s, none between
    g = rec["gps_speed"]
    fin = np.isfinite(g)
    np.testing.assert_allclose(rec.t[fin], [t for t, v in FIXES if v >= 0], atol=0.006)
    np.testing.assert_allclose(g[fin], [v for t, v in FIXES if v >= 0], rtol=1e-12)
    assert sum("gps_speed: 1 negative value(s) read as no fix" in n for n in rec.notes) == 1


def test_merge_fix_rows_without_a_gap_or_lines():
    """No fix inside a gap: the inputs back unchanged, no note, no meta; ``lines`` None stays
    None when rows are added."""
    t = np.arange(10) * 0.1
    ch = {"ax": np.ones(10)}
    t2, ch2, ln, notes, meta = merge_fix_rows(t, [0.25, 0.5], ch, np.arange(10) + 2)
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(ln, np.arange(10) + 2)
    assert notes == [] and meta == {} and ch2["ax"] is ch["ax"]
    t = np.r_[0:5, 10:15] * 0.1
    t2, ch2, ln, notes, meta = merge_fix_rows(t, [0.75], {"ax": np.ones(10)})
    assert ln is None and meta == {"fix_rows": [0.75]} and len(notes) == 1
    np.testing.assert_array_equal(t2, np.r_[t[:5], 0.75, t[5:]])
    assert np.isnan(ch2["ax"][5]) and np.count_nonzero(np.isnan(ch2["ax"])) == 1


def test_negative_as_no_fix():
    y, notes = negative_as_no_fix("gps_speed", np.array([1.0, -1.0, np.nan, 0.0, -0.5]))
    np.testing.assert_array_equal(y, [1.0, np.nan, np.nan, 0.0, np.nan])
    assert notes == ["gps_speed: 2 negative value(s) read as no fix (NaN; apps write -1 for "
                     "no fix)"]
    x = np.array([2.0, 3.0])
    y, notes = negative_as_no_fix("gps_hacc", x)
    assert notes == [] and np.array_equal(y, x)
