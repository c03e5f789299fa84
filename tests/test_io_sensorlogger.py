"""Sensor Logger exports: generated folders and zips with known answers, platform handling, bad
and hostile files (zip bombs, traversal names, random bytes)."""

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vibrospeed import io as vio
from vibrospeed.errors import InputError, ReaderError
from vibrospeed.io.sensorlogger import detect, read_sensorlogger
from vibrospeed.types import Recording

T0 = 1_700_000_000_000_000_000  # ns since the epoch
N = 300  # 100 Hz, 3 s


def _py(v):
    return v.item() if isinstance(v, np.generic) else v


def _csv(cols, rows):
    return ",".join(cols) + "\n" + "".join(",".join(repr(_py(v)) for v in r) + "\n" for r in rows)


def _ns(t):
    return [T0 + int(round(x * 1e9)) for x in t]


def _export(folder: Path, *, total=True, grav=True, meta=None, loc=True) -> dict:
    """A Sensor Logger export with linear signals, so interpolation is exact."""
    folder.mkdir(parents=True, exist_ok=True)
    ta = np.arange(N) * 0.01 + 0.002 * (np.arange(N) % 2)  # jittered 100 Hz
    tg = 0.005 + np.arange(N // 2) * 0.02  # 50 Hz gyroscope
    tv = np.arange(N) * 0.01 + 0.003  # gravity / user acceleration
    files = {}
    files["Accelerometer.csv"] = _csv(
        ["time", "seconds_elapsed", "z", "y", "x"],
        [(n, t, 0.5, t, 2 * t) for n, t in zip(_ns(tv), tv, strict=True)])  # lin = (2t, t, .5)
    if grav:
        files["Gravity.csv"] = _csv(["time", "seconds_elapsed", "z", "y", "x"],
                                    [(n, t, 9.8, 0.0, 0.0)
                                     for n, t in zip(_ns(tv), tv, strict=True)])
    if total:
        files["TotalAcceleration.csv"] = _csv(
            ["time", "seconds_elapsed", "z", "y", "x"],
            [(n, t, 9.8 + t, -t, 3 * t) for n, t in zip(_ns(ta), ta, strict=True)])
    files["Gyroscope.csv"] = _csv(["time", "seconds_elapsed", "z", "y", "x"],
                                  [(n, t, -t, 0.0, 4 * t)
                                   for n, t in zip(_ns(tg), tg, strict=True)])
    if loc:
        fixes = [(0.0, -1.0, 5.0), (0.5, 4.0, 3.0), (1.002, 5.5, 4.0), (1.003, 6.0, -1.0),
                 (2.0, 7.0, 2.0), (9.0, 8.0, 1.0)]
        files["Location.csv"] = _csv(
            ["time", "seconds_elapsed", "bearingAccuracy", "speedAccuracy", "verticalAccuracy",
             "horizontalAccuracy", "speed", "bearing", "altitude", "longitude", "latitude"],
            [(n, t, 1.0, 0.5, 3.0, h, v, 90.0, 120.0, 17.6, 47.6)
             for n, (t, v, h) in zip(_ns([f[0] for f in fixes]), fixes, strict=True)])
    if meta:
        files["Metadata.csv"] = ",".join(meta) + "\n" + ",".join(meta.values()) + "\n"
    for name, text in files.items():
        (folder / name).write_text(text)
    return {"ta": ta, "tg": tg, "tv": tv}


def _zip(folder: Path, out: Path, prefix="2024-01-01_10-00-00/", extra=()):
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        for f in sorted(folder.iterdir()):
            zf.write(f, prefix + f.name)
        for name, data in extra:
            zf.writestr(name, data)
    return out


def test_folder_zip_and_single_file_read_alike(tmp_path):
    k = _export(tmp_path / "rec")
    z = _zip(tmp_path / "rec", tmp_path / "rec.zip",
             extra=[("__MACOSX/._TotalAcceleration.csv", b"\x00\x05junk")])
    recs = []
    for src in (tmp_path / "rec", z, tmp_path / "rec" / "Gyroscope.csv"):
        assert detect(src) and vio.detect_format(src) == "sensorlogger"
        recs.append(vio.read(src))
    r = recs[0]
    ta = k["ta"]
    assert len(r) == N and r.meta["t0_epoch_ns"] == T0
    assert r.meta["master"] == "TotalAcceleration.csv"
    np.testing.assert_allclose(r.t, ta, atol=1e-6)  # ns epoch through float64: 0.25 us steps
    np.testing.assert_allclose(r["ax"], 3 * ta, atol=1e-9)  # z,y,x column order handled
    np.testing.assert_allclose(r["ay"], -ta, atol=1e-9)
    np.testing.assert_allclose(r["az"], 9.8 + ta, atol=1e-9)
    # gyroscope (50 Hz) interpolated: linear in time so exact inside its span, NaN outside
    inside = (r.t >= k["tg"][0] - 1e-6) & (r.t <= k["tg"][-1] + 1e-6)
    np.testing.assert_allclose(r["gx"][inside], 4 * r.t[inside], atol=1e-5)
    np.testing.assert_allclose(r["gz"][inside], -r.t[inside], atol=1e-5)
    assert np.isnan(r["gx"][0]) and r.units["gx"] == "rad/s"
    # user acceleration (Accelerometer.csv) as lin_a*, interpolated
    ok = np.isfinite(r["lin_ax"])
    np.testing.assert_allclose(r["lin_ax"][ok], 2 * r.t[ok], atol=1e-5)
    # GPS: negative speed = invalid, each fix once at the nearest sample, later valid fix wins
    g = r["gps_speed"]
    assert np.flatnonzero(np.isfinite(g)).tolist() == [50, 100, 200]
    assert g[50] == 4.0 and g[100] == 6.0 and g[200] == 7.0  # 1.002 and 1.003 s: later wins
    assert np.isnan(r["gps_hacc"][100]) and r["gps_hacc"][0] == 5.0  # invalid speed, hacc kept
    assert r["gps_lat"][200] == 47.6 and r.units["gps_lon"] == "deg"
    np.testing.assert_allclose(r.events["gps_fix"], [0, 0.5, 1.002, 1.003, 2.0, 9.0], atol=1e-6)
    notes = " ".join(r.notes)
    assert "TotalAcceleration.csv (with gravity) used" in notes and "interpolated" in notes
    for other in recs[1:]:
        assert set(other.channels) == set(r.channels)
        np.testing.assert_array_equal(other.t, r.t)
        for c in r.channels:
            np.testing.assert_array_equal(other[c], r[c])


def test_same_recording_as_the_equivalent_csv(tmp_path):
    _export(tmp_path / "rec")
    r = vio.read(tmp_path / "rec")
    vio.write(Recording(t=r.t, channels=r.channels, units=r.units), tmp_path / "eq.csv")
    c = vio.read(tmp_path / "eq.csv")
    assert list(c.channels) == list(r.channels)
    for name in r.channels:
        assert c.units[name] == r.units[name]
        np.testing.assert_allclose(c[name], r[name], rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(c.t, r.t, rtol=1e-12)


def test_accelerometer_plus_gravity_and_without(tmp_path):
    k = _export(tmp_path / "a", total=False)
    r = read_sensorlogger(tmp_path / "a")
    tv = k["tv"]
    np.testing.assert_allclose(r.t, tv - tv[0], atol=1e-6)
    np.testing.assert_allclose(r["ax"], 2 * tv, atol=1e-9)
    np.testing.assert_allclose(r["az"], 0.5 + 9.8, atol=1e-9)  # gravity added back
    np.testing.assert_allclose(r["lin_az"], 0.5, atol=1e-12)
    assert any("+ Gravity.csv" in n for n in r.notes)
    _export(tmp_path / "b", total=False, grav=False)
    r = read_sensorlogger(tmp_path / "b")
    np.testing.assert_allclose(r["az"], 0.5)
    assert any("WITHOUT gravity" in n for n in r.notes)


def test_ios_sign_and_uncalibrated_units(tmp_path):
    _export(tmp_path / "i", total=False, meta={"platform": "ios", "standardisation": "false"})
    r = read_sensorlogger(tmp_path / "i")
    np.testing.assert_allclose(r["az"], -(0.5 + 9.8), atol=1e-9)  # iOS signs negated
    assert r.meta["platform"] == "ios" and any("negated" in n for n in r.notes)
    # only an uncalibrated accelerometer, in g (iOS), no metadata: magnitude says g
    d = tmp_path / "u"
    d.mkdir()
    t = np.arange(50) * 0.01
    (d / "AccelerometerUncalibrated.csv").write_text(_csv(
        ["time", "seconds_elapsed", "z", "y", "x"], [(n, x, -1.0, 0.0, 0.0)
                                                     for n, x in zip(_ns(t), t, strict=True)]))
    r = vio.read(d)
    np.testing.assert_allclose(r["az"], 9.80665)
    assert any("looks like g" in n for n in r.notes)


def test_seconds_elapsed_only_and_sort(tmp_path):
    d = tmp_path / "s"
    d.mkdir()
    rows = [(0.0, 1, 2, 3), (0.01, 1, 2, 3), (0.03, 1, 2, 3), (0.02, 1, 2, 3)]
    (d / "TotalAcceleration.csv").write_text(_csv(["seconds_elapsed", "x", "y", "z"], rows))
    with pytest.raises(ReaderError, match=r"TotalAcceleration.csv, line 5, column 't': time goes "
                                          "backwards"):
        read_sensorlogger(d)
    r = read_sensorlogger(d, sort=True)
    np.testing.assert_allclose(r.t, [0, 0.01, 0.02, 0.03])


def test_path_traversal_names_are_never_extracted(tmp_path):
    _export(tmp_path / "rec", loc=False)
    z = _zip(tmp_path / "rec", tmp_path / "evil.zip", prefix="../../outside/")
    before = sorted(p.name for p in tmp_path.parent.iterdir())
    r = vio.read(z)
    assert len(r) == N
    assert sorted(p.name for p in tmp_path.parent.iterdir()) == before
    assert not (tmp_path / "outside").exists()


def test_zip_bomb_refused(tmp_path):
    z = tmp_path / "bomb.zip"
    with zipfile.ZipFile(z, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("Gyroscope.csv", b"time,seconds_elapsed,z,y,x\n" + b"0" * (20 * 1024**2))
        zf.writestr("TotalAcceleration.csv",
                    "time,seconds_elapsed,z,y,x\n1,0,1,2,3\n2,0.01,1,2,3\n")
    with pytest.raises(ReaderError, match=r"Gyroscope.csv: zip member compressed \d+:1 .*zip bomb"):
        vio.read(z)


def test_zip_member_size_limit(tmp_path):
    from vibrospeed.io._archive import SafeZip

    z = tmp_path / "big.zip"
    with zipfile.ZipFile(z, "w", zipfile.ZIP_STORED) as zf:
        zf.writestr("Accelerometer.csv", b"x" * 5000)
    with pytest.raises(ReaderError, match="zip member too large"):
        SafeZip(z, max_member=4096).read("Accelerometer.csv")


@pytest.mark.parametrize(
    ("name", "text", "pattern"),
    [
        ("TotalAcceleration.csv", "time,seconds_elapsed,z,y\n1,0,1,2\n", r"column 'x': column not"),
        ("TotalAcceleration.csv", "time,seconds_elapsed,z,y,x\n1,0,1,2,3\n2,0.1,1,q,3\n",
         r"line 3, column 'y': 'q' is not a number"),
        ("Gravity.csv", "time,seconds_elapsed,z,y,x\n1,0,1,2,3\n", r"no TotalAcceleration.csv"),
    ],
)
def test_malformed(tmp_path, name, text, pattern):
    d = tmp_path / "bad"
    d.mkdir()
    (d / name).write_text(text)
    with pytest.raises(ReaderError, match=pattern):
        read_sensorlogger(d)


def test_corrupt_zip_one_line(tmp_path):
    _export(tmp_path / "rec")
    z = _zip(tmp_path / "rec", tmp_path / "rec.zip")
    data = bytearray(z.read_bytes())
    i = data.find(b"TotalAcceleration.csv") + 200  # inside the compressed data
    data[i:i + 64] = b"\xff" * 64
    z.write_bytes(bytes(data))
    with pytest.raises(ReaderError) as exc:
        read_sensorlogger(z)
    assert "\n" not in str(exc.value) and "rec.zip" in str(exc.value)


def test_cli_info_and_bad_zip(tmp_path):
    from typer.testing import CliRunner

    from vibrospeed.cli.app import app

    _export(tmp_path / "rec")
    z = _zip(tmp_path / "rec", tmp_path / "rec.zip")
    res = CliRunner().invoke(app, ["info", str(z)])
    assert res.exit_code == 0, res.output
    assert "Sensor Logger" in res.output and "TotalAcceleration" in res.output
    bad = tmp_path / "cut.zip"
    bad.write_bytes(z.read_bytes()[: z.stat().st_size // 2])
    res = CliRunner().invoke(app, ["info", str(bad), "--format", "sensorlogger"])
    assert res.exit_code == 2
    assert "cut.zip" in res.output and "Traceback" not in res.output


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=400), st.booleans())
def test_random_bytes_never_crash(tmp_path, data, zipped):
    d = tmp_path / "fuzz"
    d.mkdir(exist_ok=True)
    head = b"time,seconds_elapsed,z,y,x\n"
    if zipped:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w") as zf:
            zf.writestr("TotalAcceleration.csv", head + data)
        target = d / "r.zip"
        target.write_bytes(buf.getvalue()[: max(len(buf.getvalue()) - len(data) % 7, 1)])
    else:
        (d / "TotalAcceleration.csv").write_bytes(head + data)
        target = d
    try:
        read_sensorlogger(target)
    except InputError as exc:
        assert "\n" not in str(exc)


def test_fixes_inside_an_accelerometer_gap_keep_rows_of_their_own(tmp_path):
    """TotalAcceleration stops for 5 s while Location goes on at 1 Hz: every fix with a valid
    speed is placed once at its own time (not piled onto the samples at the gap's edges, all
    but two lost), the accelerometer NaN there; and a fix that does share a sample is noted."""
    folder = tmp_path / "gap"
    folder.mkdir()
    ta = np.arange(1000) * 0.01
    ta = ta[(ta < 3.0) | (ta >= 8.0)]
    (folder / "TotalAcceleration.csv").write_text(_csv(
        ["time", "seconds_elapsed", "z", "y", "x"],
        [(n, t, 9.8, 2 * t, 0.5) for n, t in zip(_ns(ta), ta, strict=True)]))
    fixes = [(0.5, 4.0), (0.502, 4.5), (3.5, 5.0), (4.5, -1.0), (5.5, 6.0), (7.5, 8.0)]
    (folder / "Location.csv").write_text(_csv(
        ["time", "seconds_elapsed", "horizontalAccuracy", "speed", "altitude", "longitude",
         "latitude"],
        [(n, t, 3.0, v, 120.0, 17.6, 47.6)
         for n, (t, v) in zip(_ns([f[0] for f in fixes]), fixes, strict=True)]))
    r = read_sensorlogger(folder)
    g = r["gps_speed"]
    fin = np.isfinite(g)
    np.testing.assert_allclose(r.t[fin], [0.5, 3.5, 5.5, 7.5], atol=1e-9)
    np.testing.assert_array_equal(g[fin], [4.5, 5.0, 6.0, 8.0])  # 0.5 / 0.502: later kept
    added = ~np.isin(np.round(r.t, 6), np.round(ta, 6))
    assert added.sum() == 3 and np.all(np.isnan(r["ay"][added]))
    np.testing.assert_allclose(r["ay"][~added], 2 * ta, atol=1e-12)
    assert any("3 valid GPS fix(es) inside accelerometer gaps" in n for n in r.notes)
    assert any("1 valid GPS fix(es) fell on the same sample" in n for n in r.notes)
    assert "1 time gap(s) longer than 3 periods, longest 5.01 s (first at t = 2.99 s)" in r.notes
    assert any("give -p accel_axis=y to fuse" in n for n in r.notes)  # phone axes, as phyphox


def test_empty_and_nan_accelerometer_cells_are_noted(tmp_path):
    """Empty / NaN cells of the master accelerometer are counted in a note (phyphox and the
    CSV readers say the same), and an axis with no number at all is refused naming it."""
    folder = tmp_path / "nan"
    folder.mkdir()
    ta = np.arange(200) * 0.01
    rows = [(n, t, 9.8, "" if 50 <= i < 80 else 2 * t, "nan" if i == 7 else 0.5)
            for i, (n, t) in enumerate(zip(_ns(ta), ta, strict=True))]
    text = "time,seconds_elapsed,z,y,x\n" + "".join(
        ",".join(str(_py(v)) for v in r) + "\n" for r in rows)
    (folder / "TotalAcceleration.csv").write_text(text)
    r = read_sensorlogger(folder)
    assert int(np.isnan(r["ay"]).sum()) == 30 and int(np.isnan(r["ax"]).sum()) == 1
    assert "channel 'ay': 30 empty or NaN cell(s) of 200" in "\n".join(r.notes)
    assert "channel 'ax': 1 empty or NaN cell(s) of 200" in "\n".join(r.notes)
    (folder / "TotalAcceleration.csv").write_text("time,seconds_elapsed,z,y,x\n" + "".join(
        f"{n},{t!r},9.8,,0.5\n" for n, t in zip(_ns(ta), ta, strict=True)))
    with pytest.raises(ReaderError, match="ay.*no numeric value"):
        read_sensorlogger(folder)
