"""Helpers shared by the readers: building a checked Recording, JSON-safe metadata, checksums."""

from __future__ import annotations

import hashlib
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

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
    rec.notes.extend(describe_timebase(rec))
    return rec


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
