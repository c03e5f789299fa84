"""Parquet recordings: the same columns as canonical CSV (``t`` first, then channels, SI).

Units, wheel radius, axes, notes and metadata travel in the schema's key-value metadata under
``vibrospeed`` (JSON); each event stream under ``vibrospeed.event.<name>`` as little-endian
float64 bytes. Written in row groups of 65 536 rows, so that a reader can stream them
(:class:`vibrospeed.io.chunks.ChunkedRecording`); reading streams record batches. Needs the
optional ``pyarrow`` package (``pip install vibrospeed[parquet]``); without it a clear
:class:`ReaderError` says so.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import InputError, ReaderError
from vibrospeed.io._common import exc_text, finish, jsonable
from vibrospeed.io._csv import check_file, nan_notes
from vibrospeed.io.atomic import atomic_path
from vibrospeed.types import Recording

__all__ = ["read_parquet", "write_parquet"]

_META = b"vibrospeed"
_EVENT = "vibrospeed.event."
_BATCH = 65536


def _pyarrow(path):
    try:
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.parquet as pq
    except ImportError:
        raise ReaderError(
            path, "Parquet needs the optional package pyarrow (pip install 'vibrospeed[parquet]')"
        ) from None
    return pa, pc, pq


def is_parquet(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a file starting with the Parquet magic ``PAR1``."""
    try:
        with open(path, "rb") as fh:
            return fh.read(4) == b"PAR1"
    except OSError:
        return False


def iter_columns(path: str | os.PathLike[str], names: list[str],
                 batch_rows: int = _BATCH) -> Iterator[dict[str, np.ndarray]]:
    """The Parquet columns ``names`` as float64, ``batch_rows`` rows at a time (a column
    mapping on a Parquet file, :mod:`.mapped`): numbers as they are, a timestamp column as
    seconds since 1970-01-01 UTC; a missing or non-numeric column is a :class:`ReaderError`
    naming it."""
    p = check_file(path)
    pa, pc, pq = _pyarrow(p)
    try:
        pf = pq.ParquetFile(p)
        schema = pf.schema_arrow
        for n in names:
            if n not in schema.names:
                raise ReaderError(p, f"column not found (have: {', '.join(schema.names)})",
                                  column=n)
            f = schema.field(n)
            if not (pa.types.is_floating(f.type) or pa.types.is_integer(f.type)
                    or pa.types.is_boolean(f.type) or pa.types.is_timestamp(f.type)):
                raise ReaderError(p, f"column is not numeric ({f.type})", column=n)
        for batch in pf.iter_batches(batch_size=batch_rows, columns=list(dict.fromkeys(names))):
            out = {}
            for n in names:
                col = batch.column(n)
                if pa.types.is_timestamp(col.type):  # naive stamps taken as UTC
                    ns = pc.cast(col, pa.timestamp("ns", col.type.tz)).cast(pa.int64())
                    out[n] = ns.to_numpy(zero_copy_only=False).astype(np.float64) * 1e-9
                    out[n][np.asarray(col.is_null())] = np.nan
                else:
                    out[n] = pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False)
            yield out
    except (pa.ArrowException, OSError) as exc:
        raise ReaderError(p, f"not a readable Parquet file ({exc_text(exc)})") from None


def write_parquet(rec: Recording, path: str | os.PathLike[str]) -> None:
    """Write ``rec`` to a Parquet file atomically (columns ``t`` + channels, metadata inside)."""
    p = Path(path)
    pa, _, pq = _pyarrow(p)
    names = list(rec.channels)
    if "t" in names:
        raise InputError(f"{p}: a channel may not be called 't'")
    table = pa.table({"t": rec.t, **{k: rec.channels[k] for k in names}})
    side = {
        "kind": "recording",
        "source": rec.source,
        "wheel_radius": rec.wheel_radius,
        "axes": rec.axes,
        "units": {k: rec.units.get(k, "") for k in names},
        "notes": list(rec.notes),
        "meta": jsonable(rec.meta),
    }
    md = {_META: json.dumps(side, allow_nan=False).encode()}
    for ev, times in rec.events.items():
        md[(_EVENT + ev).encode()] = np.ascontiguousarray(times, dtype="<f8").tobytes()
    table = table.replace_schema_metadata(md)
    with atomic_path(p) as tmp:
        pq.write_table(table, tmp, row_group_size=_BATCH)  # readable chunk by chunk


def read_parquet(path: str | os.PathLike[str], *, sort: bool = False) -> Recording:
    """Read a Parquet recording written by :func:`write_parquet` or any table with a numeric
    ``t`` column (s) and numeric channels. Errors name the column; "line" is the 1-based row."""
    p = check_file(path)
    pa, pc, pq = _pyarrow(p)
    try:
        pf = pq.ParquetFile(p)
        schema = pf.schema_arrow
        names = list(schema.names)
        if "t" not in names:
            raise ReaderError(p, f"no 't' column (have: {', '.join(names)})", column="t")
        for f in schema:
            if not (pa.types.is_floating(f.type) or pa.types.is_integer(f.type)
                    or pa.types.is_boolean(f.type)):
                raise ReaderError(p, f"column is not numeric ({f.type})", column=f.name)
        parts: dict[str, list[np.ndarray]] = {n: [] for n in names}
        for batch in pf.iter_batches(batch_size=_BATCH):
            for n in names:
                col = pc.cast(batch.column(n), pa.float64())
                parts[n].append(col.to_numpy(zero_copy_only=False))
        md = schema.metadata or {}
    except (pa.ArrowException, OSError) as exc:
        raise ReaderError(p, f"not a readable Parquet file ({exc_text(exc)})") from None
    cols = {n: (np.concatenate(v) if v else np.empty(0)) for n, v in parts.items()}
    t = cols.pop("t")
    if t.size == 0:
        raise ReaderError(p, "no data rows")
    notes = nan_notes(cols, str(p))
    side: dict[str, Any] = {}
    if _META in md:
        try:
            side = json.loads(md[_META].decode())
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ReaderError(p, f"unreadable vibrospeed metadata ({exc})") from None
        if not isinstance(side, dict):
            side = {}
    events = {}
    for key, val in md.items():
        k = key.decode(errors="replace")
        if k.startswith(_EVENT):
            if len(val) % 8:
                raise ReaderError(p, f"event '{k[len(_EVENT):]}' metadata is corrupt")
            events[k[len(_EVENT):]] = np.frombuffer(val, dtype="<f8").astype(np.float64)
    units = side.get("units") if isinstance(side.get("units"), dict) else {}
    wr = side.get("wheel_radius")
    meta = side.get("meta") if isinstance(side.get("meta"), dict) else {}
    return finish(
        t, cols, source=str(p), lines=np.arange(1, t.size + 1), sort=sort,
        units={k: str(v) for k, v in units.items() if k in cols}, events=events,
        notes=[*(side.get("notes") or []), *notes], meta=meta,
        wheel_radius=float(wr) if isinstance(wr, (int, float)) else None,
        axes=side.get("axes") if isinstance(side.get("axes"), str) else None,
    )
