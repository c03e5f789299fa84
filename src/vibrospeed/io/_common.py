"""Helpers shared by the readers: building a checked Recording, JSON-safe metadata, checksums,
finding an app export's files in a folder."""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io.timebase import check_increasing, describe_timebase, sort_dedup
from vibrospeed.types import Recording


def finish(
    t: np.ndarray,
    channels: dict[str, np.ndarray],
    *,
    source: str,
    lines: np.ndarray | None = None,
    sort: bool = False,
    units: dict[str, str] | None = None,
    events: dict[str, np.ndarray] | None = None,
    notes: list[str] | None = None,
    meta: dict[str, Any] | None = None,
    wheel_radius: float | None = None,
    axes: str | None = None,
) -> Recording:
    """Recording from parsed arrays: time checked (or sorted when ``sort``), time-base notes added.

    Non-finite or non-increasing time raises :class:`ReaderError` naming the file line (``lines``)
    unless ``sort`` is true, in which case rows are sorted, de-duplicated and the fact noted.
    """
    kw: dict[str, Any] = {}
    if axes:
        kw["axes"] = axes
    rec = Recording(
        t=t,
        channels=channels,
        units=dict(units or {}),
        events=dict(events or {}),
        source=source,
        wheel_radius=wheel_radius,
        notes=list(notes or []),
        meta=dict(meta or {}),
        **kw,
    )
    if sort:
        rec = sort_dedup(rec)
    else:
        check_increasing(rec.t, source, rows=lines)
    rec.notes.extend(no_fix_as_nan(rec))
    rec.notes.extend(describe_timebase(rec))
    rec.notes.extend(gravity_notes(rec))
    return rec


def no_fix_as_nan(rec: Recording) -> list[str]:
    """Negative ``gps_speed`` / ``gps_hacc`` set to NaN (in place), with a note
    (:func:`negative_as_no_fix`).

    A log exported through a column mapping or as a canonical CSV keeps an app's -1, which the
    GPS methods would take for a fix of -1 m/s. The phone readers turn it into NaN themselves
    with the same function (they need it before placing fixes), so this finds none there and
    the note is given once."""
    notes = []
    for name in ("gps_speed", "gps_hacc"):
        x = rec.channels.get(name)
        if x is None:
            continue
        y, note = negative_as_no_fix(name, x)
        if note:
            rec.channels[name] = y
            notes.extend(note)
    return notes


def negative_as_no_fix(name: str, x: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """``x`` (a ``gps_speed`` or ``gps_hacc``) with negative values NaN, and the note saying
    how many (none: ``x`` itself and no note).

    A speed over ground and an accuracy are magnitudes; phone apps (phyphox, Sensor Logger)
    write -1 for "no fix". A reader calls this before picking the valid fixes, so that a -1 fix
    neither gets a row of its own inside a gap (:func:`.timebase.merge_fix_rows`) nor wins a
    sample over a valid fix."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        neg = x < 0
    n = int(np.count_nonzero(neg))
    if not n:
        return x, []
    return np.where(neg, np.nan, x), [f"{name}: {n} negative value(s) read as no fix (NaN; apps "
                                      "write -1 for no fix)"]


def gravity_notes(rec: Recording) -> list[str]:
    """A note where ``ax ay az`` labelled m/s^2 look like g: the median magnitude of the
    three axes is gravity's 9.81 m/s^2 in a vehicle (its accelerations are a fraction of g and
    average out), so a median between 0.5 and 2 is gravity in g, a file written in g (a
    logger's CSV, a column mapping without ``:g``). Noted, not converted: ``fuse``, ``aided``
    and ``gps-riss`` would read 1 g of acceleration as 1 m/s^2."""
    if not all(k in rec.channels and rec.units.get(k, "m/s^2") == "m/s^2"
               for k in ("ax", "ay", "az")):
        return []
    with np.errstate(over="ignore", invalid="ignore"):  # a huge value: inf, still not g
        mag = np.sqrt(rec["ax"] ** 2 + rec["ay"] ** 2 + rec["az"] ** 2)
    mag = mag[np.isfinite(mag)]
    if mag.size < 10:
        return []
    med = float(np.median(mag))
    if not 0.5 <= med <= 2.0:
        return []
    return [f"ax ay az: median magnitude {med:.3g} m/s^2 where gravity alone is 9.81: they look "
            "like g, not m/s^2; give their unit (--columns ax=COL:g,... or unit = \"g\" in a "
            "--mapping file)"]


def jsonable(x: Any) -> Any:
    """Convert ``x`` to plain JSON types (NumPy scalars/arrays, tuples, paths; NaN -> None)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.generic):
        return jsonable(x.item())
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, (bool, int, str)) or x is None:
        return x
    if isinstance(x, os.PathLike):
        return os.fspath(x)
    return repr(x)


def sha256_path(path: str | os.PathLike[str]) -> str:
    """SHA-256 hex digest of a file, or of a folder's files (sorted relative names and contents)."""
    p = Path(path)
    h = hashlib.sha256()
    files = sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p]
    for q in files:
        if p.is_dir():
            h.update(q.relative_to(p).as_posix().encode() + b"\0")
        with open(q, "rb") as fh:
            for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def exc_text(exc: BaseException) -> str:
    """``exc``'s message on one line: a library's multi-line text (pyarrow's thrift errors end
    in newlines) joined by spaces, so the :class:`ReaderError` that quotes it stays one line."""
    return " ".join(str(exc).split()) or type(exc).__name__


#: The note of the phone readers (phyphox, Sensor Logger): vibrospeed's x is forward, a phone's
#: is its right edge, and ``fuse`` / ``gps-riss`` read ``ax`` as the longitudinal acceleration
#: unless told (docs/formats.md).
PHONE_AXES_NOTE = ("phone axes (x right, y to the top edge, z out of the screen): lying flat with "
                   "the top edge forward, y is longitudinal and x lateral; give -p accel_axis=y "
                   "to fuse and --axis y to gps-riss (they read ax otherwise)")


#: Suffixes of files that are never recordings: sidecars, images, pages, notes, settings.
NOT_RECORDING_SUFFIXES = frozenset({".json", ".png", ".jpg", ".jpeg", ".svg", ".html", ".htm",
                                    ".md", ".toml", ".yaml", ".yml"})


def export_folders(folder: str | os.PathLike[str], names: Sequence[str]) -> list[Path]:
    """Where an app export in ``folder`` keeps its files, recognised by any of the file ``names``.

    ``[folder]`` when ``folder`` holds one of them itself; otherwise every subfolder (one level,
    hidden ones and ``__MACOSX`` left out) that does, sorted by name. One entry means ``folder``
    is one export (perhaps unpacked into a folder of its own); several mean a folder of exports,
    each a recording of its own; none, no export. A single export subfolder makes ``folder``
    one export only when nothing beside it may be a recording: a visible file other than a
    sidecar, image or note (:data:`NOT_RECORDING_SUFFIXES`) or the zip it was unpacked from
    (``<its name>.zip``), e.g. another drive's export as a zip, makes ``folder`` a folder of
    recordings (none: ``[]``), so that no drive in it is silently left out. Never raises (an
    unreadable folder: none).
    """
    p = Path(folder)
    try:
        if any((p / n).is_file() for n in names):
            return [p]
        entries = [q for q in sorted(p.iterdir())
                   if not q.name.startswith(".") and q.name != "__MACOSX"]
        found = [q for q in entries if q.is_dir() and any((q / n).is_file() for n in names)]
        if len(found) == 1 and any(q.is_file() and q.suffix.lower() not in NOT_RECORDING_SUFFIXES
                                   and q.name != f"{found[0].name}.zip" for q in entries):
            return []
        return found
    except OSError:
        return []


def several_exports(path: str | os.PathLike[str], exports: Sequence[Path | str],
                    app: str) -> ReaderError:
    """The error for a folder or zip holding several ``app`` exports (their folders
    ``exports``; ``""``: the zip's top) where one recording was asked for."""
    names = [Path(q).name or "." for q in exports]
    shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
    if Path(path).is_dir():
        return ReaderError(path, f"a folder of {len(names)} {app} exports ({shown}), not one "
                                 "recording: give one of them, or `vibrospeed batch` for all")
    return ReaderError(path, f"a zip of {len(names)} {app} exports ({shown}), not one "
                             "recording: unpack it and give one folder, or `vibrospeed batch` "
                             "the unpacked folder")
