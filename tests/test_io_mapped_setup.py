"""One mapping set-up for the whole-file and the chunked mapped reader
(io.mapped.resolve_mapping), and day-first slash dates in a mapped time column."""

import datetime as dt
import io
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from vibrospeed.errors import InputError, VibrospeedError
from vibrospeed.io._csv import CsvTable
from vibrospeed.io.chunks import ChunkedRecording
from vibrospeed.io.mapped import read_mapped

LOG = "time,acc_y,yaw\nms,g,deg/s\n0,0.5,10\n10,-0.25,20\n20,1,-30\n30,0,40\n40,2,50\n"


def _epoch(*args) -> float:
    """Seconds since 1970-01-01 UTC by datetime arithmetic (independent of pandas)."""
    d = dt.datetime(*args, tzinfo=dt.UTC) - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
    return d // dt.timedelta(microseconds=1) * 1e-6


def _both(path, **kw):
    """What the whole-file reader and the chunked reader (2-row chunks) make of ``path``:
    (recording, chunked recording), or the two errors as (type, text)."""
    out = []
    for read in (lambda: read_mapped(path, **kw),
                 lambda: ChunkedRecording(path, chunk_rows=2, fmt="mapped", **kw).read()):
        try:
            out.append(read())
        except VibrospeedError as exc:
            out.append((type(exc).__name__, str(exc)))
    return out


BAD = [
    ({"rate": 10.0}, "a column mapping is needed"),
    ({"columns": "t=time,ay=acc_y", "rate": 10.0}, "either a time column 't' or a sample rate"),
    ({"columns": "ay=acc_y"}, "no time column mapped"),
    ({"columns": "ay=acc_y", "rate": -5.0}, "sample rate must be positive, got -5.0"),
    ({"columns": "t=time,ay=acc_y:m/s"}, "unit 'm/s' gives m/s, but ay is in m/s^2"),
    ({"columns": "t=time,ay=acc_y:furlong"}, "unknown unit 'furlong'"),
    ({"columns": "t=time,ay=acc_y:mg"}, "gives unit 'mg' but the units row (line 2) says 'g'"),
    ({"columns": "t=time,ay=nope"}, "nope"),
]


@pytest.mark.parametrize(("kw", "said"), BAD, ids=[b[1][:20] for b in BAD])
def test_a_bad_mapping_is_the_same_error_from_both_readers(tmp_path, kw, said):
    p = tmp_path / "log.csv"
    p.write_text(LOG)
    whole, chunked = _both(p, **kw)
    assert whole == chunked
    assert whole[0] in ("ParameterError", "ReaderError") and said in whole[1]
    assert str(p) in whole[1] and "\n" not in whole[1]


def test_a_bad_toml_option_is_the_same_error_from_both_readers(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text(LOG)
    m = tmp_path / "map.toml"
    m.write_text('dayfirst = "yes"\n[columns]\nt = "time"\n')
    whole, chunked = _both(p, mapping_file=m)
    assert whole == chunked == ("ParameterError", f"{m}: dayfirst must be true or false, "
                                                  "got 'yes'")


@pytest.mark.parametrize("kw", [{"columns": "t=time,ay=acc_y,gz=yaw*0.5"},
                                {"columns": "ay=acc_y,gz=yaw*2:deg/s", "rate": 50.0}])
def test_a_good_mapping_gives_the_same_data_from_both_readers(tmp_path, kw):
    p = tmp_path / "log.csv"
    p.write_text(LOG)
    whole, chunked = _both(p, **kw)
    assert np.array_equal(whole.t, chunked.t)
    assert whole.channels.keys() == chunked.channels.keys()
    for k in whole.channels:
        assert np.array_equal(whole[k], chunked[k])
    assert whole.units == chunked.units and whole.meta == chunked.meta
    if "rate" in kw:  # no time column: i / 50 Hz; yaw scaled 2, then deg/s to rad/s
        assert np.array_equal(whole.t, np.arange(5) / 50.0)
        np.testing.assert_allclose(whole["gz"], 2 * np.deg2rad([10, 20, -30, 40, 50]),
                                   rtol=1e-15)
    else:  # ms and g from the units row; a scaled column keeps its scale alone (no unit)
        np.testing.assert_allclose(whole.t, [0, 0.01, 0.02, 0.03, 0.04], rtol=1e-15)
        np.testing.assert_allclose(whole["ay"], np.array([0.5, -0.25, 1, 0, 2]) * 9.80665,
                                   rtol=1e-15)
        np.testing.assert_array_equal(whole["gz"], [5.0, 10.0, -15.0, 20.0, 25.0])


# ---- day-first slash dates ---------------------------------------------------------------
def _dated(tmp_path, first: str, dayfirst: str | None = None):
    p = tmp_path / "eu.csv"
    p.write_text(f"time;acc_y\n{first};0,5\n03/12/2026 14:05:01.260;1,5\n03/12/2026 14:05:01.27;"
                 "-1\n")
    m = tmp_path / "map.toml"
    m.write_text(("" if dayfirst is None else f"dayfirst = {dayfirst}\n")
                 + 'decimal = ","\n[columns]\nt = "time"\nay = "acc_y"\n')
    return p, m


def test_dayfirst_reads_dd_mm_yyyy_in_both_readers(tmp_path):
    p, m = _dated(tmp_path, "03/12/2026 14:05:01.250", "true")
    whole, chunked = _both(p, mapping_file=m)
    want = [_epoch(2026, 12, 3, 14, 5, 1, 250_000), _epoch(2026, 12, 3, 14, 5, 1, 260_000),
            _epoch(2026, 12, 3, 14, 5, 1, 270_000)]
    np.testing.assert_allclose(whole.t, want, rtol=0, atol=1e-6)
    assert np.array_equal(whole.t, chunked.t)
    np.testing.assert_array_equal(whole["ay"], [0.5, 1.5, -1.0])
    assert any("dd/mm/yyyy dates read as seconds" in n for n in whole.notes)


def test_dayfirst_false_reads_month_first(tmp_path):
    p, m = _dated(tmp_path, "03/12/2026 14:05:01", "false")
    p.write_text("time,acc_y\n03/12/2026 14:05:01,1\n03/12/2026 14:05:02.5,2\n")
    m.write_text('dayfirst = false\n[columns]\nt = "time"\nay = "acc_y"\n')
    r = read_mapped(p, mapping_file=m)
    np.testing.assert_allclose(r.t, [_epoch(2026, 3, 12, 14, 5, 1), _epoch(2026, 3, 12, 14, 5, 2,
                                                                            500_000)], atol=1e-6)


def test_a_day_above_12_without_dayfirst_is_one_line_asking_for_it(tmp_path):
    p, m = _dated(tmp_path, "13/12/2026 14:05:01.250")
    whole, chunked = _both(p, mapping_file=m)
    assert whole == chunked == (
        "ReaderError", f"{p}, line 2, column 'time': '13/12/2026 14:05:01.250' is a day-first "
        "date (13 is no month): give dayfirst = true in the mapping file")


def test_an_ambiguous_slash_date_without_dayfirst_is_refused(tmp_path):
    """Before the option such a date was refused too (not an ISO time): no month-first guess."""
    p, m = _dated(tmp_path, "03/12/2026 14:05:01.250")
    with pytest.raises(InputError, match=r"line 2, column 'time': '03/12/2026 14:05:01.250' is "
                       r"a slash date, day or month first\?: give dayfirst = true \(dd/mm/yyyy\)"
                       r" or dayfirst = false"):
        read_mapped(p, mapping_file=m)


def test_a_bad_date_under_dayfirst_names_its_line(tmp_path):
    p, m = _dated(tmp_path, "03/12/2026 14:05:01.250", "true")
    p.write_text(p.read_text().replace("03/12/2026 14:05:01.27", "31/02/2026 14:05:01.27"))
    whole, chunked = _both(p, mapping_file=m)
    assert whole == chunked == (
        "ReaderError", f"{p}, line 4, column 'time': '31/02/2026 14:05:01.27' is not a "
        "dd/mm/yyyy hh:mm:ss[.fff] time (dayfirst = true)")


@settings(max_examples=40, deadline=None)
@given(st.lists(st.datetimes(min_value=dt.datetime(1900, 1, 1),
                             max_value=dt.datetime(2200, 12, 31)), min_size=1, max_size=8),
       st.booleans())
@example([dt.datetime(2164, 1, 1, 0, 0, 0, 487)], False)  # 2 ulp apart from a us-based float
def test_day_first_dates_round_trip_to_epoch_seconds(stamps, millis):
    """Any datetime written dd/mm/yyyy hh:mm:ss.ffffff (or to the millisecond) reads back as
    the seconds datetime arithmetic gives, to float64's precision."""
    if millis:
        stamps = [s.replace(microsecond=s.microsecond // 1000 * 1000) for s in stamps]
    text = [s.strftime("%d/%m/%Y %H:%M:%S.%f")[: -3 if millis else None] for s in stamps]
    tab = CsvTable(io.StringIO("t,x\n" + "".join(f"{c},1\n" for c in text)), "mem.csv",
                   dates=("t",), dayfirst=True)
    cols, _ = tab.read(["t"])
    for got, s in zip(cols["t"], stamps, strict=True):
        us = (s.replace(tzinfo=dt.UTC) - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)) \
            // dt.timedelta(microseconds=1)
        # exact seconds vs float64 (~1e-6 s apart near 2200): within 2 ulp of the true value
        assert abs(Fraction(float(got)) - Fraction(us, 10**6)) <= 2 * np.spacing(abs(us * 1e-6))
