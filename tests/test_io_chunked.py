"""Chunked reading (:mod:`vibrospeed.io.chunks`): the chunks put together are the whole file."""

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed import io
from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.io.chunks import ChunkedRecording
from vibrospeed.types import Recording

SUFFIXES = [".csv"]
try:
    import pyarrow  # noqa: F401

    SUFFIXES.append(".parquet")
except ImportError:  # pragma: no cover - the parquet extra is optional
    pass

finite = st.floats(-1e9, 1e9, allow_nan=False, allow_subnormal=True)
cell = st.one_of(finite, st.just(float("nan")))


@st.composite
def recordings(draw):
    n = draw(st.integers(1, 120))
    names = draw(st.lists(st.sampled_from(["ax", "ay", "az", "gz", "temp"]), min_size=1,
                          max_size=4, unique=True))
    steps = draw(st.lists(st.floats(1e-4, 10.0), min_size=n, max_size=n))
    t = draw(st.floats(-1e3, 1e3)) + np.cumsum(steps)
    ch = {}
    for k in names:
        x = np.array(draw(st.lists(cell, min_size=n, max_size=n)), dtype=float)
        if np.isnan(x).all():
            x[0] = 0.0
        ch[k] = x
    return Recording(t, ch, wheel_radius=0.3, notes=["from a test"], meta={"k": 1})


def same(a, b):
    np.testing.assert_array_equal(a, b)  # NaN == NaN here, -0.0 == 0.0 is checked below
    assert np.array_equal(np.signbit(a), np.signbit(b))


@settings(max_examples=60, deadline=None)
@given(recordings(), st.integers(1, 130), st.sampled_from(SUFFIXES))
def test_chunks_put_together_are_the_whole_file(rec, chunk_rows, suffix):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"r{suffix}"
        io.write(rec, p)
        whole = io.read(p)
        src = ChunkedRecording(p, chunk_rows=chunk_rows)
        chunks = list(src)
        assert all(0 < len(c) <= chunk_rows for c in chunks)
        assert [c.start for c in chunks] == list(np.cumsum([0] + [len(c) for c in chunks])[:-1])
        assert src.n == len(whole) == sum(len(c) for c in chunks)
        same(np.concatenate([c.t for c in chunks]), whole.t)
        for k in whole.channels:
            same(np.concatenate([c.channels[k] for c in chunks]), whole[k])
        assert src.channels == list(whole.channels)
        assert whole.notes[: len(src.notes)] == src.notes  # the whole read adds time-base notes
        back = src.read()
        assert back.wheel_radius == whole.wheel_radius and back.meta == whole.meta
        assert back.units == whole.units
        lines = np.concatenate([c.lines for c in chunks])
        first = 2 if suffix == ".csv" else 1  # CSV: line 1 is the header
        np.testing.assert_array_equal(lines, np.arange(first, first + len(whole)))


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize("bad", [1, 5, 6, 7, 19])
@pytest.mark.parametrize("kind", ["back", "repeat", "nan"])
def test_time_errors_name_the_same_line_at_any_chunk_boundary(tmp_path, suffix, bad, kind):
    t = np.arange(20) * 0.01
    t[bad] = {"back": t[bad - 1] - 0.005, "repeat": t[bad - 1], "nan": np.nan}[kind]
    p = tmp_path / f"r{suffix}"
    io.write(Recording(t, {"ay": np.arange(20.0)}), p)
    with pytest.raises(ReaderError) as whole:
        io.read(p)
    for rows in (1, 3, 5, 6, 7, 50):
        with pytest.raises(ReaderError) as chunked:
            list(ChunkedRecording(p, chunk_rows=rows))
        assert str(chunked.value) == str(whole.value)


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_all_nan_channel_and_bad_cells(tmp_path, suffix):
    p = tmp_path / f"r{suffix}"
    io.write(Recording(np.arange(10.0), {"ay": np.full(10, np.nan), "ax": np.ones(10)}), p)
    with pytest.raises(ReaderError) as whole:
        io.read(p)
    with pytest.raises(ReaderError) as chunked:
        list(ChunkedRecording(p, chunk_rows=3))
    assert str(chunked.value) == str(whole.value)


def test_csv_text_cell_error_same_as_whole_read(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("t,ay\n0,1\n0.01,2\n\n0.02,x\n0.03,4\n")
    with pytest.raises(ReaderError) as whole:
        io.read(p)
    with pytest.raises(ReaderError) as chunked:
        list(ChunkedRecording(p, chunk_rows=1))
    assert str(chunked.value) == str(whole.value) and "line 5" in str(chunked.value)


def test_not_canonical_and_bad_arguments(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("time,ay\n0,1\n")
    with pytest.raises(ReaderError, match="not a canonical recording"):
        ChunkedRecording(p)
    q = tmp_path / "q.csv"
    io.write(Recording(np.arange(3.0), {"ay": np.ones(3)}), q)
    with pytest.raises(ValueError, match="chunk_rows"):
        ChunkedRecording(q, chunk_rows=0)
    with pytest.raises(ReaderError, match="csv, parquet and mapped"):
        ChunkedRecording(q, fmt="phyphox")


# ---- ordering of errors: a bad cell, then an all-NaN channel, then a time error ---------------
@pytest.mark.parametrize("rows", [1, 2, 4, 50])
def test_errors_come_in_the_whole_readers_order(tmp_path, rows):
    """A time error early in the file and a bad cell (or an all-NaN channel) later: the
    whole-file reader names the later one (it parses everything before checking time); so
    does a chunked pass, at any chunk size, and it hands out no chunk past the time error."""
    p = tmp_path / "r.csv"
    p.write_text("t,ay,ax\n0,1,\n0.01,2,\n0.005,3,\n0.03,4,\n0.04,x,\n")
    for text in ("t,ay,ax\n0,1,1\n0.01,2,1\n0.005,3,1\n0.03,4,1\n0.04,x,1\n",  # bad cell
                 "t,ay,ax\n0,1,\n0.01,2,\n0.005,3,\n0.03,4,\n0.04,5,\n",  # ax all empty
                 "t,ay\n0,1\n0.01,2\n0.005,3\n0.03,4\n"):  # the time error alone
        p.write_text(text)
        with pytest.raises(ReaderError) as whole:
            io.read(p)
        src = ChunkedRecording(p, chunk_rows=rows)
        got = []
        with pytest.raises(ReaderError) as chunked:
            for c in src:
                got.append(c)
        assert str(chunked.value) == str(whole.value)
        assert sum(len(c) for c in got) <= 2  # none of the rows from the bad time on


# ---- CSV files through a column mapping --------------------------------------------------------
# units that fit each drawn channel (a unit of another quantity is refused)
UNIT_NAMES = {"ax": ["g", "mg", "m/s^2", "counts", None], "gz": ["deg/s", "rpm", "rad/s", None]}
UNIT_NAMES["ay"] = UNIT_NAMES["az"] = UNIT_NAMES["ax"]


@st.composite
def mapped_files(draw):
    """A delimited file with a text column, raw columns and either a time column in ms or
    none (a rate), and a mapping with scales, offsets and units."""
    n = draw(st.integers(1, 90))
    with_t = draw(st.booleans())
    steps = draw(st.lists(st.floats(0.1, 50.0), min_size=n, max_size=n))
    t_ms = draw(st.floats(-1e4, 1e4)) + np.cumsum(steps)
    names = draw(st.lists(st.sampled_from(["ax", "ay", "az", "gz"]), min_size=1, max_size=3,
                          unique=True))
    delim = draw(st.sampled_from([",", ";"]))
    raw = {}
    items = []
    for k, name in enumerate(names):
        x = np.array(draw(st.lists(cell, min_size=n, max_size=n)), dtype=float)
        if np.isnan(x).all():
            x[-1] = 1.5
        raw[f"c{k}"] = x
        unit = draw(st.sampled_from(UNIT_NAMES[name]))
        scale = draw(st.sampled_from([1.0, 0.00478, -2.5]))
        items.append((name, f"c{k}", scale, draw(st.sampled_from([0.0, -0.3])), unit))
    rate = None if with_t else draw(st.sampled_from([100.0, 198.4, 3.0]))
    return n, with_t, t_ms, raw, items, rate, delim


def _write_mapped(d: Path, case) -> tuple[Path, Path]:
    n, with_t, t_ms, raw, items, rate, delim = case
    p = d / "log.txt"
    head = ["date", *(["time_ms"] if with_t else []), *raw]
    lines = [delim.join(head)]
    for i in range(n):
        row = ["2026-01-01", *([repr(float(t_ms[i]))] if with_t else []),
               *("" if np.isnan(raw[c][i]) else repr(float(raw[c][i])) for c in raw)]
        lines.append(delim.join(row))
    p.write_text("\n".join(lines) + "\n")
    m = d / "map.toml"
    toml = ([f"rate = {rate!r}"] if rate is not None else []) + ["[columns]"]
    if with_t:
        toml.append('t = { column = "time_ms", unit = "ms" }')
    for name, col, scale, offset, unit in items:
        u = f', unit = "{unit}"' if unit else ""
        toml.append(f'{name} = {{ column = "{col}", scale = {scale!r}, offset = {offset!r}{u} }}')
    m.write_text("\n".join(toml) + "\n")
    return p, m


@settings(max_examples=60, deadline=None)
@given(mapped_files(), st.integers(1, 100))
def test_mapped_chunks_put_together_are_the_whole_file(case, chunk_rows):
    """Chunks of a mapped CSV (a TOML mapping with units, scales, offsets; a time column in ms
    or a rate) put together are bitwise what the whole-file reader gives, with its notes (less
    the time-base ones it adds at the end), units and meta."""
    with tempfile.TemporaryDirectory() as d:
        p, m = _write_mapped(Path(d), case)
        whole = io.read(p, mapping_file=m)
        src = ChunkedRecording(p, chunk_rows=chunk_rows, mapping_file=m)
        assert src.fmt == "mapped"
        chunks = list(src)
        same(np.concatenate([c.t for c in chunks]), whole.t)
        assert src.channels == list(whole.channels)
        for k in whole.channels:
            same(np.concatenate([c.channels[k] for c in chunks]), whole[k])
        assert whole.notes[: len(src.notes)] == src.notes
        assert len(whole.notes) - len(src.notes) <= 3  # describe_timebase's, gravity_notes' only
        back = src.read()
        assert back.units == whole.units and back.meta == whole.meta


@pytest.mark.parametrize("rows", [1, 3, 1000])
def test_mapped_columns_and_rate_from_the_command_line_strings(tmp_path, rows):
    p = tmp_path / "log.csv"
    p.write_text("date;time_ms;acc_y;yaw\nx;1000;1;180\nx;1010;0.5;-90\nx;1020;;0\n")
    cols = "t=time_ms:ms,ay=acc_y:g,gz=yaw*0.5:deg/s"
    whole = io.read(p, columns=cols)
    src = ChunkedRecording(p, chunk_rows=rows, columns=cols)
    back = src.read()
    same(back.t, whole.t)
    for k in whole.channels:
        same(back[k], whole[k])
    assert "channel 'acc_y': 1 empty or NaN cell(s) of 3" in src.notes
    q = tmp_path / "raw.csv"
    q.write_text("c1,c2\n100,1\n200,2\n300,3\n400,4\n")
    whole = io.read(q, columns="ax=c1*0.01", rate=198.4)
    back = ChunkedRecording(q, chunk_rows=rows, columns="ax=c1*0.01", rate=198.4).read()
    same(back.t, whole.t)
    same(back["ax"], whole["ax"])
    assert back.notes == whole.notes[: len(back.notes)]
    assert back.notes[-1] == "no time column: t = i / 198.4 Hz"


def _same_error(exc_type, whole_call, chunk_call):
    with pytest.raises(exc_type) as whole:
        whole_call()
    with pytest.raises(exc_type) as chunked:
        chunk_call()
    assert str(chunked.value) == str(whole.value)
    return str(whole.value)


@pytest.mark.parametrize("rows", [1, 2, 100])
def test_mapped_errors_are_the_whole_readers(tmp_path, rows):
    """Bad mappings, missing columns, text cells, all-empty columns, time going back: the
    same one-line error, naming the same file line and column."""
    p = tmp_path / "log.csv"
    p.write_text("time_ms,acc_y,e\n1000,1,\n1010,2,\n1005,x,\n1030,4,\n")
    cases = [
        (ParameterError, dict(columns="ay=acc_y")),  # no time, no rate
        (ParameterError, dict(columns="t=time_ms,ay=acc_y", rate=100.0)),  # both
        (ParameterError, dict(columns="ay=acc_y", rate=-1.0)),
        (ReaderError, dict(columns="t=time_ms:ms,ay=nope")),  # column not found
        (ReaderError, dict(columns="t=time_ms:ms,ay=acc_y")),  # text cell on line 4
        (ReaderError, dict(columns="t=time_ms:ms,ay=e")),  # no number in 'e'
    ]
    msgs = []
    for exc, kw in cases:
        msgs.append(_same_error(exc, lambda kw=kw: io.read(p, **kw),
                                lambda kw=kw: list(ChunkedRecording(p, chunk_rows=rows, **kw))))
    assert "line 4" in msgs[4] and "acc_y" in msgs[4]
    p.write_text("time_ms,acc_y\n1000,1\n1010,2\n1005,3\n1030,4\n")
    msg = _same_error(ReaderError, lambda: io.read(p, columns="t=time_ms:ms,ay=acc_y"),
                      lambda: list(ChunkedRecording(p, chunk_rows=rows,
                                                    columns="t=time_ms:ms,ay=acc_y")))
    assert "line 4" in msg
    with pytest.raises(ParameterError, match="does not take option 'rate'"):
        ChunkedRecording(p, fmt="csv", rate=10.0)
