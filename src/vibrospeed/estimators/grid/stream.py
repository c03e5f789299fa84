"""``vibrospeed estimate`` on a long log: read in chunks, estimate in blocks, write as it goes.

Above :data:`STREAM_ROWS` rows a recording estimated with the grid tracker (offline ``fb``,
fixed-lag ``lag`` or causal ``none``; no fit; with or without a plot) takes this path instead
of the whole-log one (:func:`vibrospeed.batch.estimate_recording`) when it is a canonical CSV
or Parquet file or a CSV read through a column mapping (``--columns``, ``--mapping``,
``--rate``):

1. the file is read ``chunk_rows`` rows at a time (:class:`vibrospeed.io.chunks.ChunkedRecording`,
   the same values, notes and errors as the whole-file reader), keeping the time line and the
   accelerometer channels (the grid tracker, its standstill detector and the quality flags
   use nothing else) and, for the plot, the GPS speed fixes and the truth in bounded memory
   (:class:`Overlay`); non-uniform time stamps are resampled as the whole-log path does;
2. the estimate runs block by block (:class:`vibrospeed.estimators.grid.blocks.Blocks`), and
   each block's rows (with the ``quality`` column) are appended to a temporary file beside the
   output, renamed to the output at the end (atomic: an interrupted run leaves the old output),
   then the JSON sidecar, as :func:`vibrospeed.io.write_track` writes it.

The file's rows are counted once (:func:`stream_rows`, which decides), and the count sizes the
arrays the chunks are copied into. Below the threshold, and for anything else, the whole-log
path runs: its output is unchanged.
"""

from __future__ import annotations

import csv
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: rows above which ``vibrospeed estimate`` streams a grid estimate (1 h 23 min at 100 Hz; the
#: whole-log estimate of 1 h peaks at about 0.8 GiB)
STREAM_ROWS = 500_000
#: rows read at a time
CHUNK_ROWS = 65_536
#: the streamed plot: spectrogram columns and estimate points, at most
PLOT_FRAMES = 3000
PLOT_POINTS = 20_000
_CHANNELS = ("ax", "ay", "az")
#: the truth channels the plot draws (as :func:`vibrospeed.eval.plot.track_figure` reads them)
_TRUTH = ("omega_true", "speed_true")


def count_rows(path: str | os.PathLike[str], fmt: str = "auto") -> int | None:
    """Data rows of a canonical CSV or a mapped text file (``fmt="mapped"``; lines after the
    header, counted in binary blocks) or a Parquet file (its metadata); None for other formats,
    folders or unreadable files."""
    p = Path(path)
    if not p.is_file():
        return None
    kind = fmt if fmt != "auto" else ("parquet" if p.suffix.lower() in (".parquet", ".pq")
                                      else "csv" if p.suffix.lower() == ".csv" else None)
    kind = "csv" if kind == "mapped" else kind
    try:
        if kind == "parquet":
            import pyarrow.parquet as pq

            return int(pq.ParquetFile(p).metadata.num_rows)
        if kind == "csv":
            lines, last = 0, b"\n"
            with open(p, "rb") as fh:
                while block := fh.read(1 << 22):
                    lines += block.count(b"\n")
                    last = block[-1:]
            return lines + (last != b"\n") - 1
    except Exception:  # noqa: BLE001 - not a file this path can read: the whole-log path says why
        return None
    return None


def _mapped(columns, mapping, rate) -> bool:
    return columns is not None or mapping is not None or rate is not None


def stream_rows(path, *, method: str, params: dict, fmt: str = "auto",
                columns: str | None = None, mapping=None, rate: float | None = None,
                sort: bool = False, topic: str | None = None, plot: bool = False,
                threshold: int | None = None) -> int | None:
    """The file's row count where ``vibrospeed estimate`` takes the streaming path, else None:
    the grid method, smoothed (``fb``), fixed-lag or causal, no fit, no sort, no topic, a
    canonical CSV / Parquet file or a text file through a column mapping (``columns``,
    ``mapping``, ``rate``; format ``auto`` or ``mapped``) of at least :data:`STREAM_ROWS` rows
    (or ``threshold``). ``plot`` does not change that (the streamed plot, :class:`StreamPlot`)."""
    if method != "grid" or sort or topic:
        return None
    smooth = str(params.get("smooth", "fb"))
    if smooth not in ("fb", "none", "lag") or str(params.get("fit", "")).strip():
        return None
    kind = fmt
    if _mapped(columns, mapping, rate):
        if fmt not in ("auto", "mapped"):
            return None  # the whole-file reader says why that does not go together
        kind = "mapped"
    n = count_rows(path, kind)
    return n if n is not None and n >= (STREAM_ROWS if threshold is None else threshold) \
        else None


def channel_names(path, fmt: str = "auto", *, columns: str | None = None, mapping=None,
                  rate: float | None = None, decimal: str | None = None) -> list[str]:
    """The recording's channels as its header (or mapping) names them, nothing read past the
    header; a channel with no number at all is refused by the reader before any estimate."""
    from vibrospeed.io.chunks import ChunkedRecording

    return list(ChunkedRecording(path, fmt=fmt, columns=columns, mapping_file=mapping,
                                 rate=rate, decimal=decimal).channels)


@dataclass
class Streamed:
    """What :func:`estimate_file` wrote: rows, the recording's notes, the track's notes, the
    axis used, and the parameters and wheel radius the estimate ran with, as its sidecar
    holds them (for the CLI's notes, without reading the sidecar back)."""

    rows: int
    recording_notes: list[str]
    notes: list[str]
    axis: str | None
    params: dict[str, Any] = field(default_factory=dict)
    wheel_radius: float | None = None
    #: with ``plot``: the decimated spectrogram and estimate, drawn by
    #: :func:`vibrospeed.eval.plot.plot_streamed`
    drawing: StreamPlot | None = None


def read_accelerometer(path, fmt: str = "auto", *, axis: str | None = None,
                       chunk_rows: int = CHUNK_ROWS, rows: int | None = None,
                       columns: str | None = None, mapping=None, rate: float | None = None,
                       overlay: Overlay | None = None, progress=None,
                       decimal: str | None = None):
    """The recording's time line and accelerometer channels (and ``axis``'s channel), read in
    chunks (``columns``, ``mapping``, ``rate``: through a column mapping); the notes of the
    CLI's whole-file reading (:func:`vibrospeed.batch.load_recording`: time-base notes and an
    unread ``<file>.json`` included); non-uniform time stamps resampled to the median rate as
    the whole-log path does. ``rows``: the file's row count where known (else counted here),
    the size of the arrays the chunks are copied into. ``overlay``: handed every chunk (the
    plot's GPS fixes and truth, :class:`Overlay`). ``progress``: called ``(rows read, rows)``
    after each chunk."""
    from vibrospeed.estimators.common import axis_channel
    from vibrospeed.io import timebase
    from vibrospeed.io.chunks import ChunkedRecording
    from vibrospeed.types import Recording

    src = ChunkedRecording(path, chunk_rows=chunk_rows, fmt=fmt, columns=columns,
                           mapping_file=mapping, rate=rate, decimal=decimal)
    keep = ["t", *[c for c in src.channels
                   if c in _CHANNELS or (axis is not None and c == axis_channel(axis))]]
    # copied chunk by chunk into arrays of the file's length (grown if the count was short):
    # no list of chunks, no reader buffers kept alive by views into them
    size = max((count_rows(path, src.fmt) if rows is None else rows) or 0, 1)
    out = {c: np.empty(size) for c in keep}
    n = 0
    for chunk in src:
        if overlay is not None:
            overlay.add(chunk)
        m = len(chunk)
        if n + m > size:
            size = max(2 * size, n + m)
            out = {c: np.concatenate([v[:n], np.empty(size - n)]) for c, v in out.items()}
        for c in keep:
            out[c][n:n + m] = chunk.t if c == "t" else chunk.channels[c]
        n += m
        if progress is not None:
            progress(n, max(size, n))
    _release_reader_memory()
    t = out.pop("t")[:n]
    ch = {c: v[:n] for c, v in out.items()}
    kw = {"axes": src.axes} if src.axes else {}
    rec = Recording(t, ch, units={k: v for k, v in src.units.items() if k in ch},
                    source=str(Path(path)), wheel_radius=src.wheel_radius, notes=list(src.notes),
                    meta=dict(src.meta), **kw)
    rec.notes.extend(timebase.describe_timebase(rec))  # as the whole-file readers end
    if fmt in ("auto", "csv") and not _mapped(columns, mapping, rate):
        from vibrospeed.io import unread_sidecar_note

        said = unread_sidecar_note(path)  # as load_recording adds it, before resampling
        if said:
            rec.notes.append(said)
    return timebase.as_uniform(rec)


class Overlay:
    """What the streamed plot draws over the estimate besides the accelerometer, kept as the
    chunks pass in bounded memory: the GPS speed fixes as (t, value) pairs (the finite
    ``gps_speed`` cells, with ``gps_sats`` at those rows where the file has it; at most
    ``2 * max_fixes``: past that every other kept fix is dropped and then only every 2nd,
    4th, ... further fix is kept, so the kept fixes stay evenly spread over the log) and the
    truth channels (``omega_true``, ``speed_true``) every ``k``-th row. A log with fewer
    fixes and ``k = 1`` keeps all of them: the whole-log plot's overlays."""

    def __init__(self, k: int = 1, max_fixes: int = PLOT_POINTS):
        self.k = max(1, int(k))
        self.max_fixes = max(1, int(max_fixes))
        self.stride = 1  # of the fixes seen: fix number i is kept where i % stride == 0
        self._seen = 0
        self._row = 0
        self._gps: list[np.ndarray] = []  # (3, m) blocks: t, speed, satellites (NaN: none)
        self._truth: dict[str, list[np.ndarray]] = {}
        self._truth_t: list[np.ndarray] = []
        self.has_gps = self.has_sats = False

    def add(self, chunk) -> None:
        """Keep ``chunk``'s fixes and truth (the chunks in file order)."""
        ch = chunk.channels
        m = len(chunk)
        if "gps_speed" in ch:
            self.has_gps = True
            self.has_sats = self.has_sats or "gps_sats" in ch
            g = ch["gps_speed"]
            at = np.flatnonzero(np.isfinite(g))
            sel = at[(self._seen + np.arange(at.size)) % self.stride == 0]
            self._seen += at.size
            sats = ch["gps_sats"][sel] if "gps_sats" in ch else np.full(sel.size, np.nan)
            self._gps.append(np.array([chunk.t[sel], g[sel], sats], dtype=np.float64))
            while sum(b.shape[1] for b in self._gps) > 2 * self.max_fixes:
                self._gps = [np.concatenate(self._gps, axis=1)[:, ::2]]
                self.stride *= 2
        have = [c for c in _TRUTH if c in ch]
        if have:
            sel = slice((-self._row) % self.k, m, self.k)
            self._truth_t.append(np.array(chunk.t[sel], dtype=np.float64))
            for c in have:
                self._truth.setdefault(c, []).append(np.array(ch[c][sel], dtype=np.float64))
        self._row += m

    def gps(self):
        """The kept fixes as a :class:`~vibrospeed.types.Recording` (``gps_speed`` and, where
        the file has it, ``gps_sats``) on their own time line, None without a GPS channel."""
        from vibrospeed.types import Recording

        if not self.has_gps:
            return None
        t, v, sats = (np.concatenate(self._gps, axis=1) if self._gps else np.empty((3, 0)))
        ch = {"gps_speed": v, **({"gps_sats": sats} if self.has_sats else {})}
        return Recording(t, ch)

    def truth(self):
        """The kept truth rows as a :class:`~vibrospeed.types.Recording`, None without any."""
        from vibrospeed.types import Recording

        if not self._truth:
            return None
        return Recording(np.concatenate(self._truth_t),
                         {c: np.concatenate(v) for c, v in self._truth.items()})


def _release_reader_memory() -> None:
    """Hand the Parquet reader's freed buffers back (Arrow's allocator keeps them otherwise)."""
    try:
        import pyarrow as pa
    except ImportError:  # pragma: no cover - CSV only
        return
    pa.default_memory_pool().release_unused()


def estimate_file(input_path, output, *, params: dict, axis: str | None = None,
                  wheel_radius: float | None = None, fmt: str = "auto",
                  meta: dict[str, Any] | None = None, progress: bool = False,
                  block_s: float | None = None, lookahead_s: float | None = None,
                  chunk_rows: int = CHUNK_ROWS, rows: int | None = None,
                  columns: str | None = None, mapping=None, rate: float | None = None,
                  notes: list[str] | None = None, plot: bool = False,
                  on_block=None, decimal: str | None = None) -> Streamed:
    """Estimate ``input_path`` with the grid tracker block by block and write ``output`` (CSV)
    and ``output.json`` as ``vibrospeed estimate`` does (module docstring). ``rows``: the
    file's row count from :func:`stream_rows` (not counted again); ``columns``, ``mapping``,
    ``rate``: a column mapping; ``decimal``: a CSV's decimal mark; ``notes``: notes put before
    the estimate's (the sidecar's and
    the returned ones); ``plot``: also keep a decimated spectrogram with the estimate
    (:class:`StreamPlot`, returned as ``drawing``, for
    :func:`vibrospeed.eval.plot.plot_streamed`); ``on_block``: called with each block's
    Track as it is written, in order (the CLI's summary numbers,
    :class:`vibrospeed.eval.metrics.SummaryAccumulator`)."""
    from vibrospeed import __version__
    from vibrospeed.errors import ParameterError
    from vibrospeed.estimators.common import axis_channel, only_axis
    from vibrospeed.estimators.grid import blocks as _blocks
    from vibrospeed.io._common import jsonable, sha256_path
    from vibrospeed.io.atomic import atomic_path, atomic_write_text
    from vibrospeed.io.canonical import _fmt
    from vibrospeed.io.track import TRACK_COLUMNS, check_wheel_radius
    from vibrospeed.signal.quality import flags_at, recording_quality

    check_wheel_radius(wheel_radius)  # before anything is read or written
    overlay = None
    if plot:  # the GPS fixes and the truth, kept as the chunks pass
        if rows is None:
            rows = count_rows(input_path, "mapped" if _mapped(columns, mapping, rate) else fmt)
        overlay = Overlay(-(-(rows or 1) // PLOT_POINTS))
    with _Bar(progress, "reading") as reading:
        rec = read_accelerometer(input_path, fmt, axis=axis, chunk_rows=chunk_rows, rows=rows,
                                 columns=columns, mapping=mapping, rate=rate, overlay=overlay,
                                 decimal=decimal,
                                 progress=reading.update)
    axis, axis_note = only_axis(rec, axis)
    use_axis = axis or "y"
    # the quality flags first (their temporaries are the largest per sample), then the estimate
    qs, q_notes = recording_quality(rec)
    ch = axis_channel(use_axis)
    if ch not in qs and ch in rec.channels:
        qs.update(recording_quality(rec, (ch,))[0])
    use_q = ch if ch in qs else next(iter(qs), None)
    flags = qs[use_q].flags if use_q is not None else None
    del qs
    kw = {k: v for k, v in (("block_s", block_s), ("lookahead_s", lookahead_s)) if v is not None}
    bar = _Bar(progress, "grid, in blocks")
    blk = _blocks.Blocks(rec, axis=use_axis, wheel_radius=wheel_radius, params=dict(params),
                         progress=bar.update, **kw)
    if axis_note:
        blk.notes.insert(0, axis_note)
    blk.notes[:0] = list(notes or [])
    names: list[str] | None = None
    n_out = 0
    drawing = None
    if plot:  # the whole-log plot's channel: the axis used, else the first one
        drawing = StreamPlot(rec, ch if ch in rec.channels else next(iter(rec.channels)),
                             len(rec), overlay=overlay)
    out = Path(output)
    with bar, atomic_path(out) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        for track in blk:
            if flags is not None:
                track.extras["quality"] = flags_at(rec.t, flags, track.t).astype(np.float64)
            if names is None:
                names = [*TRACK_COLUMNS, *track.extras]
                w.writerow(names)
            cols = [np.asarray(getattr(track, k), dtype=np.float64) for k in TRACK_COLUMNS]
            cols += [np.asarray(track.extras[k], dtype=np.float64) for k in names[9:]]
            for a in range(0, len(track), 20000):
                w.writerows(zip(*(_fmt(c[a:a + 20000]) for c in cols), strict=True))
            n_out += len(track)
            if on_block is not None:
                on_block(track)
            if drawing is not None:
                drawing.add(track)
        all_notes = [*blk.notes, *q_notes]
        side_meta = {"version": __version__, "axis": use_axis, "recording_notes": rec.notes,
                     **(meta or {})}
        side_params = jsonable(blk.params)
        side = {
            "kind": "track", "method": "grid", "params": side_params, "level": blk.level,
            "wheel_radius": blk.wheel_radius, "version": __version__,
            "input": os.fspath(input_path), "input_sha256": sha256_path(input_path),
            "columns": names or list(TRACK_COLUMNS), "notes": all_notes,
            "meta": jsonable(side_meta),
        }
        try:  # the sidecar's text before the CSV is renamed, as write_track does
            text = json.dumps(side, indent=1, allow_nan=False) + "\n"
        except ValueError as exc:
            raise ParameterError(f"{out}.json: cannot write the sidecar: {exc}") from None
        # the older sidecar goes before the CSV is replaced (io.write_track's rule): stopped
        # in between (Ctrl-C), the new CSV stands without one, never beside the old options'
        Path(f"{out}.json").unlink(missing_ok=True)
    atomic_write_text(Path(f"{out}.json"), text)
    if drawing is not None:
        drawing.finish(level=blk.level, method="grid", M=int(blk.params["M"]),
                       wheel_radius=blk.wheel_radius)
    return Streamed(n_out, list(rec.notes), all_notes, use_axis, side_params, blk.wheel_radius,
                    drawing)


class StreamPlot:
    """What ``vibrospeed estimate --plot`` draws for a streamed log, in bounded memory.

    The spectrogram of ``channel`` (the whole-log plot's: Hann windows of ``window_s``, power
    density of the mean-removed, NaN-zeroed signal, each segment's mean removed, as
    :func:`vibrospeed.signal.spectral.spectrogram`) at most :data:`PLOT_FRAMES` columns: frames
    every 0.25 window (the whole-log plot's hop) or, on a long log, further apart, computed a
    batch of frames at a time. :meth:`add` keeps every k-th sample of each block's estimate,
    band and ``has_signal`` (at most :data:`PLOT_POINTS` points) and the largest upper band
    edge (which sets the spectrogram's height, as in the whole-log plot). ``overlay``: the GPS
    fixes and truth kept while reading (:class:`Overlay`), drawn as the whole-log plot draws
    the recording's. No posterior image (the blocks do not keep it).
    """

    def __init__(self, rec, channel: str, n: int, window_s: float = 3.0, batch: int = 256,
                 overlay: Overlay | None = None):
        from vibrospeed.signal.dsp import get_window

        self.channel, self.source, self.rec = channel, rec.source, rec  # rec: kept by the caller
        self.overlay = overlay
        x = rec.channel(channel)
        fs = 1.0 / rec.dt
        nper = int(max(1, min(x.size, max(16, round(window_s * fs)))))
        hop = max(nper - int(min(nper - 1, round(0.75 * nper))),
                  -(-(x.size - nper + 1) // PLOT_FRAMES))
        starts = np.arange(0, max(x.size - nper + 1, 1), hop)
        mean = np.nanmean(x)
        win = get_window("hann", nper)
        scale = 1.0 / (fs * float((win * win).sum()))
        nf = nper // 2 + 1
        self.power = np.empty((nf, starts.size))
        frames = np.lib.stride_tricks.sliding_window_view(x, nper)
        for i in range(0, starts.size, batch):
            seg = np.nan_to_num(frames[starts[i:i + batch]] - mean)
            seg = seg - seg.mean(axis=1, keepdims=True)
            pw = np.abs(np.fft.rfft(seg * win, axis=1)) ** 2 * scale
            pw[:, 1:nf - 1 if nper % 2 == 0 else nf] *= 2.0  # one-sided
            self.power[:, i:i + batch] = pw.T
        self.t = rec.t[0] + (starts + nper / 2) / fs
        self.omega = 2 * np.pi * np.fft.rfftfreq(nper, 1.0 / fs)
        self.hop_s = hop / fs
        self.window_s = nper / fs
        self.fs = fs
        self.k = max(1, -(-n // PLOT_POINTS))
        self._done = 0
        self._parts: list[tuple[np.ndarray, ...]] = []
        self.top = -np.inf

    def add(self, track) -> None:
        """Keep the samples of ``track`` (the log's next rows) whose index is a multiple of k."""
        m = len(track)
        first = (-self._done) % self.k
        sel = slice(first, m, self.k)
        sig = track.extras.get("has_signal")
        still = track.extras.get("standstill")
        self._parts.append(tuple(np.array(v[sel], dtype=np.float64) for v in (
            track.t, track.omega, track.omega_lo, track.omega_hi,
            sig if sig is not None else np.ones(m),
            still if still is not None else np.full(m, np.nan))))
        hi = np.asarray(track.omega_hi)
        if np.isfinite(hi).any():
            self.top = max(self.top, float(np.nanmax(hi)))
        self._done += m

    def finish(self, *, level: float, method: str, M: int,
               wheel_radius: float | None) -> None:
        """Set what the estimate ran with: the band's level, the method, its harmonics and
        wheel radius (the figure's legend, harmonics and speed axis)."""
        self.level, self.method, self.M, self.wheel_radius = level, method, M, wheel_radius

    def track(self):
        """The kept samples as a :class:`vibrospeed.types.Track` (after :meth:`finish`): omega,
        its band, ``has_signal`` and the blocks' ``standstill`` where they flag one."""
        from vibrospeed.types import Track

        t, om, lo, hi, sig, still = (np.concatenate([p[i] for p in self._parts])
                                     if self._parts else np.empty(0) for i in range(6))
        extras = {"has_signal": sig}
        if np.isfinite(still).any():  # the blocks flag standstills
            extras["standstill"] = np.nan_to_num(still)
        return Track.from_omega(t, om, np.full(t.size, np.nan), lo=lo, hi=hi, level=self.level,
                                wheel_radius=self.wheel_radius, method=self.method,
                                params={"M": self.M}, extras=extras)


class _Bar:
    """A transient rich progress bar over the samples (``what`` they go through), on stderr
    (when ``on``)."""

    def __init__(self, on: bool, what: str):
        self.on, self.what = on, what
        self._bar = None
        self._task = None

    def __enter__(self):
        if self.on:
            from rich.console import Console
            from rich.progress import Progress

            self._bar = Progress(console=Console(stderr=True), transient=True)
            self._bar.__enter__()
            self._task = self._bar.add_task(self.what, total=None)
        return self

    def update(self, done: int, total: int) -> None:
        if self._bar is not None:
            self._bar.update(self._task, completed=done, total=total)

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)

