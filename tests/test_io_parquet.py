"""Parquet: exact round trip with metadata and events; errors."""

import numpy as np
import pytest

from vibrospeed.errors import ReaderError
from vibrospeed.io import detect_format, read, write
from vibrospeed.types import Recording

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")


def test_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.015, 1000))
    ay = rng.standard_normal(1000)
    ay[10:20] = np.nan
    rec = Recording(t=t, channels={"ay": ay, "gz": rng.standard_normal(1000), "temp": t * 0},
                    units={"temp": "degC"}, events={"wss_ticks": np.sort(rng.uniform(0, 10, 50))},
                    wheel_radius=0.31, notes=["simulated"], meta={"seed": 0})
    p = tmp_path / "r.parquet"
    write(rec, p)
    assert detect_format(p) == "parquet"
    back = read(p)
    np.testing.assert_array_equal(back.t, rec.t)
    for k in rec.channels:
        np.testing.assert_array_equal(back[k], rec[k])
    np.testing.assert_array_equal(back.events["wss_ticks"], rec.events["wss_ticks"])
    assert back.units == rec.units and back.wheel_radius == 0.31 and back.meta == {"seed": 0}
    assert back.notes[0] == "simulated"
    assert [f.name for f in pq.read_schema(p)] == ["t", "ay", "gz", "temp"]


def test_foreign_table_and_errors(tmp_path):
    p = tmp_path / "f.parquet"
    pq.write_table(pa.table({"t": [0, 1, 2], "ax": pa.array([1, None, 3], pa.int32())}), p)
    r = read(p)
    np.testing.assert_array_equal(r["ax"], [1, np.nan, 3])
    pq.write_table(pa.table({"t": [0.0, 1.0], "name": ["a", "b"]}), p)
    with pytest.raises(ReaderError, match="column 'name': column is not numeric"):
        read(p)
    pq.write_table(pa.table({"time": [0.0, 1.0]}), p)
    with pytest.raises(ReaderError, match="no 't' column"):
        read(p)
    pq.write_table(pa.table({"t": [0.0, 2.0, 1.0]}), p)
    with pytest.raises(ReaderError, match="line 3, column 't': time goes backwards"):
        read(p)
    p.write_bytes(b"PAR1 this is not parquet")
    with pytest.raises(ReaderError, match="not a readable Parquet file"):
        read(p)


def test_missing_pyarrow_is_a_clear_error(tmp_path, monkeypatch):
    import sys

    p = tmp_path / "r.parquet"
    write(Recording(t=[0.0, 1.0], channels={"ay": [1.0, 2.0]}), p)
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(ReaderError, match="needs the optional package pyarrow"):
        read(p)


def test_damaged_pages_give_one_line(tmp_path):
    """A Parquet file whose footer reads but whose first data page is overwritten: pyarrow's
    message ends in newlines ("Couldn't deserialize thrift ...\\nDeserializing page header
    failed.\\n"); the whole-file and the chunked reader both quote it on the error's one line."""
    from vibrospeed.io.chunks import ChunkedRecording

    p = tmp_path / "damaged.parquet"
    t = np.arange(2000) / 100
    write(Recording(t=t, channels={"ay": np.sin(t)}), p)
    raw = bytearray(p.read_bytes())
    raw[4:68] = b"\xff" * 64  # after the leading magic: the first column chunk's page header
    p.write_bytes(bytes(raw))
    for reader in (read, lambda q: list(ChunkedRecording(q, chunk_rows=500))):
        with pytest.raises(ReaderError, match="not a readable Parquet file") as info:
            reader(p)
        msg = str(info.value)
        assert "\n" not in msg and "  " not in msg and msg.startswith(f"{p}: ")
