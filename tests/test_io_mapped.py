"""Generic CSV through a column mapping: parsing, TOML, unit scaling, files without time."""

import math
from pathlib import Path

import numpy as np
import pytest

from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.io import read
from vibrospeed.io.mapped import ColumnSpec, load_mapping, parse_mapping

KART = Path(__file__).resolve().parents[2] / "shared/datasets/gopro_kart/GX030410_accl_raw.csv"


def test_parse_mapping():
    m = parse_mapping(" t=time:ms , ay=acc_y:g,gz=Yaw rate (x)*0.5:deg/s, a*b=col*x")
    assert m["t"] == ColumnSpec("time", 1.0, 0.0, "ms")
    assert m["ay"] == ColumnSpec("acc_y", 1.0, 0.0, "g")
    assert m["gz"] == ColumnSpec("Yaw rate (x)", 0.5, 0.0, "deg/s")
    assert m["a*b"] == ColumnSpec("col*x")  # '*x' is not a number: part of the name
    for bad in ("", "ay", "ay=", "=c", "ay=a,ay=b"):
        with pytest.raises(ParameterError):
            parse_mapping(bad)


def test_units_and_scaling(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text("date;time_ms;acc_y;yaw;v\n"
                 "x;1000;1;180;36\nx;1010;0.5;-90;72\nx;1020;;0;0\n")
    r = read(p, columns="t=time_ms:ms,ay=acc_y:g,gz=yaw:deg/s,gps_speed=v:km/h")
    np.testing.assert_allclose(r.t, [1.0, 1.01, 1.02])
    np.testing.assert_allclose(r["ay"], [9.80665, 4.903325, np.nan])
    np.testing.assert_allclose(r["gz"], [math.pi, -math.pi / 2, 0.0])
    np.testing.assert_allclose(r["gps_speed"], [10.0, 20.0, 0.0])
    assert r.units["gz"] == "rad/s" and r.units["ay"] == "m/s^2"
    assert any("'acc_y': 1 empty" in n for n in r.notes)


def test_toml_mapping_with_offset_and_rate(tmp_path):
    p = tmp_path / "raw.csv"
    p.write_text("c1,c2\n100,1\n200,2\n300,3\n")
    m = tmp_path / "map.toml"
    m.write_text('rate = 50.0\n[columns]\nax = { column = "c1", scale = 0.01, offset = -1.0 }\n'
                 'gz = { column = "c2", unit = "deg/s" }\n')
    spec, opts = load_mapping(m)
    assert opts == {"rate": 50.0} and spec["ax"].scale == 0.01
    r = read(p, mapping_file=m)
    np.testing.assert_allclose(r.t, [0.0, 0.02, 0.04])
    np.testing.assert_allclose(r["ax"], [0.0, 1.0, 2.0])
    np.testing.assert_allclose(r["gz"], np.deg2rad([1, 2, 3]))
    m.write_text('[columns]\nax = { column = "c1", unit = "furlong" }\n')
    with pytest.raises(ParameterError, match="unknown unit 'furlong'"):
        read(p, mapping_file=m, rate=10)
    m.write_text("[columns\n")
    with pytest.raises(ReaderError, match="not a valid TOML"):
        load_mapping(m)


def test_mapping_errors(tmp_path):
    p = tmp_path / "d.csv"
    p.write_text("time,acc_y\n0,1\n0.1,oops\n")
    with pytest.raises(ReaderError, match=r"d\.csv, line 1, column 'acc_z': column not found"):
        read(p, columns="t=time,az=acc_z")
    with pytest.raises(ReaderError, match=r"d\.csv, line 3, column 'acc_y': 'oops' is not a num"):
        read(p, columns="t=time,ay=acc_y")
    with pytest.raises(ParameterError, match="no time column mapped"):
        read(p, format="mapped", columns="ay=acc_y")
    with pytest.raises(ParameterError, match="not both"):
        read(p, columns="t=time,ay=acc_y", rate=100)
    with pytest.raises(ParameterError, match="does not take option 'rate'"):
        read(p, format="phyphox", rate=100)


def test_gopro_kart_raw_counts_with_rate():
    if not KART.exists():
        pytest.skip("shared dataset not present")
    r = read(KART, columns="ax=c1,ay=c2,az=c3", rate=198.4)
    assert len(r) == 90670
    assert r.fs == pytest.approx(198.4, rel=1e-9)
    assert r.duration == pytest.approx(457.0, abs=0.1)  # the video length
    assert r.is_uniform(1e-9)
    # raw int16 counts, kept as given (no scale requested)
    for k in ("ax", "ay", "az"):
        x = r[k]
        assert np.all(np.isfinite(x)) and np.all(x == np.round(x))
        assert np.all(np.abs(x) <= 32768)
    assert r["ax"][:2].tolist() == [10698.0, 10358.0]


@pytest.mark.parametrize("columns, unit, want", [
    ("t=time,ay=acc_y:m/s", "m/s", "m/s^2"),      # a speed unit for an acceleration
    ("t=time,gz=acc_y:deg", "deg", "rad/s"),      # an angle for a rate
    ("t=time:g,ay=acc_y", "g", "s"),              # an acceleration for the time
    ("t=time,gps_speed=acc_y:deg/s", "deg/s", "m/s"),
])
def test_a_unit_of_another_quantity_is_refused(tmp_path, columns, unit, want):
    """``ay=acc_y:m/s`` would label an acceleration m/s; ``gz=yaw:deg`` (meant: deg/s) would
    label a rate rad: refused in one line naming the channel, its SI unit and the units that
    fit, by the whole-file and the streamed reader alike."""
    from vibrospeed.io.chunks import ChunkedRecording
    from vibrospeed.io.mapped import UNITS

    p = tmp_path / "d.csv"
    p.write_text("time,acc_y\n0,1\n0.1,2\n0.2,3\n")
    with pytest.raises(ParameterError) as exc:
        read(p, columns=columns)
    msg = str(exc.value)
    assert f"unit '{unit}' gives {UNITS[unit][1]}" in msg and f"is in {want}" in msg
    fits = [u for u, (_, si) in UNITS.items() if si == want]
    assert f"(units for it: {', '.join(fits)}, or counts)" in msg
    with pytest.raises(ParameterError) as streamed:
        list(ChunkedRecording(p, columns=columns))
    assert str(streamed.value) == msg


def test_counts_and_unknown_channels_take_any_unit(tmp_path):
    p = tmp_path / "d.csv"
    p.write_text("time,acc_y\n0,1\n0.1,2\n0.2,3\n")
    r = read(p, columns="t=time,ay=acc_y*0.5:counts,wheel_rpm=acc_y:rpm")
    np.testing.assert_allclose(r["ay"], [0.5, 1.0, 1.5])
    np.testing.assert_allclose(r["wheel_rpm"], np.array([1.0, 2.0, 3.0]) * 2 * math.pi / 60)
    assert r.units["ay"] == "1" and r.units["wheel_rpm"] == "rad/s"


def test_an_accelerometer_in_g_read_as_si_is_noted(tmp_path):
    """A logger's CSV in g mapped without ``:g``: the three axes' median magnitude is 1, not
    gravity's 9.81 m/s^2, and a note says so and how to give the unit; with ``:g`` (or a file
    in m/s^2) there is no note."""
    rng = np.random.default_rng(5)
    n = 500
    a = np.column_stack([rng.normal(0, 0.05, n), rng.normal(0, 0.05, n),
                         1.0 + rng.normal(0, 0.05, n)])  # g, gravity on z
    p = tmp_path / "g.csv"
    p.write_text("time,x,y,z\n" + "".join(f"{i * 10},{r[0]!r},{r[1]!r},{r[2]!r}\n"
                                         for i, r in enumerate(a.tolist())))
    med = float(np.median(np.linalg.norm(a, axis=1)))
    r = read(p, columns="t=time:ms,ax=x,ay=y,az=z")
    (note,) = [s for s in r.notes if "look like g" in s]
    assert note.startswith(f"ax ay az: median magnitude {med:.3g} m/s^2 where gravity")
    assert "--columns ax=COL:g" in note
    r = read(p, columns="t=time:ms,ax=x:g,ay=y:g,az=z:g")
    assert not any("look like g" in s for s in r.notes)
    assert np.median(np.linalg.norm([r["ax"], r["ay"], r["az"]], axis=0)) == pytest.approx(
        9.80665 * med)


def test_gps_speed_minus_one_is_no_fix(tmp_path):
    """A phone log through a mapping (or as canonical CSV) with -1 for "no fix": the -1 fixes
    become NaN with a note, not fixes of -1 m/s that a GPS method would follow (fuse went to
    -0.9 m/s through such a stretch); valid fixes, 0 included, are kept."""
    p = tmp_path / "log.csv"
    p.write_text("time,acc,v,hacc\n0,1,-1,-1\n0.1,1,,\n0.2,1,0,5\n0.3,1,12.5,4\n0.4,1,-1,-1\n")
    r = read(p, columns="t=time,ay=acc,gps_speed=v,gps_hacc=hacc")
    np.testing.assert_array_equal(r["gps_speed"], [np.nan, np.nan, 0.0, 12.5, np.nan])
    np.testing.assert_array_equal(r["gps_hacc"], [np.nan, np.nan, 5.0, 4.0, np.nan])
    notes = "\n".join(r.notes)
    assert "gps_speed: 2 negative value(s) read as no fix (NaN" in notes
    assert "gps_hacc: 2 negative value(s)" in notes
    c = tmp_path / "canon.csv"
    c.write_text("t,ay,gps_speed\n0,1,-1\n0.1,1,3\n0.2,1,-1\n")
    r = read(c)
    np.testing.assert_array_equal(r["gps_speed"], [np.nan, 3.0, np.nan])
    assert any(n.startswith("gps_speed: 2 negative value(s)") for n in r.notes)
