"""Sensor Logger exports (the Android / iOS app by Kelvin Choi): a folder or a .zip of per-sensor
CSV files, each ``time`` (ns since the epoch), ``seconds_elapsed`` (s), then the values.

Files used (columns are found by name, so ``z,y,x`` and ``x,y,z`` orders both work):

================================  =========================================================
``TotalAcceleration.csv``         x y z (m/s^2, *with* gravity; Android) -> ``ax ay az``.
                                  **Master time line** when present.
``Accelerometer.csv``             x y z (m/s^2, *without* gravity: the phone's "user
                                  acceleration") -> ``lin_ax lin_ay lin_az``. Master time line
                                  when there is no TotalAcceleration.csv; then ``ax ay az`` =
                                  Accelerometer + Gravity.csv (interpolated onto it), or the
                                  Accelerometer alone (no gravity, said in a note) without one.
``AccelerometerUncalibrated.csv`` raw x y z (with gravity) -> ``ax ay az`` only when neither
                                  file above exists (iOS writes it in g: converted, see below).
``Gravity.csv``                   x y z (m/s^2), only to add gravity back (see above).
``Gyroscope.csv``                 x y z (rad/s) -> ``gx gy gz``; ``GyroscopeUncalibrated.csv``
                                  when there is no calibrated one.
``Magnetometer.csv``              x y z (uT) -> ``mx my mz`` (uncalibrated one as fallback).
``Location.csv``                  ``speed`` (m/s) -> ``gps_speed``, ``horizontalAccuracy`` (m)
                                  -> ``gps_hacc``, ``latitude longitude altitude`` ->
                                  ``gps_lat gps_lon gps_alt``; negative speed / accuracy =
                                  invalid -> NaN. Each fix is placed once, at the master
                                  sample nearest it (NaN elsewhere; of fixes sharing a sample the
                                  last with a valid speed wins), raw fix times in event
                                  ``gps_fix`` -- as the phyphox reader does, a fix inside a
                                  gap of the master getting a row of its own.
``Metadata.csv``                  ``platform`` and ``standardisation``: see below.
================================  =========================================================

Every other sensor's samples are linearly interpolated onto the master time line (NaN outside
its span and across gaps longer than 5 of its own periods), as for phyphox. Time is
``t = (time - first master time) / 1e9`` s (``seconds_elapsed`` when there is no ``time``
column); the epoch offset is kept in ``meta["t0_epoch_ns"]``.

Platforms: Android's axes are kept (x right, y top edge, z out of the screen; a phone flat on its
back reads +g on z). iOS writes accelerations and gravity with the opposite sign and the
uncalibrated accelerometer in g unless "Standardise Units & Frames" was on; when Metadata.csv says
``platform=ios`` without standardisation the accelerations are negated and g is converted to
m/s^2 (noted). Without Metadata.csv an uncalibrated accelerometer whose median magnitude is
below 3 is taken to be in g (noted).

A folder is one export when it holds a sensor file, or when exactly one of its subfolders does
(an export unpacked into a folder of its own); a folder with several such subfolders holds
several drives, each one recording (``vibrospeed batch``), and reading it as one is an error.

A zip is read member by member into memory (:mod:`vibrospeed.io._archive`: no extraction to
disk, size and compression-ratio limits).
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._archive import SafeZip
from vibrospeed.io._common import (
    PHONE_AXES_NOTE,
    export_folders,
    finish,
    negative_as_no_fix,
    several_exports,
)
from vibrospeed.io._csv import CsvTable, nan_notes
from vibrospeed.io.timebase import interp_onto, merge_fix_rows, nearest_index, row_order
from vibrospeed.types import Recording

__all__ = ["detect", "read_sensorlogger"]

TOT, ACC, ACCU, GRAV = ("TotalAcceleration.csv", "Accelerometer.csv",
                        "AccelerometerUncalibrated.csv", "Gravity.csv")
GYR, GYRU, MAG, MAGU = ("Gyroscope.csv", "GyroscopeUncalibrated.csv", "Magnetometer.csv",
                        "MagnetometerUncalibrated.csv")
LOC, META = "Location.csv", "Metadata.csv"
MEMBERS = (TOT, ACC, ACCU, GRAV, GYR, GYRU, MAG, MAGU, LOC, META)
SENSORS = tuple(n for n in MEMBERS if n not in (META, LOC))  # the files that make an export
G0 = 9.80665  # m/s^2, the app's standard gravity


class _Source:
    """The export's files from a folder, a zip, or a single CSV (then its folder)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.zip: SafeZip | None = None
        self.files: dict[str, Path] = {}
        if path.is_dir():
            roots = export_folders(path, SENSORS)
            if len(roots) > 1:
                raise several_exports(path, roots, "Sensor Logger")
            root = roots[0] if roots else path
            for name in MEMBERS:
                if (root / name).is_file():
                    self.files[name] = root / name
        elif _is_zip(path):
            self.zip = SafeZip(path)
            inner = self.zip.folders(SENSORS)
            if len(inner) > 1:
                raise several_exports(path, inner, "Sensor Logger")
        elif path.name in MEMBERS and path.name != META:
            for name in MEMBERS:
                if (path.parent / name).is_file():
                    self.files[name] = path.parent / name
        else:  # one sensor file on its own: read as the accelerometer
            self.files[ACC] = path

    def names(self) -> set[str]:
        if self.zip is not None:
            return {n for n in MEMBERS if n in self.zip.members}
        return set(self.files)

    def label(self, name: str) -> str:
        return self.zip.label(name) if self.zip is not None else str(self.files[name])

    @contextlib.contextmanager
    def open(self, name: str) -> Iterator[TextIO]:
        if self.zip is not None:
            yield self.zip.text(name)
            return
        p = self.files[name]
        if p.stat().st_size == 0:
            raise ReaderError(p, "empty file")
        with open(p, encoding="utf-8", newline="") as fh:
            yield fh


def _is_zip(p: Path) -> bool:
    try:
        return p.is_file() and zipfile.is_zipfile(p)
    except OSError:
        return False


def _looks_like(head: bytes | str) -> bool:
    if isinstance(head, bytes):
        head = head.decode("utf-8", errors="replace")
    first = head.lstrip("\ufeff").split("\n", 1)[0].strip().lower().replace('"', "")
    cols = [c.strip() for c in first.split(",")]
    return len(cols) >= 3 and cols[0] == "time" and cols[1] == "seconds_elapsed"


def _head(p: Path, n: int = 512) -> bytes:
    try:
        with open(p, "rb") as fh:
            return fh.read(n)
    except OSError:
        return b""


def detect(path: str | os.PathLike[str]) -> bool:
    """True for a folder / zip holding a Sensor Logger sensor CSV (header ``time,seconds_elapsed,
    ...``) or for one such file. Never raises."""
    p = Path(path)
    try:
        if p.is_dir():  # one export (perhaps in a folder of its own), not a folder of several
            roots = export_folders(p, SENSORS)
            if len(roots) != 1:
                return False
            name = next(n for n in SENSORS if (roots[0] / n).is_file())
            return _looks_like(_head(roots[0] / name))
        if _is_zip(p):
            z = SafeZip(p)
            name = next((n for n in SENSORS if n in z.members), None)
            return name is not None and _looks_like(z.head(name))
        return p.is_file() and _looks_like(_head(p))
    except (OSError, ReaderError):
        return False


def _metadata(src: _Source, notes: list[str]) -> dict[str, str]:
    if META not in src.names():
        return {}
    try:
        with src.open(META) as fh:
            rows = list(csv.reader(io.StringIO(fh.read(1 << 16))))
    except (ReaderError, UnicodeDecodeError, csv.Error):
        notes.append(f"{META} unreadable, ignored")
        return {}
    if len(rows) < 2:
        return {}
    return {h.strip().lower(): v.strip() for h, v in zip(rows[0], rows[1], strict=False)}


def _table(src: _Source, name: str, want: list[str], sort: bool, notes: list[str]):
    """Time (epoch ns or s elapsed, as float) and the wanted columns of one file, ordered."""
    label = src.label(name)
    with src.open(name) as fh:
        tab = CsvTable(fh, label)
        lower = {h.lower(): h for h in tab.header if h}
        tcol = lower.get("time") or lower.get("seconds_elapsed")
        if tcol is None:
            raise ReaderError(label, "no 'time' or 'seconds_elapsed' column", row=tab.header_line,
                              column="time")
        cols = [tcol]
        for w in want:
            if w.lower() not in lower:
                raise ReaderError(label, f"column not found (header has: "
                                  f"{', '.join(tab.header)[:120]})", row=tab.header_line, column=w)
            cols.append(lower[w.lower()])
        data, lines = tab.read(cols)
    notes.extend(f"{label}: {n}" for n in tab.notes)
    scale = 1e-9 if tcol.lower() == "time" else 1.0
    t = data[tcol]
    order = row_order(t, lines, label, sort, notes)
    return t[order], scale, [data[c][order] for c in cols[1:]], lines[order]


def read_sensorlogger(path: str | os.PathLike[str], *, sort: bool = False) -> Recording:
    """Read a Sensor Logger export (folder, .zip, or one of its CSV files) onto the acceleration
    file's time line; see the module docstring for what is read and how.

    Parameters
    ----------
    path : export folder, zip file, or one Sensor Logger CSV
    sort : sort each file by time and drop repeated timestamps instead of refusing them
    """
    p = Path(path)
    if not p.exists():
        raise ReaderError(p, "file not found")
    src = _Source(p)
    have = src.names()
    notes: list[str] = []
    meta_csv = _metadata(src, notes)
    platform = meta_csv.get("platform", "").lower()
    std = next((v for k, v in meta_csv.items() if k.startswith("standardi")), "").lower()
    ios_raw = platform == "ios" and std not in ("true", "1", "yes", "on")
    if platform:
        notes.append(f"Sensor Logger on {platform}" + (
            " without 'Standardise Units & Frames': accelerations negated to Android's sign "
            "convention" if ios_raw else ""))
    master = next((n for n in (TOT, ACC, ACCU) if n in have), None)
    if master is None:
        raise ReaderError(p, f"no {TOT}, {ACC} or {ACCU} in this Sensor Logger export")
    xyz = ["x", "y", "z"]
    traw, scale, (ax, ay, az), lines = _table(src, master, xyz, sort, notes)
    if traw.size == 0:
        raise ReaderError(src.label(master), "no samples")
    t_ref = float(traw[0])
    t = (traw - t_ref) * scale
    sign = -1.0 if ios_raw else 1.0
    acc = [sign * a for a in (ax, ay, az)]
    notes.extend(nan_notes(dict(zip(("ax", "ay", "az"), acc, strict=True)), src.label(master)))
    units: dict[str, str] = {}
    chans: dict[str, np.ndarray] = {}
    fs = 1.0 / float(np.median(np.diff(t))) if t.size > 1 else float("nan")
    label = src.label(master)
    notes.append(f"Sensor Logger {label}: {t.size} samples, master time line (~{fs:.4g} Hz)")
    notes.append(PHONE_AXES_NOTE)
    loc = _read_location(src, t_ref, scale, sort, notes) if LOC in have else None
    fix_meta: dict[str, list] = {}
    if loc is not None:  # fixes inside accelerometer gaps: rows of their own (not lost)
        acc_ch = dict(zip("xyz", acc, strict=True))
        t, acc_ch, lines, fnotes, fix_meta = merge_fix_rows(
            t, loc[0][np.isfinite(loc[1]["gps_speed"])], acc_ch, lines)
        acc = [acc_ch[k] for k in "xyz"]
        notes.extend(fnotes)

    def onto(name: str, want: list[str]) -> list[np.ndarray] | None:
        """Columns of ``name`` interpolated onto the master time line (None if unusable)."""
        tk, sk, cols, _ = _table(src, name, want, sort, notes)
        if sk != scale:
            raise ReaderError(src.label(name), f"time column differs from {master}'s "
                              "(time vs seconds_elapsed)")
        tk = (tk - t_ref) * sk
        if tk.size < 2:
            notes.append(f"{name}: {tk.size} sample(s), not used")
            return None
        dt = float(np.median(np.diff(tk)))
        notes.append(f"{name} ({1 / dt:.4g} Hz) linearly interpolated onto the {master} time "
                     f"line (NaN outside {tk[0]:.4g}..{tk[-1]:.4g} s and across gaps > "
                     f"{5 * dt:.3g} s)")
        return [interp_onto(tk, x, t, 5.0 * dt) for x in cols]

    if master == TOT:
        notes.append(f"{TOT} (with gravity) used as ax ay az"
                     + (f"; {ACC} (without gravity) as lin_ax lin_ay lin_az" if ACC in have
                        else ""))
        if ACC in have:
            lin = onto(ACC, xyz)
            if lin is not None:
                chans.update({f"lin_a{k}": sign * v for k, v in zip("xyz", lin, strict=True)})
    elif master == ACC:
        chans.update({f"lin_a{k}": v for k, v in zip("xyz", acc, strict=True)})
        grav = onto(GRAV, xyz) if GRAV in have else None
        if grav is not None:
            acc = [a + sign * g for a, g in zip(acc, grav, strict=True)]
            notes.append(f"ax ay az = {ACC} (without gravity) + {GRAV} (interpolated); "
                         "lin_ax lin_ay lin_az = Accelerometer alone")
        else:
            notes.append(f"ax ay az from {ACC}: WITHOUT gravity (no {TOT} or {GRAV}); az has no "
                         "+g offset")
    else:
        in_g = platform == "ios" and ios_raw
        if not platform:
            mag = np.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2)
            med = float(np.nanmedian(mag)) if np.any(np.isfinite(mag)) else float("nan")
            in_g = bool(med < 3.0)
            if in_g:
                notes.append(f"{ACCU}: median magnitude {med:.3g} looks like g (iOS): converted "
                             "to m/s^2 and negated to Android's sign convention")
                acc = [-a for a in acc]
        if in_g:
            acc = [G0 * a for a in acc]
        notes.append(f"ax ay az from {ACCU} (raw, with gravity; no calibrated accelerometer)")
    chans.update({"ax": acc[0], "ay": acc[1], "az": acc[2]})
    for name, alt, prefix, unit in ((GYR, GYRU, "g", "rad/s"), (MAG, MAGU, "m", "uT")):
        use = name if name in have else alt if alt in have else None
        if use is None:
            continue
        vals = onto(use, xyz)
        if vals is not None:
            for k, v in zip("xyz", vals, strict=True):
                chans[prefix + k], units[prefix + k] = v, unit
            if use == alt:
                notes.append(f"{alt} used (no {name})")
    for k in ("lin_ax", "lin_ay", "lin_az"):
        if k in chans:
            units[k] = "m/s^2"
    events: dict[str, np.ndarray] = {}
    if loc is not None:
        g, ev, gnotes, gunits = _location(loc, t)
        chans.update(g)
        events.update(ev)
        notes.extend(gnotes)
        units.update(gunits)
    meta = {"format": "sensorlogger", "master": master,
            "t0_epoch_ns" if scale == 1e-9 else "t0_elapsed_s": t_ref}
    if platform:
        meta["platform"] = platform
    meta.update(fix_meta)
    return finish(
        t, chans, source=str(p), lines=lines, sort=False, units=units, events=events,
        notes=notes, meta=meta,
        axes="phone axes, Android convention: x right, y top edge, z out of screen (flat, top "
        "forward: x lateral, y longitudinal, z up incl. +g)",
    )


def _read_location(src: _Source, t_ref: float, scale: float, sort: bool, notes: list[str]):
    """``Location.csv``: fix times on the master's clock and the GPS channels by name
    (negative speed / accuracy: invalid -> NaN)."""
    label = src.label(LOC)
    with src.open(LOC) as fh:
        header = [h.strip().lower() for h in next(csv.reader([fh.readline().lstrip("\ufeff")]),
                                                         [])]
    cols = {"gps_speed": "speed", "gps_hacc": "horizontalaccuracy", "gps_lat": "latitude",
            "gps_lon": "longitude", "gps_alt": "altitude"}
    if "speed" not in header:
        raise ReaderError(label, "no 'speed' column", row=1, column="speed")
    cols = {k: v for k, v in cols.items() if v in header}
    tl, sk, vals, _ = _table(src, LOC, list(cols.values()), sort, notes)
    if sk != scale:
        raise ReaderError(label, "time column differs from the accelerometer's")
    tl = (tl - t_ref) * sk
    data = dict(zip(cols, vals, strict=True))
    for k in ("gps_speed", "gps_hacc"):  # the app writes negative values for "invalid"
        if k in data:
            data[k], knote = negative_as_no_fix(k, data[k])
            notes.extend(f"{label}: {n}" for n in knote)
    return tl, data


def _location(loc, t: np.ndarray):
    """The fixes of :func:`_read_location` placed on the master time line ``t``."""
    tl, data = loc
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    inside = np.flatnonzero((tl >= t[0] - dt / 2) & (tl <= t[-1] + dt / 2))
    j = nearest_index(tl[inside], t)
    valid = np.isfinite(data["gps_speed"][inside])
    order = np.lexsort((inside, valid, j))  # per sample: last valid fix, else the last one
    last = np.ones(order.size, dtype=bool)
    last[:-1] = j[order][1:] != j[order][:-1]
    win = order[last]
    out = {}
    for k, x in data.items():
        y = np.full(t.size, np.nan)
        y[j[win]] = x[inside][win]
        out[k] = y
    nvalid = int(np.count_nonzero(valid))
    gnotes = [f"{LOC}: {tl.size} fixes, {nvalid} with a valid speed inside the accelerometer "
              "span; GPS channels placed at the sample nearest each fix, NaN elsewhere; raw fix "
              "times in event 'gps_fix'"]
    nplaced = int(np.count_nonzero(np.isfinite(out["gps_speed"])))
    if nplaced < nvalid:
        gnotes.append(f"{nvalid - nplaced} valid GPS fix(es) fell on the same sample as a later "
                      "one (the later is kept)")
    if nvalid == 0:
        gnotes.append("no GPS fix with a valid speed: gps_speed is all NaN")
    units = {"gps_speed": "m/s", "gps_hacc": "m", "gps_lat": "deg", "gps_lon": "deg",
             "gps_alt": "m"}
    return out, {"gps_fix": tl[np.isfinite(tl)]}, gnotes, {k: units[k] for k in out}
