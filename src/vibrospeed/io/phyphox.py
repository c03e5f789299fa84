"""phyphox exports (https://phyphox.org): a folder or .zip of per-sensor CSV files.

A folder is one export when it holds ``Accelerometer.csv``, or when exactly one of its subfolders
does and no file beside it may be a recording (an export unpacked into a folder of its own;
:func:`vibrospeed.io._common.export_folders`). A folder with several such subfolders, or with one
beside other drives' files, holds several drives: each is one recording (``vibrospeed batch``
reads them one by one), and reading the folder, or a zip holding several exports, as one
recording is an error naming them.

Files used (each with its own time base, first column ``Time (s)``):

``Accelerometer.csv``       X, Y, Z (m/s^2) -> ``ax ay az``. **Master time line.**
``Gyroscope.csv``           X, Y, Z (rad/s) -> ``gx gy gz``, linearly interpolated onto the master
                            time line (NaN outside its span and across gaps > 5 gyro periods).
``Linear Acceleration.csv`` optional -> ``lin_ax lin_ay lin_az`` (gravity removed by the phone),
                            interpolated like the gyroscope.
``Location.csv``            ``Velocity (m/s)`` -> ``gps_speed`` (-1 or any negative value = no
                            valid speed -> NaN) and ``Horizontal Accuracy (m)`` -> ``gps_hacc``.
                            Each fix is placed at the single accelerometer sample nearest to it
                            and the channels are NaN elsewhere, so that an estimator sees every
                            fix exactly once, at most half an accelerometer period late or early
                            (if several fixes share a sample, the last one with a valid velocity
                            is kept, both channels from the same fix). A valid fix inside a gap
                            of the accelerometer gets a row of its own at its time, the
                            accelerometer NaN there (:func:`.timebase.rows_for_fixes`).
                            The raw fix times are kept as event ``gps_fix``. phyphox gives no
                            satellite count, so there is no ``gps_sats``.

Time: a row repeating the previous row's timestamp exactly (phones emit a few, e.g. 2 in 22000
accelerometer rows of rsq_q2_01) is dropped, keeping the first, and noted; time going backwards
is an error unless ``sort=True``.

Axes are the phone's (x right, y towards the top edge, z out of the screen); for a phone lying
flat, top edge forward, y is longitudinal and x lateral (as in the Hungary drives). Headers are
quoted and may contain a mis-encoded degree sign; columns are found by their x/y/z letter and
unit, so header wording differences between phyphox versions do not matter. Semicolon exports with
a decimal comma are read too.
"""

from __future__ import annotations

import contextlib
import os
import re
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import (
    PHONE_AXES_NOTE,
    export_folders,
    finish,
    negative_as_no_fix,
    several_exports,
)
from vibrospeed.io._csv import CsvTable, nan_notes, text_stream
from vibrospeed.io.timebase import interp_onto, merge_fix_rows, nearest_index, row_order
from vibrospeed.types import Recording

__all__ = ["is_phyphox", "read_phyphox"]

ACC, GYR, LIN, LOC = "Accelerometer.csv", "Gyroscope.csv", "Linear Acceleration.csv", "Location.csv"
_MEMBERS = (ACC, GYR, LIN, LOC)
_AXIS = re.compile(r"(?:^|[\s_])([xyz])(?=[\s(_]|$)", re.IGNORECASE)


class _Source:
    """Files of one export, from a folder or a zip; ``open(name)`` yields a text stream."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.files: dict[str, Callable[[], contextlib.AbstractContextManager[IO[str]]]] = {}
        self.labels: dict[str, str] = {}
        if path.is_dir():
            roots = export_folders(path, (ACC,))
            if len(roots) > 1:
                raise several_exports(path, roots, "phyphox")
            root = roots[0] if roots else path
            for name in _MEMBERS:
                if (root / name).is_file():
                    self._add_file(name, root / name)
        elif zipfile.is_zipfile(path):
            try:
                zf = zipfile.ZipFile(path)
                infos = zf.infolist()
            except (zipfile.BadZipFile, OSError) as exc:
                raise ReaderError(path, f"unreadable zip file ({exc})") from None
            members = [info.filename for info in infos
                       if "__MACOSX" not in info.filename and not info.is_dir()]
            # the export is the zip folder holding the accelerometer; several such: several drives
            acc_dirs = sorted({m.rpartition("/")[0] for m in members
                               if m.rpartition("/")[2] == ACC})
            if len(acc_dirs) > 1:
                raise several_exports(path, acc_dirs, "phyphox")
            for m in members:
                folder, _, base = m.rpartition("/")
                if base in _MEMBERS and base not in self.files and (not acc_dirs
                                                                    or folder == acc_dirs[0]):
                    self.files[base] = self._zip_opener(path, m)
                    self.labels[base] = f"{path}:{m}"
        else:
            # a single CSV: part of an export folder, or one sensor on its own
            if path.name in _MEMBERS and (path.parent / ACC).is_file():
                self.__init__(path.parent)
                return
            self._add_file(ACC, path)

    def _add_file(self, name: str, p: Path) -> None:
        @contextlib.contextmanager
        def opener() -> Iterator[IO[str]]:
            if p.stat().st_size == 0:
                raise ReaderError(p, "empty file")
            with open(p, encoding="utf-8", newline="") as fh:
                yield fh

        self.files[name] = opener
        self.labels[name] = str(p)

    @staticmethod
    def _zip_opener(path: Path, member: str):
        @contextlib.contextmanager
        def opener() -> Iterator[IO[str]]:
            try:
                with zipfile.ZipFile(path) as zf, zf.open(member) as raw:
                    yield text_stream(raw)
            except (zipfile.BadZipFile, OSError, EOFError) as exc:
                raise ReaderError(f"{path}:{member}", f"unreadable zip member ({exc})") from None

        return opener


def is_phyphox(path: str | os.PathLike[str]) -> bool:
    """True for a folder holding one export (``Accelerometer.csv`` in it or in its one subfolder
    that has one), a zip holding ``Accelerometer.csv``, or a CSV whose first column is phyphox's
    ``Time (s)``. A folder of several exports is not one recording: False (a batch reads it as
    its exports)."""
    p = Path(path)
    try:
        if p.is_dir():  # one export, perhaps in a folder of its own; a folder of several: no
            return len(export_folders(p, (ACC,))) == 1
        if zipfile.is_zipfile(p):
            with zipfile.ZipFile(p) as zf:
                return any(n.rsplit("/", 1)[-1] == ACC for n in zf.namelist())
        with open(p, encoding="utf-8", errors="replace") as fh:
            first = fh.readline().lstrip("\ufeff").strip()
        return first.strip('"').startswith("Time (s)")
    except (OSError, zipfile.BadZipFile):
        return False


def _read_table(src: _Source, name: str) -> tuple[CsvTable, dict[str, np.ndarray], np.ndarray]:
    label = src.labels[name]
    with src.files[name]() as fh:
        tab = CsvTable(fh, label)
        if tab.delimiter == ";":
            tab.decimal = ","
        cols, lines = tab.read([h for h in tab.header if h])
    return tab, cols, lines


def _xyz(tab: CsvTable, label: str) -> list[str]:
    """Header names of the x, y, z columns (by axis letter, else the three after time)."""
    found: dict[str, str] = {}
    for h in tab.header[1:]:
        m = _AXIS.search(h)
        if m and m.group(1).lower() not in found:
            found[m.group(1).lower()] = h
    if len(found) == 3:
        return [found["x"], found["y"], found["z"]]
    if len(tab.header) >= 4:
        return tab.header[1:4]
    raise ReaderError(label, "expected a time column and x, y, z columns", row=tab.header_line)


def _sensor(src, name, sort, notes):
    tab, cols, lines = _read_table(src, name)
    label = src.labels[name]
    if "time" not in tab.header[0].lower():  # phyphox writes "Time (s)" first, every version
        raise ReaderError(label, f"first column {tab.header[0]!r} is not phyphox's 'Time (s)': "
                          "not a phyphox export (--format auto detects the format)",
                          row=tab.header_line)
    t = cols[tab.header[0]]
    xyz = [cols[h] for h in _xyz(tab, label)]
    order = row_order(t, lines, label, sort, notes)
    return tab, t[order], [x[order] for x in xyz], lines[order]


def read_phyphox(path: str | os.PathLike[str], *, sort: bool = False) -> Recording:
    """Read a phyphox export (folder, .zip, or a single sensor CSV) onto the accelerometer's time
    line; see the module docstring for how each sensor is merged.

    Parameters
    ----------
    path : export folder, zip file, or one phyphox CSV
    sort : sort each file by time and drop repeated timestamps instead of refusing them
    """
    p = Path(path)
    if not p.exists():
        raise ReaderError(p, "file not found")
    src = _Source(p)
    if ACC not in src.files:
        raise ReaderError(p, f"no {ACC} in this phyphox export")
    notes: list[str] = []
    units: dict[str, str] = {}
    tab, t, (ax, ay, az), lines = _sensor(src, ACC, sort, notes)
    notes.extend(tab.notes)
    chans = {"ax": ax, "ay": ay, "az": az}
    if any("rad/s" in h for h in tab.header[1:]):  # a lone gyroscope file given as the source
        chans = {"gx": ax, "gy": ay, "gz": az}
    notes.extend(nan_notes(chans, src.labels[ACC]))
    fs = 1.0 / float(np.median(np.diff(t))) if t.size > 1 else float("nan")
    notes.append(f"phyphox {src.labels[ACC]}: {t.size} samples, master time line (~{fs:.4g} Hz)")
    notes.append(PHONE_AXES_NOTE)
    loc = _read_location(src, sort, notes) if LOC in src.files else None
    meta: dict[str, object] = {"format": "phyphox"}
    if loc is not None:  # fixes inside accelerometer gaps: rows of their own (not lost)
        t, chans, lines, fnotes, fmeta = merge_fix_rows(t, loc[1][np.isfinite(loc[2])], chans,
                                                        lines)
        notes.extend(fnotes)
        meta.update(fmeta)
    for name, prefix in ((GYR, "g"), (LIN, "lin_a")):
        if name not in src.files:
            continue
        tb, tg, xyz, _ = _sensor(src, name, sort, notes)
        notes.extend(tb.notes)
        if tg.size < 2:
            raise ReaderError(src.labels[name], "fewer than 2 samples")
        dtg = float(np.median(np.diff(tg)))
        for ax_name, x in zip("xyz", xyz, strict=True):
            chans[f"{prefix}{ax_name}"] = interp_onto(tg, x, t, 5.0 * dtg)
            units[f"{prefix}{ax_name}"] = "rad/s" if prefix == "g" else "m/s^2"
        notes.append(
            f"{name} ({1 / dtg:.4g} Hz) linearly interpolated onto the accelerometer time line "
            f"(NaN outside {tg[0]:.4g}..{tg[-1]:.4g} s and across gaps > {5 * dtg:.3g} s)"
        )
    events: dict[str, np.ndarray] = {}
    if loc is not None:
        chans_gps, ev, gnotes = _location(loc, t)
        chans.update(chans_gps)
        events.update(ev)
        notes.extend(gnotes)
        units.update({"gps_speed": "m/s", "gps_hacc": "m"})
    return finish(
        t, chans, source=str(p), lines=lines, sort=False, units=units, events=events, notes=notes,
        axes="phone axes: x right, y top edge, z out of screen (flat, top forward: x lateral, "
        "y longitudinal, z up incl. +g)",
        meta=meta,
    )


def _read_location(src: _Source, sort: bool, notes: list[str]):
    """``Location.csv``: its table's notes, fix times, velocity (NaN: no fix) and horizontal
    accuracy (None without that column)."""
    tab, cols, lines = _read_table(src, LOC)
    label = src.labels[LOC]
    tl = cols[tab.header[0]]
    vel = next((h for h in tab.header if h.lower().startswith("velocity")), None)
    if vel is None:
        raise ReaderError(label, "no 'Velocity (m/s)' column", row=tab.header_line,
                          column="Velocity (m/s)")
    hacc = next((h for h in tab.header if "horizontal accuracy" in h.lower()), None)
    order = row_order(tl, lines, label, sort, notes)
    cols = {k: x[order] for k, x in cols.items()}
    tl = tl[order]
    # phyphox writes -1 when the fix has no velocity: NaN before the valid fixes are picked
    v, vnote = negative_as_no_fix("gps_speed", cols[vel])
    h, hnote = negative_as_no_fix("gps_hacc", cols[hacc]) if hacc is not None else (None, [])
    notes.extend(f"{label}: {n}" for n in vnote + hnote)
    return tab.notes, tl, v, h


def _location(loc, t: np.ndarray):
    """The fixes of :func:`_read_location` placed on the accelerometer time line ``t``."""
    tab_notes, tl, v, hacc = loc
    h = np.full(tl.size, np.nan) if hacc is None else hacc
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    inside = np.flatnonzero((tl >= t[0] - dt / 2) & (tl <= t[-1] + dt / 2))
    j = nearest_index(tl[inside], t)
    valid = np.isfinite(v[inside])
    # one fix per sample: the last one with a valid velocity, else the last one
    order = np.lexsort((inside, valid, j))
    last = np.ones(order.size, dtype=bool)
    last[:-1] = j[order][1:] != j[order][:-1]
    win = order[last]
    out = {"gps_speed": np.full(t.size, np.nan), "gps_hacc": np.full(t.size, np.nan)}
    out["gps_speed"][j[win]] = v[inside][win]
    out["gps_hacc"][j[win]] = h[inside][win]
    if hacc is None:
        del out["gps_hacc"]
    nvalid = int(np.count_nonzero(valid))
    nplaced = int(np.count_nonzero(np.isfinite(out["gps_speed"])))
    gnotes = [
        *tab_notes,
        f"{LOC}: {tl.size} fixes, {nvalid} with a valid velocity inside the accelerometer span; "
        "gps_speed/gps_hacc placed at the accelerometer sample nearest each fix, NaN elsewhere; "
        "raw fix times in event 'gps_fix'"
    ]
    if nplaced < nvalid:
        gnotes.append(f"{nvalid - nplaced} valid GPS fix(es) fell on the same sample as a later "
                      "one (the later is kept)")
    if nvalid == 0:
        gnotes.append("no GPS fix with a valid velocity: gps_speed is all NaN")
    return out, {"gps_fix": tl[np.isfinite(tl)]}, gnotes
