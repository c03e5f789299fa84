"""Large recordings read in chunks: memory bounded by one chunk, not by the file.

:func:`read` (canonical CSV, Parquet, a CSV through a column mapping) builds the whole
:class:`~vibrospeed.types.Recording`:
a 24-hour 100 Hz log with six channels is ~400 MB of float64 once read, more while it is
parsed. :class:`ChunkedRecording` hands the same samples out ``chunk_rows`` rows at a time
(:class:`Chunk`), for work that streams: the causal trackers
(:class:`~vibrospeed.estimators.online.OnlineTracker`), statistics, conversion. Concatenating
the chunks gives exactly what the whole-file reader gives (same float64 values, same errors at
the same file lines); the checks that need the whole file are done as the chunks pass: time
strictly increasing across chunk boundaries (a stream cannot be sorted: ``--sort`` is for whole
reads), a channel with no number at all, NaN counts (notes at the end). The whole-file readers
raise a bad cell before an all-NaN channel before a time error, wherever each is in the file;
so does a pass here: a time error is kept and raised when the file is exhausted (the chunks
before it have been handed out by then).

A CSV read through a column mapping (``columns="t=time:ms,ay=acc_y:g"``, a TOML
``mapping_file``, ``rate`` for a file without a time column; :mod:`vibrospeed.io.mapped`)
streams the same way: each chunk's columns scaled to SI as the whole-file reader scales them
(``(raw * scale + offset) * factor``, element by element: the same float64 values), the time
line ``i / rate`` counted from the file's first row, the same notes and errors.

Example::

    from vibrospeed.io.chunks import ChunkedRecording
    src = ChunkedRecording("day.parquet", chunk_rows=100_000)
    for chunk in src:
        for y in chunk.channels["ay"]:
            tracker.update(y)
    print(src.notes)
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.io._common import exc_text
from vibrospeed.io._csv import (
    CHUNK_ROWS,
    CsvTable,
    check_decimal,
    count_notes,
    nonfinite_counts,
    open_text,
)
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
    """A canonical CSV or Parquet recording, or a CSV through a column mapping (``columns``,
    ``mapping_file``, ``rate`` as for :func:`vibrospeed.io.read`; format ``mapped``; a CSV's
    ``decimal`` mark as there), read
    ``chunk_rows`` rows at a time.

    Iterating yields :class:`Chunk` s (a new pass reads the file again). ``channels`` (names),
    ``units``, ``wheel_radius``, ``axes``, ``meta`` come from the header / metadata before the
    first chunk; ``notes`` and ``n`` (rows) are complete once a pass has ended. Errors are the
    whole-file readers': :class:`~vibrospeed.errors.ReaderError` naming the file, line, column.
    """

    path: str | os.PathLike[str]
    chunk_rows: int = CHUNK_ROWS
    fmt: str = "auto"
    columns: str | None = None
    mapping_file: str | os.PathLike[str] | None = None
    rate: float | None = None
    #: the numbers' decimal mark (``"."`` or ``","``) of a CSV, as :func:`vibrospeed.io.read`
    decimal: str | None = None
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
        mapped = self.columns is not None or self.mapping_file is not None or self.rate is not None
        if fmt == "auto":
            fmt = "mapped" if mapped else "parquet" if p.suffix.lower() in (".parquet", ".pq") \
                else "csv"
        if fmt not in ("csv", "parquet", "mapped"):
            raise ReaderError(p, f"chunked reading supports csv, parquet and mapped, not '{fmt}'")
        if mapped and fmt != "mapped":  # as vibrospeed.io.read says it
            k = next(k for k in ("columns", "mapping_file", "rate")
                     if getattr(self, k) is not None)
            raise ParameterError(f"{p}: format '{fmt}' does not take option '{k}'")
        if self.decimal is not None and fmt == "parquet":
            raise ParameterError(f"{p}: format 'parquet' does not take option 'decimal'")
        check_decimal(self.decimal, str(p))
        self.fmt = fmt
        self._side_notes: list[str] = []
        self._tail_notes: list[str] = []
        if fmt == "csv":
            self._csv_header(p)
        elif fmt == "mapped":
            self._mapped_header(p)
        else:
            self._parquet_header(p)

    # ---- metadata ---------------------------------------------------------------------------
    def _csv_header(self, p: Path) -> None:
        from vibrospeed.io.canonical import _read_sidecar_json, is_canonical_header, row_units
        from vibrospeed.io.mapped import unit_name

        with open_text(p) as fh:
            tab = CsvTable(fh, str(p), decimal=self.decimal or ".", unit_name=unit_name)
        if not is_canonical_header(tab.header):
            raise ReaderError(
                p, "not a canonical recording: the header must start with 't' followed by "
                "channel names (give a column mapping for other CSV files)", row=tab.header_line)
        self.channels = [h for h in tab.header if h][1:]
        side = _read_sidecar_json(p)
        self._side(side)
        self.units.update(row_units(tab, p))
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
            raise ReaderError(p, f"not a readable Parquet file ({exc_text(exc)})") from None
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

    def _mapped_header(self, p: Path) -> None:
        """The mapping checked as :func:`vibrospeed.io.mapped.read_mapped` checks it (the same
        :func:`~vibrospeed.io.mapped.resolve_mapping`), the header read and every mapped column
        found."""
        from vibrospeed.io.mapped import mapping_text, resolve_mapping, si_units
        from vibrospeed.io.parquet import is_parquet, iter_columns

        setup = resolve_mapping(p, columns=self.columns, mapping_file=self.mapping_file,
                                rate=self.rate, decimal=self.decimal)
        self._parquet = is_parquet(p)
        if self._parquet:  # a Parquet table with its own column names, as read_mapped reads it
            spec, self._unit_notes, self._srcs = setup.columns_for(None)
            next(iter_columns(p, self._srcs, batch_rows=1), None)  # columns found and numeric
        else:
            with setup.open_table() as fh:
                tab = setup.table(fh)
                spec, self._unit_notes, self._srcs = setup.columns_for(tab)
                for c in self._srcs:
                    tab.index(c)  # a missing column: the whole-file reader's error, before rows
        self._setup, self._spec, self._rate = setup, spec, setup.rate
        self.channels = [k for k in spec if k != "t"]
        self.units = {k: u for k, u in si_units(spec).items() if k != "t"}
        self.meta = {"mapping": {k: sp._asdict() for k, sp in spec.items()}, "rate": setup.rate}
        self._tail_notes = [f"columns mapped: {mapping_text(spec)}"]
        if "t" not in spec:
            self._tail_notes.append(f"no time column: t = i / {setup.rate:g} Hz")

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
    def _raw(self) -> Iterator[tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, list[str],
                                     dict[str, np.ndarray]]]:
        """``(t, channels, lines, reader notes, the columns whose NaN are counted)`` per chunk
        (the file's columns, as the whole-file reader counts them)."""
        p = Path(self.path)
        if self.fmt == "csv":
            from vibrospeed.io.mapped import unit_name

            with open_text(p) as fh:
                tab = CsvTable(fh, str(p), decimal=self.decimal or ".", unit_name=unit_name)
                names = ["t", *self.channels]
                for cols, lines in tab.iter_chunks(names, chunk_rows=self.chunk_rows):
                    t = cols.pop("t")
                    yield t, cols, lines, tab.notes, cols
            return
        if self.fmt == "mapped":
            yield from self._raw_mapped(p)
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
                yield t, cols, lines, [], cols
        except (pa.ArrowException, OSError) as exc:
            raise ReaderError(p, f"not a readable Parquet file ({exc_text(exc)})") from None
        if row == 1:
            raise ReaderError(p, "no data rows")

    def _raw_mapped(self, p: Path):
        from vibrospeed.io.mapped import to_si

        spec, tcol = self._spec, (self._spec["t"].column if "t" in self._spec else None)
        start = 0
        with contextlib.ExitStack() as stack:
            if self._parquet:
                from vibrospeed.io.parquet import iter_columns

                notes = list(self._unit_notes)
                chunks = ((raw, np.arange(start + 1, start + 1 + raw[self._srcs[0]].size))
                          for raw in iter_columns(p, self._srcs, batch_rows=self.chunk_rows)
                          if raw[self._srcs[0]].size)
            else:
                tab = self._setup.table(stack.enter_context(self._setup.open_table()))
                tab.notes.extend(self._unit_notes)
                notes = tab.notes
                chunks = tab.iter_chunks(self._srcs, chunk_rows=self.chunk_rows)
            for raw, lines in chunks:
                chans = to_si(spec, raw)
                # t = i / rate: the same float64 division of the same integers as the whole file
                t = chans.pop("t") if tcol is not None else \
                    np.arange(start, start + lines.size) / self._rate
                start += lines.size
                yield t, chans, lines, notes, {c: x for c, x in raw.items() if c != tcol}
        if self._parquet and start == 0:
            raise ReaderError(p, "no data rows")

    def __iter__(self) -> Iterator[Chunk]:
        src = str(Path(self.path))
        nan_count: dict[str, tuple[int, int]] = {}  # (NaN, infinite) per channel
        last: tuple[float, int] | None = None  # (time, line) of the previous chunk's last row
        n = 0
        reader_notes: list[str] = []
        late: ReaderError | None = None  # the first time error, raised when the file is read
        for t, cols, lines, rnotes, counted in self._raw():
            if late is None:
                try:
                    if last is None:
                        check_increasing(t, src, rows=lines)
                    else:
                        check_increasing(np.concatenate(([last[0]], t)), src,
                                         rows=np.concatenate(([last[1]], lines)))
                except ReaderError as exc:
                    late = exc
            if t.size:
                last = (float(t[-1]), int(lines[-1]))
            for k, x in counted.items():
                a, b = nonfinite_counts(x)
                na, nb = nan_count.get(k, (0, 0))
                nan_count[k] = (na + a, nb + b)
            reader_notes = rnotes
            if late is None:
                yield Chunk(t, cols, lines, n)
            n += t.size
        notes = count_notes(nan_count, dict.fromkeys(nan_count, n), src)
        if late is not None:
            raise late
        self.n = n
        self.notes = [*self._side_notes, *reader_notes, *notes, *self._tail_notes]

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
