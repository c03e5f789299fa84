"""Chunked reading (:mod:`vibrospeed.io.chunks`): the chunks put together are the whole file."""

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed import io
from vibrospeed.errors import ReaderError
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
    with pytest.raises(ReaderError, match="csv and parquet"):
        ChunkedRecording(q, fmt="phyphox")
