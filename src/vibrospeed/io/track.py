"""Estimator output files: a Track as CSV plus a JSON sidecar.

``est.csv`` columns, in this order::

    t, omega, omega_lo, omega_hi, speed, omega_std, speed_lo, speed_hi, speed_std, <extras...>

(s, rad/s, m/s; an empty cell is NaN, e.g. ``speed`` when the wheel radius is unknown).
``est.csv.json`` holds ``method``, ``params``, ``level``, ``wheel_radius``, the vibrospeed
``version``, the ``input`` file with its ``input_sha256``, ``notes`` and any extra ``meta``.
Both files are written atomically, the sidecar's text made first (a wheel radius that is not a
finite number > 0 m, or any value JSON cannot hold, stops the writer before the CSV exists) and
an older sidecar removed before the CSV is replaced (so a writer stopped in between never
leaves a new CSV beside an old sidecar that describes another estimate);
:func:`read_track` reads them back exactly.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import InputError, ParameterError, ReaderError
from vibrospeed.io._common import jsonable, sha256_path
from vibrospeed.io._csv import CsvTable, open_text
from vibrospeed.io.atomic import atomic_write_text
from vibrospeed.io.canonical import _write_columns
from vibrospeed.types import Track, check_wheel_radius

__all__ = ["TRACK_COLUMNS", "check_wheel_radius", "read_track", "write_track"]

TRACK_COLUMNS = (
    "t", "omega", "omega_lo", "omega_hi", "speed",
    "omega_std", "speed_lo", "speed_hi", "speed_std",
)


def _version() -> str:
    from vibrospeed import __version__

    return __version__


def write_track(
    track: Track,
    path: str | os.PathLike[str],
    *,
    meta: dict[str, Any] | None = None,
    input_path: str | os.PathLike[str] | None = None,
) -> None:
    """Write ``track`` to ``path`` (CSV) and ``<path>.json`` (metadata), both atomically.

    Parameters
    ----------
    meta : extra JSON-serialisable metadata stored under ``meta`` (e.g. axis, CLI options)
    input_path : the recording the track was estimated from; its path and SHA-256 checksum (of
        the file, or of all files of a folder) go into the sidecar. ``meta["input"]`` is used
        when this is not given.

    Raises :class:`ParameterError` before anything is written where ``track.wheel_radius`` is
    not None or a finite number > 0 m (:func:`check_wheel_radius`) or the sidecar cannot be
    made.
    """
    p = Path(path)
    check_wheel_radius(track.wheel_radius, f"{p}: wheel_radius")
    extras = list(track.extras)
    clash = [k for k in extras if k in TRACK_COLUMNS]
    if clash:
        raise InputError(f"{p}: extra column(s) {', '.join(clash)} clash with standard columns")
    cols = [np.asarray(getattr(track, k), dtype=np.float64) for k in TRACK_COLUMNS]
    cols += [np.asarray(track.extras[k], dtype=np.float64) for k in extras]
    n = cols[0].size
    for name, c in zip([*TRACK_COLUMNS, *extras], cols, strict=True):
        if c.shape != (n,):
            raise InputError(f"{p}: track column '{name}' has shape {c.shape}, expected ({n},)")
    meta = dict(meta or {})
    if input_path is None and meta.get("input"):
        input_path = meta["input"]
    side: dict[str, Any] = {
        "kind": "track",
        "method": track.method,
        "params": jsonable(track.params),
        "level": track.level,
        "wheel_radius": track.wheel_radius,
        "version": _version(),
        "input": os.fspath(input_path) if input_path is not None else None,
        "input_sha256": (
            sha256_path(input_path) if input_path is not None and Path(input_path).exists()
            else None
        ),
        "columns": [*TRACK_COLUMNS, *extras],
        "notes": list(track.notes),
        "meta": jsonable(meta),
    }
    try:  # the sidecar's text first: a value JSON cannot hold stops before the CSV is written
        text = json.dumps(side, indent=1, allow_nan=False) + "\n"
    except ValueError as exc:
        raise ParameterError(f"{p}.json: cannot write the sidecar: {exc}") from None
    # an older sidecar goes before the CSV is replaced: stopped in between, the new CSV stands
    # without one (a batch estimates it again), never beside the old options' sidecar
    Path(f"{p}.json").unlink(missing_ok=True)
    _write_columns(p, [*TRACK_COLUMNS, *extras], cols)
    atomic_write_text(Path(f"{p}.json"), text)


def read_track(path: str | os.PathLike[str]) -> Track:
    """Read a track CSV (and its JSON sidecar if present). ``t`` and ``omega`` or ``speed`` are
    required; other standard columns missing from the file are NaN; unknown columns are extras."""
    p = Path(path)
    with open_text(p) as fh:
        tab = CsvTable(fh, str(p))
        names = [h for h in tab.header if h]
        if "t" not in names or not ({"omega", "speed"} & set(names)):
            raise ReaderError(p, "not a track file: needs columns t and omega or speed",
                              row=tab.header_line)
        cols, lines = tab.read(names, allow_empty=True)
    n = lines.size
    t = cols["t"]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ReaderError(p, "time is missing or not finite", row=int(lines[bad[0]]), column="t")
    side: dict[str, Any] = {}
    q = Path(f"{p}.json")
    if q.is_file():
        try:
            side = json.loads(q.read_text(encoding="utf-8-sig"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ReaderError(q, f"unreadable track sidecar ({exc})") from None
        if not isinstance(side, dict) or side.get("kind") != "track":
            side = {}
    std = {k: cols.get(k, np.full(n, np.nan)) for k in TRACK_COLUMNS}
    extras = {k: v for k, v in cols.items() if k not in TRACK_COLUMNS}
    wr = side.get("wheel_radius")
    level = side.get("level", 0.98)
    return Track(
        **std,
        method=str(side.get("method") or ""),
        params=side.get("params") if isinstance(side.get("params"), dict) else {},
        level=float(level) if isinstance(level, (int, float)) else 0.98,
        wheel_radius=float(wr) if isinstance(wr, (int, float)) else None,
        extras=extras,
        notes=[*(side.get("notes") or []), *tab.notes],
    )
