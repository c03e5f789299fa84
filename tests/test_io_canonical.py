"""Canonical CSV: exact round trips, awkward-but-valid input, and one-line errors."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vibrospeed.errors import ReaderError
from vibrospeed.io import read, write
from vibrospeed.io.canonical import event_path, read_csv, write_csv
from vibrospeed.types import Recording

_FINITE = st.floats(allow_nan=False, allow_infinity=False, width=64)
_FAST = {"deadline": None, "suppress_health_check": [HealthCheck.function_scoped_fixture]}


@st.composite
def _recordings(draw):
    n = draw(st.integers(1, 30))
    steps = draw(st.lists(st.floats(1e-9, 1e6), min_size=n, max_size=n))
    t = draw(st.floats(-1e6, 1e6)) + np.cumsum(steps)
    # strictly increasing after rounding, or rebuild a simple one
    if not np.all(np.diff(t) > 0):
        t = np.arange(n, dtype=float) * 0.01
    names = draw(st.lists(st.sampled_from(["ax", "ay", "az", "gz", "gps_speed", "my col", "x,y"]),
                          min_size=1, max_size=4, unique=True))
    chans = {}
    for k in names:
        vals = draw(st.lists(st.one_of(_FINITE, st.just(np.nan)), min_size=n, max_size=n))
        vals[draw(st.integers(0, n - 1))] = draw(_FINITE)  # at least one number
        # a speed over ground is a magnitude: a negative one is read as "no fix" (NaN)
        chans[k] = np.abs(vals) if k == "gps_speed" else np.array(vals)
    events = {}
    if draw(st.booleans()):
        events["wss_ticks"] = np.array(draw(st.lists(_FINITE, max_size=10)))
    return Recording(t=t, channels=chans, events=events,
                     wheel_radius=draw(st.one_of(st.none(), st.floats(0.01, 1.0))))


@settings(max_examples=40, **_FAST)
@given(rec=_recordings())
def test_round_trip_exact(tmp_path, rec):
    p = tmp_path / "rec.csv"
    write(rec, p)
    back = read(p)
    np.testing.assert_array_equal(back.t, rec.t)
    assert list(back.channels) == list(rec.channels)
    for k, v in rec.channels.items():
        np.testing.assert_array_equal(back[k], v)  # NaN == NaN here, bits otherwise
    assert set(back.events) == set(rec.events)
    for k, v in rec.events.items():
        np.testing.assert_array_equal(back.events[k], np.sort(v))
    assert back.wheel_radius == rec.wheel_radius
    assert back.units == rec.units


def test_sidecars_layout_and_stale_events_removed(tmp_path):
    p = tmp_path / "drive.csv"
    rec = Recording(t=[0.0, 0.5, 1.0], channels={"ay": [1.0, 2.0, 3.0], "temp": [20, 21, 22]},
                    units={"temp": "degC"}, events={"wss_ticks": [0.1, 0.7]}, wheel_radius=0.08)
    write_csv(rec, p)
    assert p.read_text().splitlines() == ["t,ay,temp", "0.0,1.0,20.0", "0.5,2.0,21.0",
                                          "1.0,3.0,22.0"]
    assert event_path(p, "wss_ticks").read_text() == "t\n0.1\n0.7\n"
    side = json.loads((tmp_path / "drive.csv.json").read_text())
    assert side["kind"] == "recording" and side["units"]["temp"] == "degC"
    back = read_csv(p)
    assert back.units["temp"] == "degC" and back.wheel_radius == 0.08
    write_csv(Recording(t=[0.0, 1.0], channels={"ay": [0.0, 1.0]}), p)
    assert not event_path(p, "wss_ticks").exists()
    assert read_csv(p).events == {}


def test_plain_csv_without_sidecars_bom_crlf_nan_jitter(tmp_path):
    p = tmp_path / "phone.csv"
    text = "\ufefft,ax,ay\r\n0.000,1,2\r\n0.011,,3\r\n\r\n0.019,NaN,4\r\n0.031,5,\r\n0.040,6,7\r\n"
    p.write_bytes(text.encode())
    r = read(p)
    np.testing.assert_array_equal(r.t, [0.0, 0.011, 0.019, 0.031, 0.040])
    np.testing.assert_array_equal(r["ax"], [1, np.nan, np.nan, 5, 6])
    notes = " | ".join(r.notes)
    for word in ("byte-order mark", "CRLF", "blank line", "'ax': 2 empty", "non-uniform"):
        assert word in notes
    assert r.units["ax"] == "m/s^2"


def test_time_gap_is_noted(tmp_path):
    p = tmp_path / "gap.csv"
    t = np.concatenate([np.arange(50) * 0.01, 3 + np.arange(50) * 0.01])
    write(Recording(t=t, channels={"ay": np.sin(t)}), p)
    assert any("time gap" in n for n in read(p).notes)


@pytest.mark.parametrize(
    ("content", "pattern"),
    [
        ("", r"x\.csv: empty file"),
        ("\n\n", r"x\.csv: empty file \(no header row\)"),
        ("t,ay\n", r"x\.csv, line 1: no data rows"),
        ("t,ay\n0,1\n0.1,abc\n", r"x\.csv, line 3, column 'ay': 'abc' is not a number"),
        ("t,ay\n0,1\n0.1\n", r"x\.csv, line 3: expected 2 fields, found 1"),
        ("t,ay\n0,1\n0.1,2,3\n", r"x\.csv, line 3: expected 2 fields, found 3"),
        ("t,ay\n0,\n0.1,\n", r"x\.csv, column 'ay': channel has no numeric value"),
        ("t,ay\n0,1\n0.2,1\n0.1,1\n", r"x\.csv, line 4, column 't': time goes backwards"),
        ("t,ay\n0,1\n,1\n", r"x\.csv, line 3, column 't': time is nan"),
        ("t,ay,ay\n0,1,1\n", r"x\.csv, line 1, column 'ay': duplicate column name"),
        ("time,ay\n0,1\n", r"x\.csv, line 1: unknown format"),
        ("t,ay\n0,1\n1,\x00\n", r"x\.csv, line 3, column 'ay': '\\x00' is not a number"),
    ],
)
def test_errors_are_one_line_reader_errors(tmp_path, content, pattern):
    p = tmp_path / "x.csv"
    p.write_text(content)
    with pytest.raises(ReaderError, match=pattern) as exc:
        read(p)
    assert "\n" not in str(exc.value)


def test_missing_file_and_unknown_format(tmp_path):
    with pytest.raises(ReaderError, match="nope.csv: file not found"):
        read(tmp_path / "nope.csv")
    (tmp_path / "a.csv").write_text("t,ay\n0,1\n")
    with pytest.raises(ReaderError, match="unknown format 'xls'"):
        read(tmp_path / "a.csv", format="xls")
    with pytest.raises(ReaderError, match=r"channel 'az' is missing"):
        read(tmp_path / "a.csv", require=["az"])


def test_sort_option_repairs_time(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("t,ay\n0.2,2\n0.0,0\n0.1,1\n0.1,9\n")
    r = read(p, sort=True)
    np.testing.assert_array_equal(r.t, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(r["ay"], [0.0, 1.0, 2.0])


def test_not_utf8(tmp_path):
    p = tmp_path / "b.csv"
    p.write_bytes(b"t,ay\n0,1\n1,\xff\xfe\n")
    with pytest.raises(ReaderError, match="not UTF-8"):
        read(p)


_GOOD = "t,ax,ay\n" + "".join(f"{i * 0.01!r},{float(np.sin(i))!r},{float(np.cos(i))!r}\n"
                               for i in range(20))


@settings(max_examples=150, **_FAST)
@given(data=st.one_of(st.binary(max_size=300), st.text(max_size=300)))
def test_garbage_raises_reader_error_only(tmp_path, data):
    p = tmp_path / "g.csv"
    p.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass"))
    try:
        rec = read(p, format="csv")
    except ReaderError as exc:
        assert "\n" not in str(exc)
    else:
        assert isinstance(rec, Recording) and np.all(np.diff(rec.t) > 0)


@settings(max_examples=100, **_FAST)
@given(cut=st.integers(0, len(_GOOD)), junk=st.text(max_size=8), where=st.integers(0, len(_GOOD)))
def test_truncated_or_corrupted_rows(tmp_path, cut, junk, where):
    p = tmp_path / "t.csv"
    for text in (_GOOD[:cut], _GOOD[:where] + junk + _GOOD[where:]):
        p.write_text(text, encoding="utf-8", errors="surrogatepass")
        try:
            rec = read(p)
        except ReaderError as exc:
            assert "\n" not in str(exc)
        else:
            assert np.all(np.diff(rec.t) > 0)
    # a cut strictly inside the data rows either fails or yields a prefix of the rows
    p.write_text(_GOOD[:cut])
    try:
        rec = read(p)
    except ReaderError:
        return
    full = _read_text(tmp_path, _GOOD)
    n = len(rec)
    np.testing.assert_array_equal(rec.t[: n - 1], full.t[: n - 1])


def _read_text(folder, text):
    q = folder / "full.csv"
    q.write_text(text)
    return read(q)


def test_decimal_comma_is_refused_with_the_way_to_read_it(tmp_path):
    """A ';'-separated file with decimal commas (a European spreadsheet's export) is refused,
    never guessed (``1,234`` could be a thousands separator), and the one-line error says how to
    read it: a mapping file with ``decimal = ","``, which then reads the same numbers."""
    p = tmp_path / "x.csv"
    p.write_text("t;ay\n0,0;1,5\n0,01;-2,25\n")
    with pytest.raises(ReaderError, match=r"x\.csv, line 2, column 't': '0,0' is not a number "
                                          r"\(a decimal comma\? .*decimal = \",\"") as exc:
        read(p)
    assert "\n" not in str(exc.value)
    m = tmp_path / "m.toml"
    m.write_text('decimal = ","\n[columns]\nt = "t"\nay = "ay"\n')
    r = read(p, mapping_file=m)
    np.testing.assert_array_equal(r.t, [0.0, 0.01])
    np.testing.assert_array_equal(r["ay"], [1.5, -2.25])
    for content in ("t;ay\n0;1\n1;abc\n", 't,ay\n0,1\n1,"2,5"\n'):  # no number, or ',' fields
        p.write_text(content)
        with pytest.raises(ReaderError, match="is not a number$"):
            read(p)
