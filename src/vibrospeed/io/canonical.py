"""Canonical CSV: vibrospeed's own recording format.

Layout of a recording written to ``drive.csv``::

    drive.csv               t,ax,ay,az,...        header row, ``t`` (s) first, canonical names
                                                  (types.CHANNEL_UNITS) in SI; other columns kept
                                                  as they are; empty cell = NaN
    drive.wss_ticks.csv     t                     one sidecar per event stream, one time per row
    drive.csv.json          {"kind": "recording"} units, wheel radius, axes, notes, metadata

A gzip-compressed ``drive.csv.gz`` (``gzip drive.csv``) keeps the sidecars of ``drive.csv``:
``drive.csv.json`` (or ``drive.csv.gz.json``) and ``drive.<name>.csv`` (:func:`uncompressed`).

Floats are written with ``repr`` (shortest string that reads back to the same float64), so a
write/read round trip is exact. Sidecars are optional when reading: a plain CSV with a ``t``
column is a valid recording. Every file is written atomically.
"""

from __future__ import annotations

import csv
import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import InputError, ReaderError
from vibrospeed.io._common import finish, jsonable
from vibrospeed.io._csv import CsvTable, _short, check_decimal, nan_notes, open_text
from vibrospeed.io.atomic import atomic_path, atomic_write_text
from vibrospeed.types import CHANNEL_UNITS, Recording

__all__ = ["event_path", "event_sidecars", "is_canonical_header", "is_event_sidecar", "read_csv",
           "sidecar_json", "uncompressed", "write_csv"]

_EVENT_NAME = re.compile(r"^[A-Za-z0-9_\-]+$")
_ROWS_PER_WRITE = 20000


#: name endings of a compressed file (gzip, the one the readers decompress), left off for its
#: sidecars' names and a batch's output name
COMPRESSED_SUFFIXES = (".gz", ".gzip")


def uncompressed(path: str | os.PathLike[str]) -> Path:
    """``path`` without a compression suffix (``drive.csv.gz`` -> ``drive.csv``; others as
    they are): the name its sidecars and event files go by, as ``gzip drive.csv`` leaves
    ``drive.csv.json`` and ``drive.wss_ticks.csv`` beside it."""
    p = Path(path)
    for suf in COMPRESSED_SUFFIXES:
        if p.name.lower().endswith(suf) and len(p.name) > len(suf):
            return p.with_name(p.name[: -len(suf)])
    return p


def sidecar_json(path: str | os.PathLike[str]) -> Path:
    """The metadata sidecar of a canonical CSV: ``<path>.json``; for ``drive.csv.gz`` that one
    where it exists, else ``drive.csv.json`` (the sidecar of the file before compression)."""
    p = Path(path)
    own = Path(f"{p}.json")
    base = uncompressed(p)
    return own if base == p or own.is_file() else Path(f"{base}.json")


def event_sidecars(path: str | os.PathLike[str]) -> dict[str, Path]:
    """The event files of a canonical CSV, ``<stem>.<name>.csv`` with the header ``t`` alone
    (those of ``drive.csv`` for ``drive.csv.gz``)."""
    return _event_sidecars(uncompressed(path))


def event_path(path: str | os.PathLike[str], name: str) -> Path:
    """Sidecar file of event stream ``name`` for recording ``path`` (``<stem>.<name>.csv``)."""
    p = Path(path)
    return p.with_name(f"{p.stem}.{name}.csv")


def is_event_sidecar(path: str | os.PathLike[str]) -> bool:
    """True for an event stream of a canonical recording, not a recording of its own:
    ``<stem>.<name>.csv`` (``name`` as :func:`write_csv` allows, no dot) beside ``<stem>.csv``
    (or ``<stem>.csv.gz``),
    with the header ``t`` alone (as :func:`read_events` finds them). ``drive.2024-05-01.csv``
    beside ``drive.csv`` is a drive; ``trip.v2.wss_ticks.csv`` is ``trip.v2.csv``'s ticks."""
    q = Path(path)
    head, dot, name = q.stem.rpartition(".")
    if not dot or q.suffix != ".csv" or not _EVENT_NAME.match(name):
        return False
    if not any(q.with_name(f"{head}.csv{z}").is_file() for z in ("", *COMPRESSED_SUFFIXES)):
        return False
    try:
        with open(q, encoding="utf-8-sig", newline="") as fh:
            return fh.readline().strip() == "t"
    except (OSError, UnicodeDecodeError):
        return False


def is_canonical_header(header: list[str]) -> bool:
    """True for a header whose first column is ``t`` and whose other names are non-empty."""
    return bool(header) and header[0] == "t" and all(h for h in header[1:])


def _fmt(values: np.ndarray) -> list[str]:
    # repr of a Python float is the shortest exact representation; NaN -> empty cell
    return [repr(v) if v == v else "" for v in values.tolist()]


def _write_columns(path: Path, names: list[str], cols: list[np.ndarray]) -> None:
    n = cols[0].size if cols else 0
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(names)
        for a in range(0, n, _ROWS_PER_WRITE):
            b = min(n, a + _ROWS_PER_WRITE)
            w.writerows(zip(*(_fmt(c[a:b]) for c in cols), strict=True))


def _event_sidecars(path: Path) -> dict[str, Path]:
    """Existing ``<stem>.<name>.csv`` files next to ``path`` whose header is exactly ``t``."""
    out = {}
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        return out
    prefix = path.stem + "."
    for q in folder.glob(f"{_glob_escape(prefix)}*.csv"):
        name = q.name[len(prefix) : -4]
        if not _EVENT_NAME.match(name) or q == path:
            continue
        try:
            with open(q, encoding="utf-8-sig", newline="") as fh:
                first = fh.readline().strip()
        except (OSError, UnicodeDecodeError):
            continue
        if first == "t":
            out[name] = q
    return out


def _glob_escape(s: str) -> str:
    # Escape glob metacharacters in ``s``.
    return re.sub(r"([\[\]*?])", r"[\1]", s)


def write_csv(rec: Recording, path: str | os.PathLike[str]) -> None:
    """Write ``rec`` as canonical CSV plus event sidecars and ``<path>.json`` (all atomic).

    Stale event sidecars of an earlier recording at the same path are removed. A channel named
    ``t`` or an event name that is not ``[A-Za-z0-9_-]+`` raises :class:`InputError`.
    """
    p = Path(path)
    names = list(rec.channels)
    if "t" in names:
        raise InputError(f"{p}: a channel may not be called 't'")
    for k in names:
        if not k or k != k.strip() or "\n" in k or "\r" in k:
            raise InputError(f"{p}: channel name {k!r} is empty, padded or contains a newline")
    for ev in rec.events:
        if not _EVENT_NAME.match(ev):
            raise InputError(f"{p}: event name '{ev}' must match [A-Za-z0-9_-]+")
    _write_columns(p, ["t", *names], [rec.t, *(rec.channels[k] for k in names)])
    for ev, times in rec.events.items():
        _write_columns(event_path(p, ev), ["t"], [times])
    for ev, q in _event_sidecars(p).items():
        if ev not in rec.events:
            q.unlink(missing_ok=True)
    side = {
        "kind": "recording",
        "format": "vibrospeed canonical csv 1",
        "source": rec.source,
        "wheel_radius": rec.wheel_radius,
        "axes": rec.axes,
        "units": {k: rec.units.get(k, "") for k in names},
        "events": sorted(rec.events),
        "notes": list(rec.notes),
        "meta": jsonable(rec.meta),
    }
    atomic_write_text(Path(f"{p}.json"), json.dumps(side, indent=1, allow_nan=False) + "\n")


def _read_sidecar_json(p: Path) -> dict[str, Any]:
    q = sidecar_json(p)
    if not q.is_file():
        return {}
    try:
        side = json.loads(q.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ReaderError(q, f"unreadable metadata sidecar ({exc})") from None
    if not isinstance(side, dict) or side.get("kind") != "recording":
        return {}
    return side


def read_events(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Event streams from the ``<stem>.<name>.csv`` sidecars of ``path`` (empty if none)."""
    events = {}
    for name, q in sorted(event_sidecars(path).items()):
        with open_text(q) as fh:
            tab = CsvTable(fh, str(q), delimiter=",")
            cols, lines = tab.read(["t"], allow_empty=True)
        t = cols["t"]
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise ReaderError(q, "event time is missing or not finite", row=int(lines[bad[0]]),
                              column="t")
        events[name] = t
    return events


def row_units(tab: CsvTable, p: Path) -> dict[str, str]:
    """The units a units row under the header gives (:class:`CsvTable` ``unit_name``), checked:
    ``t`` in s and the canonical channels in their SI units (m/s^2, rad/s, ...), otherwise a
    :class:`ReaderError` saying how to convert through a mapping; other columns keep the text as
    their unit."""
    from vibrospeed.io.mapped import UNITS, unit_name

    out = {}
    for col, text in tab.units.items():
        name = unit_name(text)
        want = "s" if col == "t" else CHANNEL_UNITS.get(col)
        if want is None:
            out[col] = text  # a channel vibrospeed does not know: its unit as written
            continue
        if name is None or UNITS[name] != (1.0, want):
            how = (f": read it through a mapping, --columns {col}={col}:{name} ..." if name
                   else "")
            raise ReaderError(p, f"units row says '{_short(text)}', but canonical CSV is in SI "
                              f"({want}){how}", row=tab.units_line, column=col)
        if col != "t":
            out[col] = want
    return out


def read_csv(path: str | os.PathLike[str], *, sort: bool = False,
             decimal: str | None = None) -> Recording:
    """Read a canonical CSV recording (header ``t,<channels>``), its event sidecars and metadata.

    Parameters
    ----------
    path : the ``.csv`` file
    sort : sort rows by time and drop repeated timestamps instead of refusing them
    decimal : the numbers' decimal mark, ``"."`` (None: the default) or ``","`` for a ``;`` or
        tab separated export that writes ``1,5`` (never guessed)

    Raises
    ------
    ReaderError : missing/empty file, header not starting with ``t``, wrong field count, text in
        a numeric cell, a channel with no numeric value, time not increasing (unless ``sort``).
    """
    p = Path(path)
    from vibrospeed.io.mapped import unit_name

    decimal = check_decimal(decimal, str(p)) or "."
    with open_text(p) as fh:
        tab = CsvTable(fh, str(p), decimal=decimal, unit_name=unit_name)
        if not is_canonical_header(tab.header):
            raise ReaderError(
                p,
                "not a canonical recording: the header must start with 't' followed by "
                "channel names (give a column mapping for other CSV files)",
                row=tab.header_line,
            )
        names = [h for h in tab.header if h]
        cols, lines = tab.read(names)
    notes = list(tab.notes)
    t = cols.pop("t")
    notes.extend(nan_notes(cols, str(p)))
    side = _read_sidecar_json(p)
    units_side = side.get("units") if isinstance(side.get("units"), dict) else {}
    units = {k: str(v) for k, v in units_side.items() if k in cols}
    units.update(row_units(tab, p))
    side_notes = side.get("notes") if isinstance(side.get("notes"), list) else []
    rec_notes = [*map(str, side_notes), *notes]
    meta = dict(side["meta"]) if isinstance(side.get("meta"), dict) else {}
    if isinstance(side.get("source"), str) and side["source"]:
        meta.setdefault("origin", side["source"])
    wr = side.get("wheel_radius")
    axes = side.get("axes") if isinstance(side.get("axes"), str) else None
    return finish(
        t,
        cols,
        source=str(p),
        lines=lines,
        sort=sort,
        units=units,
        events=read_events(p),
        notes=rec_notes,
        meta=meta,
        wheel_radius=float(wr) if isinstance(wr, (int, float)) else None,
        axes=axes,
    )

