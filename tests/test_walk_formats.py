"""Input shapes users bring (walkthrough of the formats): gzip-compressed CSV, a units row under
the header, units in the header names, ISO-8601 time stamps, Parquet with other column names,
European spreadsheet exports (BOM, CRLF, ';', decimal comma). Each value is checked against
the numbers the file was written from."""

import gzip
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_runner import one_line_error, run
from vibrospeed import io
from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.io.chunks import ChunkedRecording
from vibrospeed.io.mapped import UNITS, read_mapped

G = 9.80665
N = 40
T = np.arange(N) / 100.0
AX = np.sin(np.arange(N) * 0.7)  # in g where a file says g
AY = np.cos(np.arange(N) * 0.3)


def _canonical_text() -> str:
    rows = [f"{t!r},{a!r},{b!r}" for t, a, b in zip(T.tolist(), AX.tolist(), AY.tolist(),
                                                    strict=True)]
    return "t,ax,ay\n" + "\n".join(rows) + "\n"


def _eu(x: float) -> str:
    return f"{x:.9f}".replace(".", ",")


def _european(path, header: str, units: str | None, t_scale: float = 1.0) -> None:
    """A spreadsheet's export: BOM, CRLF, ';' and decimal commas; AX/AY in g."""
    lines = [header] + ([units] if units else [])
    lines += [f"{_eu(t * t_scale)};{_eu(a)};{_eu(b)}" for t, a, b in zip(T, AX, AY, strict=True)]
    path.write_bytes(("\ufeff" + "\r\n".join(lines) + "\r\n").encode())


def _toml(path, cols: str) -> None:
    path.write_text(f'delimiter = ";"\ndecimal = ","\n[columns]\n{cols}\n')


# ---- gzip ---------------------------------------------------------------------------------

def test_csv_gz_is_read_as_its_text(tmp_path):
    plain, packed = tmp_path / "d.csv", tmp_path / "d.csv.gz"
    plain.write_text(_canonical_text())
    packed.write_bytes(gzip.compress(plain.read_bytes()))
    assert io.detect_format(packed) == "csv"
    rec = io.read(packed)
    np.testing.assert_array_equal(rec.t, T)
    np.testing.assert_array_equal(rec["ax"], AX)
    via_map = io.read(packed, columns="t=t,ay=ay:g")
    np.testing.assert_allclose(via_map["ay"], AY * G, rtol=1e-15)
    streamed = ChunkedRecording(packed, chunk_rows=7).read()
    np.testing.assert_array_equal(streamed["ay"], AY)


def test_truncated_gz_is_one_line_and_no_output(tmp_path):
    packed = tmp_path / "d.csv.gz"
    packed.write_bytes(gzip.compress((_canonical_text() * 50).encode())[:300])
    out = tmp_path / "est.csv"
    line = one_line_error(run("estimate", packed, "-o", out))
    assert str(packed) in line and "gzip" in line
    assert not out.exists()


# ---- units row and units in the header ----------------------------------------------------

def test_units_row_of_a_european_export_converts_to_si(tmp_path):
    f, m = tmp_path / "log.csv", tmp_path / "map.toml"
    _european(f, "Zeit;AccX;AccY", "[ms];g;m/s²", t_scale=1e3)
    _toml(m, 't = "Zeit"\nax = "AccX"\nay = "AccY"')
    rec = io.read(f, mapping_file=m)
    np.testing.assert_allclose(rec.t, T, atol=1e-12)
    np.testing.assert_allclose(rec["ax"], AX * G, atol=1e-8)
    np.testing.assert_allclose(rec["ay"], AY, atol=1e-9)  # m/s² is SI already
    assert rec.units["ax"] == "m/s^2"
    assert any("units row (line 2)" in n for n in rec.notes)
    assert any("'AccX': unit g from the units row" in n for n in rec.notes)
    streamed = ChunkedRecording(f, mapping_file=m, chunk_rows=9).read()
    np.testing.assert_array_equal(streamed["ax"], rec["ax"])
    np.testing.assert_array_equal(streamed.t, rec.t)


def test_units_in_header_names(tmp_path):
    f, m = tmp_path / "log.csv", tmp_path / "map.toml"
    _european(f, "Time (ms);AccX (g);ay [m/s²]", None, t_scale=1e3)
    _toml(m, 't = "Time (ms)"\nax = "AccX (g)"\nay = "ay [m/s²]"')
    rec = io.read(f, mapping_file=m)
    np.testing.assert_allclose(rec.t, T, atol=1e-12)
    np.testing.assert_allclose(rec["ax"], AX * G, atol=1e-8)
    # a unit given in the mapping that contradicts the header is refused, naming both
    _toml(m, 't = "Time (ms)"\nax = { column = "AccX (g)", unit = "m/s^2" }')
    with pytest.raises(ParameterError, match=r"'ax' gives unit 'm/s\^2' but the header"):
        io.read(f, mapping_file=m)


def test_header_unit_left_alone_where_the_mapping_scales(tmp_path):
    f = tmp_path / "log.csv"
    f.write_text("time,speed (km/h)\n0,36\n0.1,72\n0.2,72\n")
    rec = io.read(f, columns="t=time,gps_speed=speed (km/h)*0.2777777777777778")
    np.testing.assert_allclose(rec["gps_speed"], [10.0, 20.0, 20.0])
    assert any("scale/offset applied and no unit" in n for n in rec.notes)


def test_canonical_units_row_si_read_other_refused(tmp_path):
    ok, bad = tmp_path / "ok.csv", tmp_path / "bad.csv"
    ok.write_text("t,ax,temp\ns,m/s^2,°C\n0,1.5,20\n0.01,2.5,21\n")
    rec = io.read(ok)
    np.testing.assert_array_equal(rec["ax"], [1.5, 2.5])
    assert rec.units["temp"] == "°C"
    bad.write_text("t,ax\ns,g\n0,1\n0.01,2\n")
    with pytest.raises(ReaderError, match=r"line 2, column 'ax': units row says 'g'.*ax=ax:g"):
        io.read(bad)


def test_a_text_first_row_without_units_is_still_an_error(tmp_path):
    f = tmp_path / "d.csv"
    f.write_text("t,ax\nfoo,bar\n0,1\n")
    with pytest.raises(ReaderError, match=r"line 2, column 't': 'foo' is not a number"):
        io.read(f)


# ---- ISO-8601 time ------------------------------------------------------------------------

def test_iso_times_with_offsets_are_the_same_instants(tmp_path):
    f = tmp_path / "iso.csv"
    # 12:00:00.000Z, then the same clock in +02:00, then naive (UTC)
    f.write_text("when,ax\n2024-05-01T12:00:00.000Z,1\n2024-05-01T14:00:00.250+02:00,2\n"
                 "2024-05-01 12:00:00.5,3\n")
    rec = io.read(f, columns="t=when,ax=ax")
    epoch = 1714564800.0  # 2024-05-01T12:00:00Z
    np.testing.assert_allclose(rec.t, epoch + np.array([0.0, 0.25, 0.5]), atol=1e-6)
    assert any("ISO-8601" in n for n in rec.notes)
    f.write_text("when,ax\n2024-05-01T12:00:00Z,1\n2024-05-01T12:00:0x,2\n")
    with pytest.raises(ReaderError, match=r"line 3, column 'when': .* nor an ISO-8601 time"):
        io.read(f, columns="t=when,ax=ax")


def test_numeric_time_with_an_empty_first_cell_is_not_taken_for_dates(tmp_path):
    f = tmp_path / "d.csv"
    f.write_text("time,ax\n,1\n0.01,2\n0.02,x\n")
    with pytest.raises(ReaderError, match=r"line 4, column 'ax': 'x' is not a number"):
        io.read(f, columns="t=time,ax=ax")


# ---- Parquet with its own names -----------------------------------------------------------

def test_parquet_through_a_mapping(tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    f = tmp_path / "phone.parquet"
    pd.DataFrame({"time_ms": T * 1e3, "accX": AX, "accY": AY}).to_parquet(f)
    rec = io.read(f, columns="t=time_ms:ms,ax=accX:g,ay=accY")
    np.testing.assert_allclose(rec.t, T, atol=1e-15)
    np.testing.assert_allclose(rec["ax"], AX * G, rtol=1e-15)
    streamed = ChunkedRecording(f, columns="t=time_ms:ms,ax=accX:g", chunk_rows=16).read()
    np.testing.assert_array_equal(streamed["ax"], rec["ax"])
    with pytest.raises(ReaderError, match=r"column 'accQ': column not found"):
        io.read(f, columns="t=time_ms:ms,ax=accQ")


# ---- arbitrary text -----------------------------------------------------------------------

@given(st.text(max_size=12))
def test_unit_name_is_a_known_unit_or_none(text):
    from vibrospeed.io.mapped import unit_name

    u = unit_name(text)
    assert u is None or u in UNITS


_cell = st.one_of(st.sampled_from(["s", "ms", "g", "[m/s²]", "(g)", "", "nan", "°C", "x"]),
                  st.floats(allow_nan=False, allow_infinity=False, width=32).map(repr),
                  st.sampled_from(["2024-05-01T12:00:00Z", "2024-05-01 12:00:01.5"]),
                  st.text(alphabet="0123456789.,;-eT:Z+ ", max_size=8))


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(_cell, min_size=2, max_size=3), min_size=1, max_size=6),
       sep=st.sampled_from([",", ";", "\t"]))
def test_mapped_reader_reads_or_refuses_in_one_line(tmp_path, rows, sep):
    f = tmp_path / "any.csv"
    f.write_text("\n".join([sep.join(["time", "a", "b"])] + [sep.join(r) for r in rows]) + "\n")
    try:
        rec = read_mapped(f, columns="t=time,ax=a")
    except (ReaderError, ParameterError) as exc:
        assert "\n" not in str(exc)
    else:
        assert np.all(np.diff(rec.t) > 0) and all(math.isfinite(v) for v in rec.t)


# ---- phone apps ---------------------------------------------------------------------------

def _sensorlogger_csv(path, t_ns, cols) -> None:
    rows = [f"{int(t)},{(t - t_ns[0]) / 1e9!r},{z!r},{y!r},{x!r}"
            for t, (x, y, z) in zip(t_ns.tolist(), zip(*(c.tolist() for c in cols), strict=True),
                                    strict=True)]
    path.write_text("time,seconds_elapsed,z,y,x\n" + "\n".join(rows) + "\n")


def test_sensorlogger_note_names_only_the_files_there(tmp_path):
    t_ns = 1_700_000_000_000_000_000 + np.arange(N) * 10_000_000
    _sensorlogger_csv(tmp_path / "TotalAcceleration.csv", t_ns, (AX, AY, AY + G))
    rec = io.read(tmp_path)
    np.testing.assert_allclose(rec.t, T, atol=2.6e-7)  # ns epoch in float64: 0.25 us (docs)
    np.testing.assert_array_equal(rec["ax"], AX)
    assert not any("Accelerometer.csv" in n for n in rec.notes), rec.notes
    _sensorlogger_csv(tmp_path / "Accelerometer.csv", t_ns, (AX, AY, AY))
    rec = io.read(tmp_path)
    np.testing.assert_allclose(rec["lin_az"], AY, atol=1e-12)
    assert any("Accelerometer.csv (without gravity) as lin_ax" in n for n in rec.notes)


def test_excel_sep_line_names_the_delimiter(tmp_path):
    f = tmp_path / "x.csv"
    f.write_text("sep=;\nt;ax;ay\n0;1,5;2\n0.01;2;3\n")  # ',' is no delimiter here
    assert io.detect_format(f) == "csv"
    with pytest.raises(ReaderError, match=r"line 3, column 'ax': '1,5' is not a number"):
        io.read(f)
    f.write_text("sep=;\nt;ax;ay\n0;1.5;2\n0.01;2;3\n")
    rec = io.read(f)
    np.testing.assert_array_equal(rec["ax"], [1.5, 2.0])
    assert any("'sep=;'" in n for n in rec.notes)


def test_windows_export_in_cp1252(tmp_path):
    f, m = tmp_path / "win.csv", tmp_path / "map.toml"
    f.write_bytes("Zeit;ax [m/s²]\r\n0;1,25\r\n0,01;-2\r\n".encode("cp1252"))
    with pytest.raises(ReaderError, match=r"line 1: not UTF-8 text .*encoding = \"cp1252\""):
        io.read(f, columns="t=Zeit")
    m.write_text('delimiter = ";"\ndecimal = ","\nencoding = "cp1252"\n'
                 '[columns]\nt = "Zeit"\nax = "ax [m/s²]"\n', encoding="utf-8")
    rec = io.read(f, mapping_file=m)
    np.testing.assert_array_equal(rec["ax"], [1.25, -2.0])
    np.testing.assert_array_equal(ChunkedRecording(f, mapping_file=m).read()["ax"], rec["ax"])
    m.write_text('encoding = "hex"\n[columns]\nt = "Zeit"\n')
    with pytest.raises(ParameterError, match="unknown encoding 'hex'"):
        io.read(f, mapping_file=m)


def test_excel_unicode_text_and_binary_files_are_named_as_such(tmp_path):
    f, m = tmp_path / "u16.txt", tmp_path / "map.toml"
    f.write_bytes("Zeit\tax\r\n0\t1,5\r\n0,01\t-2\r\n".encode("utf-16"))  # with its BOM
    with pytest.raises(ReaderError, match=r"UTF-16 text .*encoding = \"utf-16\""):
        io.read(f, columns="t=Zeit,ax=ax")
    m.write_text('decimal = ","\nencoding = "utf-16"\n[columns]\nt = "Zeit"\nax = "ax"\n')
    np.testing.assert_array_equal(io.read(f, mapping_file=m)["ax"], [1.5, -2.0])
    b = tmp_path / "x.csv"
    b.write_bytes(b"PAR1" + bytes(range(256)) * 4)  # NUL and bytes no text decodes
    with pytest.raises(ReaderError, match=r"x.csv: a binary file, not CSV text"):
        io.read(b, "csv")


def test_a_decimal_comma_through_columns_gets_the_hint(tmp_path):
    # the t column may hold ISO times through a mapping, whose error had lost the comma hint
    p = tmp_path / "eu.csv"
    p.write_text("t;ax;ay;az\n0,00;0,1;0,2;9,8\n0,01;0,1;0,3;9,8\n")
    with pytest.raises(ReaderError) as err:
        read_mapped(p, columns="t=t,ax=ax,ay=ay,az=az")
    assert str(err.value) == (f"{p}, line 2, column 't': '0,00' is neither a number nor an "
                              "ISO-8601 time (e.g. 2024-05-01T12:00:00.250Z) (a decimal comma? "
                              "give --decimal , or decimal = \",\" in a --mapping TOML file, "
                              "see docs/formats.md)")
