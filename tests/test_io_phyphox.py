"""phyphox exports: the real Hungary drive, and synthetic folders/zips with known answers."""

import math
import zipfile
from pathlib import Path

import numpy as np
import pytest

from vibrospeed.errors import ReaderError
from vibrospeed.io import detect_format, read
from vibrospeed.io.phyphox import is_phyphox, read_phyphox

DRIVE = Path(__file__).resolve().parents[2] / "shared/datasets/hungary_car_phyphox/rsq_q2_00"

_ACC_H = '"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)"\n'
_GYR_H = '"Time (s)","X (rad/s)","Y (rad/s)","Z (rad/s)"\n'
_LOC_H = ('"Time (s)","Latitude (\u00b0)","Longitude (\u00b0)","Height (m)","Velocity (m/s)",'
          '"Direction (\u00b0)","Horizontal Accuracy (m)","Vertical Accuracy (\u00b0)"\n')


def _export(folder: Path, *, repeat=False) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    ta = np.arange(200) * 0.01
    acc = [f"{t!r},{math.sin(t)!r},{2 * t!r},9.81\n" for t in ta.tolist()]
    if repeat:
        acc.insert(51, acc[50].replace(",9.81", ",0.0"))  # repeated timestamp, other value
    (folder / "Accelerometer.csv").write_text(_ACC_H + "".join(acc))
    tg = 0.005 + np.arange(198) * 0.01
    (folder / "Gyroscope.csv").write_text(
        _GYR_H + "".join(f"{t!r},{3 * t!r},0,{-t!r}\n" for t in tg.tolist()))
    loc = [(0.0, -1.0, 65.0), (0.5, 4.0, 10.0), (1.003, 5.5, 8.0), (1.004, 6.0, -1.0),
           (1.5, -1.0, 9.0), (3.0, 7.0, 5.0)]
    (folder / "Linear Acceleration.csv").write_text(
        _ACC_H + "".join(f"{t!r},0,{t!r},0\n" for t in (ta[::2] + 0.001).tolist()))
    (folder / "Location.csv").write_text(
        _LOC_H + "".join(f"{t},47.6,17.6,110,{v},-1,{h},{h}\n" for t, v, h in loc))


def test_synthetic_folder_and_zip(tmp_path):
    _export(tmp_path / "exp")
    with zipfile.ZipFile(tmp_path / "exp.zip", "w") as zf:
        for f in (tmp_path / "exp").iterdir():
            zf.write(f, f"My Experiment/{f.name}")
    for src in (tmp_path / "exp", tmp_path / "exp.zip", tmp_path / "exp" / "Gyroscope.csv"):
        assert detect_format(src) == "phyphox"
        r = read(src)
        assert len(r) == 200
        np.testing.assert_allclose(r["ay"], 2 * r.t)
        if src.name != "Gyroscope.csv":  # a single file given: the whole export is read
            ok = np.isfinite(r["lin_ay"])
            np.testing.assert_allclose(r["lin_ay"][ok], r.t[ok], atol=1e-12)  # value = own time
            assert ok.sum() == 198 and r.units["lin_ay"] == "m/s^2"
        # gyro linearly interpolated: exact for a linear signal, NaN outside its span
        inside = (r.t >= 0.005) & (r.t <= 0.005 + 197 * 0.01)
        np.testing.assert_allclose(r["gx"][inside], 3 * r.t[inside], atol=1e-12)
        assert np.all(np.isnan(r["gx"][~inside]))
        # GPS: -1 -> no fix; each valid fix once at the nearest sample; 3.0 s is after the end
        g = r["gps_speed"]
        assert np.flatnonzero(np.isfinite(g)).tolist() == [50, 100]
        assert g[50] == 4.0 and g[100] == 6.0  # 1.003 and 1.004 share sample 100: later wins
        np.testing.assert_array_equal(r.events["gps_fix"], [0.0, 0.5, 1.003, 1.004, 1.5, 3.0])
        # both GPS channels come from the same fix (1.004 s: hacc -1 -> NaN)
        assert r["gps_hacc"][0] == 65.0 and np.isnan(r["gps_hacc"][100])
        assert r["gps_hacc"][50] == 10.0


def test_later_fix_wins_on_same_sample(tmp_path):
    _export(tmp_path / "e")
    r = read_phyphox(tmp_path / "e")
    # fixes at 1.003 (5.5 m/s) and 1.004 (6.0 m/s) both nearest to sample 100 (t = 1.00)
    assert r["gps_speed"][100] == 6.0
    assert any("same sample" in n for n in r.notes)


def test_repeated_timestamp_dropped_and_noted(tmp_path):
    _export(tmp_path / "e", repeat=True)
    r = read_phyphox(tmp_path / "e")
    assert len(r) == 200 and r["az"][50] == 9.81
    assert any("repeating the previous timestamp" in n for n in r.notes)


def test_backwards_time_is_an_error(tmp_path):
    _export(tmp_path / "e")
    acc = (tmp_path / "e" / "Accelerometer.csv").read_text().splitlines(keepends=True)
    acc[10], acc[11] = acc[11], acc[10]
    (tmp_path / "e" / "Accelerometer.csv").write_text("".join(acc))
    with pytest.raises(ReaderError, match=r"Accelerometer\.csv, line 12, column 't'"):
        read_phyphox(tmp_path / "e")
    assert len(read_phyphox(tmp_path / "e", sort=True)) == 200


def test_missing_accelerometer(tmp_path):
    (tmp_path / "e").mkdir()
    (tmp_path / "e" / "Gyroscope.csv").write_text(_GYR_H + "0,1,2,3\n")
    assert not is_phyphox(tmp_path / "e")
    with pytest.raises(ReaderError, match="no Accelerometer.csv"):
        read(tmp_path / "e", format="phyphox")


def test_real_drive_rsq_q2_00():
    if not DRIVE.exists():
        pytest.skip("shared dataset not present")
    r = read(DRIVE)
    assert r.fs == pytest.approx(99.6, abs=0.1)
    assert r.duration == pytest.approx(188.3, abs=0.5)
    assert {"ax", "ay", "az", "gx", "gy", "gz", "gps_speed", "gps_hacc"} <= set(r.channels)
    assert np.nanmean(r["az"]) == pytest.approx(9.81, abs=0.2)  # z up, includes +g
    # y forward: integrating a_y over the start-up matches the first valid GPS speed sign (> 0)
    g = r["gps_speed"]
    fixes = np.flatnonzero(np.isfinite(g))
    assert 150 <= fixes.size <= 190
    assert np.nanmin(g) >= 0 and 10 < np.nanmax(g) < 20
    # longitudinal acceleration from GPS speed correlates with a_y, not with a_x
    tf, vf = r.t[fixes], g[fixes]
    dv = np.diff(vf) / np.diff(tf)
    mids = (tf[1:] + tf[:-1]) / 2
    ok = np.diff(tf) < 1.5
    sm = {k: np.convolve(r[k] - np.nanmean(r[k]), np.ones(100) / 100, "same") for k in ("ax", "ay")}
    c = {k: np.corrcoef(dv[ok], np.interp(mids[ok], r.t, sm[k]))[0, 1] for k in sm}
    assert c["ay"] > 0.5 > abs(c["ax"])
    assert r.events["gps_fix"].size == 187


def test_fixes_inside_an_accelerometer_gap_keep_rows_of_their_own(tmp_path):
    """A phone whose accelerometer stops for 5 s while GPS goes on (1 Hz): every valid fix is
    placed once, at its own time (not all on the samples at the gap's edges, where all but
    two would be lost and those moved by up to 2.5 s); the accelerometer is NaN there."""
    folder = tmp_path / "gap"
    folder.mkdir()
    ta = np.arange(1000) * 0.01
    ta = ta[(ta < 3.0) | (ta >= 8.0)]  # no accelerometer sample in [3, 8) s
    (folder / "Accelerometer.csv").write_text(
        _ACC_H + "".join(f"{t!r},0.5,{2 * t!r},9.81\n" for t in ta.tolist()))
    fixes = [(0.5, 4.0), (3.5, 5.0), (4.5, -1.0), (5.5, 6.0), (6.5, 7.0), (7.5, 8.0), (9.0, 9.0)]
    (folder / "Location.csv").write_text(
        _LOC_H + "".join(f"{t},47.6,17.6,110,{v},-1,5,5\n" for t, v in fixes))
    r = read_phyphox(folder)
    g = r["gps_speed"]
    got = {(float(t), float(v)) for t, v in zip(r.t[np.isfinite(g)], g[np.isfinite(g)],
                                                strict=True)}
    want = {(t, v) for t, v in fixes if v >= 0}  # each valid fix at its own time, once
    assert got == want
    added = np.isin(r.t, [3.5, 5.5, 6.5, 7.5])  # the fix with velocity -1 adds no row
    assert len(r) == ta.size + 4 and added.sum() == 4
    assert np.all(np.isnan(r["ay"][added]))
    np.testing.assert_array_equal(r["ay"][~added], 2 * ta)  # the file's rows are unchanged
    assert any("4 valid GPS fix(es) inside accelerometer gaps" in n for n in r.notes)
    assert not any("same sample" in n for n in r.notes)
    # the time-line notes describe the accelerometer: one gap of 5.01 s, not 5 of about 1 s
    assert "1 time gap(s) longer than 3 periods, longest 5.01 s (first at t = 2.99 s)" in r.notes


def test_phone_axes_note_names_the_longitudinal_axis(tmp_path):
    """A phone's x is its right edge; fuse and gps-riss read ax as forward unless told: the
    phyphox and Sensor Logger readers say which axis to give them."""
    from vibrospeed.io._common import PHONE_AXES_NOTE

    _export(tmp_path / "e")
    r = read_phyphox(tmp_path / "e")
    assert PHONE_AXES_NOTE in r.notes
    assert "-p accel_axis=y" in PHONE_AXES_NOTE and "--axis y" in PHONE_AXES_NOTE


def test_a_csv_that_is_no_phyphox_export_is_refused_when_the_format_is_forced(tmp_path):
    # a canonical CSV read with --format phyphox: its first three data columns were taken as
    # the phone's x, y, z, the other channels dropped, and the phone-axes note given
    p = tmp_path / "drive.csv"
    p.write_text("t,ax,ay,az,gx\n0,0,0,9.8,0\n0.01,0,0,9.8,0\n0.02,0,0,9.8,0\n")
    with pytest.raises(ReaderError, match=r"drive\.csv, line 1: first column 't' is not "
                                          r"phyphox's 'Time \(s\)': not a phyphox export"):
        read(p, "phyphox")
    assert detect_format(p) != "phyphox"
