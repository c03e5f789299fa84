"""AndroSensor exports split into ``accel.<trip>.csv`` and ``gps.<trip>.csv`` (the layout of the
quat_orient_corolla recordings in ``../shared/datasets``).

``accel.*.csv``: ``Time since start in ms, ACCELEROMETER X (m/s²), ... Y ..., ... Z ...``
(Android device axes, not vehicle axes: the phone's mounting decides how they map; they are
stored as ``ax ay az`` with a note). ``gps.*.csv`` beside it (same trip suffix):
``Time since start in ms, LOCATION Latitude, Longitude, LOCATION Speed ( Kmh), ...,
Satellites in range, ...``: speed km/h -> m/s as ``gps_speed`` and ``gps_sats``, each fix placed
once at the accelerometer sample nearest it (NaN elsewhere), as for phyphox; a fix inside a gap of
the accelerometer gets a row of its own (:func:`vibrospeed.io.timebase.rows_for_fixes`). The
accelerometer rate of these logs (~16.7 Hz) is far too low for wheel vibrations: the vibration
trackers refuse it through their Nyquist check; GPS fusion works.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import finish, negative_as_no_fix
from vibrospeed.io._csv import CsvTable, nan_notes, open_text
from vibrospeed.io.timebase import merge_fix_rows, place_nearest
from vibrospeed.types import Recording

_TIME = "Time since start in ms"


def _find(tab: CsvTable, *words: str) -> str:
    """Header name containing every word (case-insensitive)."""
    for h in tab.header:
        if all(w.lower() in h.lower() for w in words):
            return h
    raise ReaderError(tab.source, f"no column with {' '.join(words)!r} (header: {tab.header})",
                      row=tab.header_line)


def _table(path: Path) -> tuple[CsvTable, dict[str, np.ndarray], np.ndarray]:
    with open_text(path) as fh:
        tab = CsvTable(fh, str(path))
        cols, lines = tab.read([h for h in tab.header if h])
    return tab, cols, lines


def detect(path: str | os.PathLike[str]) -> bool:
    """True for a file whose header starts with AndroSensor's time column and has ACCELEROMETER."""
    p = Path(path)
    if not p.is_file():
        return False
    try:
        with open(p, encoding="utf-8", errors="replace") as fh:
            head = fh.readline().lstrip("\ufeff")
    except OSError:
        return False
    return head.startswith(_TIME) and "ACCELEROMETER" in head


def accel_of(path: str | os.PathLike[str]) -> Path | None:
    """The ``accel.<trip>.csv`` that reads ``path`` as its GPS (``gps.<trip>.csv`` beside it,
    :func:`read_androsensor`), or None: such a file is part of that recording, not one of its
    own."""
    p = Path(path)
    if not p.name.startswith("gps"):
        return None
    acc = p.with_name("accel" + p.name[3:])
    return acc if detect(acc) else None


def read_androsensor(path: str | os.PathLike[str], *, sort: bool = False) -> Recording:
    """Read ``accel.<trip>.csv`` and, if present, the matching ``gps.<trip>.csv``."""
    p = Path(path)
    tab, cols, lines = _table(p)
    t = cols[_find(tab, "time since start")] * 1e-3
    ch = {f"a{ax}": cols[_find(tab, "accelerometer", ax.upper())] for ax in "xyz"}
    notes = list(tab.notes) + nan_notes(cols, str(p))
    notes.append("AndroSensor accelerometer in Android device axes (x right, y up the screen, "
                 "z out of it): map them to vehicle axes for your mounting")
    events = {}
    meta: dict[str, list[float]] = {}
    gps_path = p.with_name(p.name.replace("accel", "gps", 1)) if "accel" in p.name else None
    if gps_path is not None and gps_path.is_file():
        gtab, g, _ = _table(gps_path)
        tg = g[_find(gtab, "time since start")] * 1e-3
        # a negative speed is no fix (as the phone apps' -1): NaN before the valid fixes are
        # picked, so that it gets no row of its own inside a gap
        v, vnote = negative_as_no_fix("gps_speed", g[_find(gtab, "speed")] / 3.6)
        notes.extend(f"{gps_path.name}: {n}" for n in vnote)
        sats = g[_find(gtab, "satellites")]
        order = np.argsort(tg, kind="stable")
        tg, v, sats = tg[order], v[order], sats[order]
        inside = (tg >= np.nanmin(t)) & (tg <= np.nanmax(t))
        if np.all(np.diff(t) > 0):  # fixes inside accelerometer gaps: rows of their own
            t, ch, lines, fnotes, fmeta = merge_fix_rows(t, tg[inside & np.isfinite(v)], ch,
                                                         lines)
            notes.extend(fnotes)
            meta.update(fmeta)
        grid = np.sort(t)
        ch["gps_speed"] = place_nearest(tg[inside], v[inside], grid)
        ch["gps_sats"] = place_nearest(tg[inside], sats[inside], grid)
        if not np.all(np.diff(t) > 0):  # keep rows aligned with the unsorted time line
            back = np.argsort(np.argsort(t, kind="stable"), kind="stable")
            ch["gps_speed"], ch["gps_sats"] = ch["gps_speed"][back], ch["gps_sats"][back]
        events["gps_fix"] = tg[inside]
        notes.append(f"{gps_path.name}: {int(inside.sum())} fixes, speed km/h -> m/s, placed at "
                     "the nearest accelerometer sample (NaN elsewhere)")
        lost = int(np.count_nonzero(np.isfinite(v[inside]))
                   - np.count_nonzero(np.isfinite(ch["gps_speed"])))
        if lost:
            notes.append(f"{lost} GPS fix(es) fell on the same accelerometer sample as a later "
                         "one (the later is kept)")
    else:
        notes.append("no matching gps.*.csv beside the accelerometer file")
    return finish(t, ch, source=str(p), lines=lines, sort=sort, events=events, notes=notes,
                  meta=meta,
                  axes="Android device axes (x right, y up the screen, z out of the screen)")
