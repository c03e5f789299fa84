"""Large recordings read in chunks: memory bounded by one chunk, not by the file.

:func:`read` (canonical CSV, Parquet) builds the whole :class:`~vibrospeed.types.Recording`:
a 24-hour 100 Hz log with six channels is ~400 MB of float64 once read, more while it is
parsed. :class:`ChunkedRecording` hands the same samples out ``chunk_rows`` rows at a time
(:class:`Chunk`), for work that streams: the causal trackers
(:class:`~vibrospeed.estimators.online.OnlineTracker`), statistics, conversion. Concatenating
the chunks gives exactly what the whole-file reader gives (same float64 values, same errors at
the same file lines); the checks that need the whole file are done as the chunks pass: time
strictly increasing across chunk boundaries (a stream cannot be sorted: ``--sort`` is for whole
reads), a channel with no number at all (raised at the end), NaN counts (notes at the end).

Example::

    from vibrospeed.io.chunks import ChunkedRecording
    src = ChunkedRecording("day.parquet", chunk_rows=100_000)
    for chunk in src:
        for y in chunk.channels["ay"]:
            tracker.update(y)
    print(src.notes)
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._csv import CHUNK_ROWS, CsvTable, open_text
from vibrospeed.io.timebase import check_increasing
from vibrospeed.types import Recording

__all__ = ["Chunk", "ChunkedRecording"]


@dataclass(frozen=True)
class Chunk:
    """Consecutive rows of a recording: ``t`` (s), ``channels`` (SI, NaN = missing), the
    1-based file ``lines`` (CSV lines; Parquet rows) and ``start``, the index of the first row
    in the whole recording."""

    t: np.ndarray
    channels: dict[str, np.ndarray]
    lines: np.ndarray
    start: int

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass
class ChunkedRecording:
    """A canonical CSV or Parquet recording read ``chunk_rows`` rows at a time.

    Iterating yields :class:`Chunk` s (a new pass reads the file again). ``channels`` (names),
    ``units``, ``wheel_radius``, ``axes``, ``meta`` come from the header / metadata before the
    first chunk; ``notes`` and ``n`` (rows) are complete once a pass has ended. Errors are the
    whole-file readers': :class:`~vibrospeed.errors.ReaderError` naming the file, line, column.
    """

    path: str | os.PathLike[str]
    chunk_rows: int = CHUNK_ROWS
    fmt: str = "auto"
    channels: list[str] = field(init=False, default_factory=list)
    units: dict[str, str] = field(init=False, default_factory=dict)
    wheel_radius: float | None = field(init=False, default=None)
    axes: str | None = field(init=False, default=None)
    meta: dict[str, Any] = field(init=False, default_factory=dict)
    notes: list[str] = field(init=False, default_factory=list)
    n: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        p = Path(self.path)
        if self.chunk_rows < 1:
            raise ValueError(f"chunk_rows must be at least 1, got {self.chunk_rows}")
        fmt = self.fmt
        if fmt == "auto":
            fmt = "parquet" if p.suffix.lower() in (".parquet", ".pq") else "csv"
        if fmt not in ("csv", "parquet"):
            raise ReaderError(p, f"chunked reading supports csv and parquet, not '{fmt}'")
        self.fmt = fmt
        self._side_notes: list[str] = []
        if fmt == "csv":
            self._csv_header(p)
        else:
            self._parquet_header(p)

    # ---- metadata ---------------------------------------------------------------------------
    def _csv_header(self, p: Path) -> None:
        from vibrospeed.io.canonical import _read_sidecar_json, is_canonical_header

        with open_text(p) as fh:
            tab = CsvTable(fh, str(p))
        if not is_canonical_header(tab.header):
            raise ReaderError(
                p, "not a canonical recording: the header must start with 't' followed by "
                "channel names (give a column mapping for other CSV files)", row=tab.header_line)
        self.channels = [h for h in tab.header if h][1:]
        side = _read_sidecar_json(p)
        self._side(side)
        if isinstance(side.get("source"), str) and side["source"]:
            self.meta.setdefault("origin", side["source"])

    def _parquet_header(self, p: Path) -> None:
        import json

        from vibrospeed.io._csv import check_file
        from vibrospeed.io.parquet import _META, _pyarrow

        check_file(p)
        pa, _, pq = _pyarrow(p)
        try:
            schema = pq.ParquetFile(p).schema_arrow
        except (pa.ArrowException, OSError) as exc:
            raise ReaderError(p, f"not a readable Parquet file ({exc})") from None
        names = list(schema.names)
        if "t" not in names:
            raise ReaderError(p, f"no 't' column (have: {', '.join(names)})", column="t")
        for f in schema:
            if not (pa.types.is_floating(f.type) or pa.types.is_integer(f.type)
                    or pa.types.is_boolean(f.type)):
                raise ReaderError(p, f"column is not numeric ({f.type})", column=f.name)
        self.channels = [n for n in names if n != "t"]
        md = schema.metadata or {}
        side: dict[str, Any] = {}
        if _META in md:
            try:
                side = json.loads(md[_META].decode())
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise ReaderError(p, f"unreadable vibrospeed metadata ({exc})") from None
            side = side if isinstance(side, dict) else {}
        self._side(side)

    def _side(self, side: dict[str, Any]) -> None:
        units = side.get("units") if isinstance(side.get("units"), dict) else {}
        self.units = {k: str(v) for k, v in units.items() if k in self.channels}
        wr = side.get("wheel_radius")
        self.wheel_radius = float(wr) if isinstance(wr, (int, float)) else None
        self.axes = side.get("axes") if isinstance(side.get("axes"), str) else None
        self.meta = dict(side["meta"]) if isinstance(side.get("meta"), dict) else {}
        notes = side.get("notes") if isinstance(side.get("notes"), list) else []
        self._side_notes = [str(x) for x in notes]

    # ---- chunks ---------------------------------------------------------------------------
    def _raw(self) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, list[str]]]:
        p = Path(self.path)
        if self.fmt == "csv":
            with open_text(p) as fh:
                tab = CsvTable(fh, str(p))
                names = ["t", *self.channels]
                for cols, lines in tab.iter_chunks(names, chunk_rows=self.chunk_rows):
                    t = cols.pop("t")
                    yield t, cols, lines, tab.notes
            return
        from vibrospeed.io.parquet import _pyarrow

        pa, pc, pq = _pyarrow(p)
        row = 1
        try:
            pf = pq.ParquetFile(p)
            names = ["t", *self.channels]
            for batch in pf.iter_batches(batch_size=self.chunk_rows, columns=names):
                cols = {n: pc.cast(batch.column(n), pa.float64()).to_numpy(zero_copy_only=False)
                        for n in names}
                t = cols.pop("t")
                lines = np.arange(row, row + t.size)
                row += t.size
                yield t, cols, lines, []
        except (pa.ArrowException, OSError) as exc:
            raise ReaderError(p, f"not a readable Parquet file ({exc})") from None
        if row == 1:
            raise ReaderError(p, "no data rows")

    def __iter__(self) -> Iterator[Chunk]:
        src = str(Path(self.path))
        nan_count = dict.fromkeys(self.channels, 0)
        last: tuple[float, int] | None = None  # (time, line) of the previous chunk's last row
        n = 0
        reader_notes: list[str] = []
        for t, cols, lines, rnotes in self._raw():
            if last is None:
                check_increasing(t, src, rows=lines)
            else:
                check_increasing(np.concatenate(([last[0]], t)), src,
                                 rows=np.concatenate(([last[1]], lines)))
            if t.size:
                last = (float(t[-1]), int(lines[-1]))
            for k, x in cols.items():
                nan_count[k] += int(np.count_nonzero(np.isnan(x)))
            reader_notes = rnotes
            yield Chunk(t, cols, lines, n)
            n += t.size
        notes = []
        for k, nbad in nan_count.items():
            if n and nbad == n:
                raise ReaderError(src, "channel has no numeric value (all empty or NaN)",
                                  column=k)
            if nbad:
                notes.append(f"channel '{k}': {nbad} empty or NaN cell(s) of {n}")
        self.n = n
        self.notes = [*self._side_notes, *reader_notes, *notes]

    def read(self) -> Recording:
        """All chunks as one :class:`Recording` (what the whole-file reader gives, without its
        time-base notes)."""
        parts = list(self)
        t = np.concatenate([c.t for c in parts]) if parts else np.empty(0)
        ch = {k: (np.concatenate([c.channels[k] for c in parts]) if parts else np.empty(0))
              for k in self.channels}
        kw = {"axes": self.axes} if self.axes else {}
        return Recording(t, ch, units=dict(self.units), source=str(Path(self.path)),
                         wheel_radius=self.wheel_radius, notes=list(self.notes),
                         meta=dict(self.meta), **kw)
