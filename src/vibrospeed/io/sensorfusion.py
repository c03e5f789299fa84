"""Log files of the "Sensor Fusion" Android app (Linkoping University), as used by the thesis
(appendix B.2: Samsung Galaxy S6 Edge at fs = 100 Hz).

One measurement per line, fields separated by tabs (any white space is accepted)::

    timestamp_ms  TAG  v1  v2  v3 ...

=====  ==========================  =================================================
tag    values                      vibrospeed channels
=====  ==========================  =================================================
ACC    x y z (m/s^2)               ``ax ay az`` - **master time line**
GYR    x y z (rad/s)               ``gx gy gz``, linearly interpolated onto ACC times
MAG    x y z (uT)                  ``mx my mz``, linearly interpolated onto ACC times
GPS    lat lon [alt] (deg, deg, m) ``gps_lat gps_lon gps_alt`` at the ACC sample nearest
                                   each fix (NaN elsewhere; inside an ACC gap on a row of
                                   its own); fix times in event ``gps_fix``
ORI    orientation (quaternion)    not used (counted in the notes)
=====  ==========================  =================================================

Time ``t = (timestamp - first ACC timestamp) / 1000`` s; the offset is kept in
``meta["t0_ms"]``. Interpolated channels are NaN outside their sensor's span and across gaps
longer than 5 of its periods. A line repeating the previous timestamp of its sensor exactly is
dropped (first kept) and noted; time going backwards is an error unless ``sort=True``. Unknown
tags are skipped and counted in the notes.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import finish
from vibrospeed.io._csv import _short, check_file
from vibrospeed.io.timebase import (
    check_increasing,
    interp_onto,
    merge_fix_rows,
    place_nearest,
)
from vibrospeed.types import Recording

__all__ = ["is_sensorfusion", "read_sensorfusion"]

_NVALUES = {"ACC": (3, 3), "GYR": (3, 3), "MAG": (3, 3), "GPS": (2, 3), "ORI": (3, 5)}
_LINE = re.compile(r"^\s*[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?\s+[A-Z][A-Z0-9_]{1,7}(?:\s|$)")


def is_sensorfusion(path: str | os.PathLike[str]) -> bool:
    """True if the first non-blank line of ``path`` looks like ``<number> <TAG> ...``."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for _ in range(50):
                line = fh.readline()
                if not line:
                    return False
                line = line.lstrip("\ufeff")
                if line.strip() and not line.lstrip().startswith("#"):
                    return bool(_LINE.match(line))
    except OSError:
        return False
    return False


def _num(s: str, p: Path, line: int, col: str) -> float:
    try:
        return float(s)
    except ValueError:
        raise ReaderError(p, f"'{_short(s)}' is not a number", row=line, column=col) from None


def read_sensorfusion(path: str | os.PathLike[str], *, sort: bool = False) -> Recording:
    """Read a Sensor Fusion app log; see the module docstring for the merge onto ACC times.

    Parameters
    ----------
    path : the log file
    sort : sort each sensor's lines by time and drop repeated timestamps instead of refusing them
    """
    p = check_file(path)
    data: dict[str, list[list[float]]] = {k: [] for k in _NVALUES}
    rows: dict[str, list[int]] = {k: [] for k in _NVALUES}
    other: dict[str, int] = {}
    notes: list[str] = []
    blank = 0
    try:
        with open(p, encoding="utf-8", newline="") as fh:
            for lineno, line in enumerate(fh, start=1):
                if lineno == 1 and line.startswith("\ufeff"):
                    line = line[1:]
                    notes.append("UTF-8 byte-order mark skipped")
                parts = line.split()
                if not parts or parts[0].startswith("#"):
                    blank += 1
                    continue
                if len(parts) < 2:
                    raise ReaderError(p, "expected 'timestamp TAG values...'", row=lineno)
                tag = parts[1]
                if tag not in _NVALUES:
                    other[tag] = other.get(tag, 0) + 1
                    continue
                lo, hi = _NVALUES[tag]
                nv = len(parts) - 2
                if not lo <= nv <= hi:
                    want = f"{lo}" if lo == hi else f"{lo} to {hi}"
                    raise ReaderError(p, f"{tag} line needs {want} values, found {nv}", row=lineno)
                vals = [_num(parts[0], p, lineno, "timestamp")]
                vals += [_num(s, p, lineno, f"{tag} value {k + 1}") for k, s in
                         enumerate(parts[2:])]
                vals += [np.nan] * (hi - nv)
                data[tag].append(vals)
                rows[tag].append(lineno)
    except UnicodeDecodeError as exc:
        raise ReaderError(p, f"not UTF-8 text ({exc.reason})") from None
    if not data["ACC"]:
        raise ReaderError(p, "no ACC lines (accelerometer) in this log", column="ACC")
    arr = {k: np.asarray(v, dtype=np.float64).reshape(-1, _NVALUES[k][1] + 1)
           for k, v in data.items()}
    fin = np.flatnonzero(np.isfinite(arr["ACC"][:, 0]))
    if not fin.size:
        raise ReaderError(p, "no ACC line has a finite timestamp", column="timestamp")
    t0_ms = float(arr["ACC"][fin[0], 0])
    times: dict[str, np.ndarray] = {}
    for k, a in arr.items():
        if not a.size:
            continue
        tk = (a[:, 0] - t0_ms) / 1000.0
        r = np.asarray(rows[k])
        if sort:
            order = np.argsort(tk, kind="stable")
            keep = np.concatenate([[True], np.diff(tk[order]) > 0])
            order = order[keep]
            if order.size < tk.size:
                notes.append(f"{k}: sorted by time, {tk.size - order.size} repeated timestamps "
                             "dropped")
            tk, arr[k], r = tk[order], a[order], r[order]
        else:
            keep = np.concatenate([[True], tk[1:] != tk[:-1]])
            if not keep.all():
                notes.append(f"{k}: dropped {tk.size - int(keep.sum())} line(s) repeating the "
                             "previous timestamp (first kept)")
                tk, arr[k], r = tk[keep], a[keep], r[keep]
            check_increasing(tk, f"{p} ({k} lines)", rows=r)
        times[k] = tk
    t = times["ACC"]
    acc = arr["ACC"]
    chans = {"ax": acc[:, 1], "ay": acc[:, 2], "az": acc[:, 3]}
    units: dict[str, str] = {}
    meta = {"format": "sensorfusion", "t0_ms": t0_ms}
    if "GPS" in times:  # fixes inside ACC gaps: rows of their own (not piled on the gap's edge)
        t, chans, _, fnotes, fmeta = merge_fix_rows(t, times["GPS"], chans)
        notes.extend(fnotes)
        meta.update(fmeta)
    for tag, prefix, unit in (("GYR", "g", "rad/s"), ("MAG", "m", "uT")):
        if tag not in times:
            continue
        tg, a = times[tag], arr[tag]
        if tg.size < 2:
            notes.append(f"{tag}: only {tg.size} line, not used")
            continue
        dtg = float(np.median(np.diff(tg)))
        for j, axn in enumerate("xyz"):
            chans[prefix + axn] = interp_onto(tg, a[:, j + 1], t, 5.0 * dtg)
            units[prefix + axn] = unit
        notes.append(f"{tag} ({1 / dtg:.4g} Hz) linearly interpolated onto the ACC time line")
    events = {}
    if "GPS" in times:
        tg, a = times["GPS"], arr["GPS"]
        dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        inside = (tg >= t[0] - dt / 2) & (tg <= t[-1] + dt / 2)
        for j, (name, unit) in enumerate((("gps_lat", "deg"), ("gps_lon", "deg"),
                                          ("gps_alt", "m"))):
            x = a[inside, j + 1]
            if np.any(np.isfinite(x)):
                chans[name] = place_nearest(tg[inside], x, t)
                units[name] = unit
        events["gps_fix"] = tg
        placed = max((int(np.count_nonzero(np.isfinite(chans[k])))
                      for k in ("gps_lat", "gps_lon", "gps_alt") if k in chans), default=0)
        notes.append(f"GPS: {tg.size} fixes, {int(inside.sum())} inside the ACC span placed at "
                     f"the nearest ACC sample; times in 'gps_fix'")
        if placed < int(inside.sum()):
            notes.append(f"GPS: {int(inside.sum()) - placed} fix(es) fell on the same ACC sample "
                         "as a later one (the later is kept)")
    if "ORI" in times:
        notes.append(f"ORI: {times['ORI'].size} orientation lines not used")
    for tag, n in sorted(other.items()):
        notes.append(f"skipped {n} line(s) with unknown tag {tag}")
    if blank:
        notes.append(f"skipped {blank} blank or comment line(s)")
    return finish(t, chans, source=str(p), lines=None, sort=False, units=units,
                  events=events, notes=notes, meta=meta)
