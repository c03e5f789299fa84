"""Reading and writing recordings and tracks.

:func:`read` turns any supported file into a :class:`~vibrospeed.types.Recording` in SI units with
canonical channel names; :func:`write` stores one (canonical CSV or Parquet, by suffix);
:func:`write_track` / :func:`read_track` store estimator outputs. Every output is written
atomically (:mod:`vibrospeed.io.atomic`); every bad input raises a one-line
:class:`~vibrospeed.errors.ReaderError` naming the file, line and column.

Formats (:data:`FORMATS`)
-------------------------
``csv``          canonical CSV (``t`` first, canonical names), see :mod:`.canonical`
``mapped``       any CSV through a column mapping / TOML file, see :mod:`.mapped`
``phyphox``      phyphox export folder or zip, see :mod:`.phyphox`
``sensorlogger`` Sensor Logger app export folder or zip, see :mod:`.sensorlogger`
``sensorfusion`` Sensor Fusion app log, see :mod:`.sensorfusion`
``rosbag``       ROS 1 / ROS 2 bag (needs ``rosbags``), see :mod:`.rosbag`
``gopro``        GoPro MP4 with GPMF telemetry, see :mod:`.gopro`
``parquet``      Parquet with canonical columns, see :mod:`.parquet`

Adding a reader
---------------
Write a module with a reader ``read_x(path, *, sort=False, ...) -> Recording`` and optionally
``detect(path) -> bool`` (for ``format="auto"``), then either add one line to :data:`_BUILTIN`
(lazy, imported on first use; ``comma2k19`` and ``f1tenth`` are declared there and are offered as
soon as their modules exist) or call :func:`register_format` at run time. :func:`read` passes a
reader only the options its signature accepts and refuses options it does not take.

Examples
--------
>>> import numpy as np, tempfile, pathlib
>>> from vibrospeed.types import Recording
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> rec = Recording(t=np.arange(4) / 100, channels={"ay": np.array([0.0, 1.0, 0.5, -1.0])})
>>> write(rec, d / "r.csv")
>>> read(d / "r.csv")["ay"]
array([ 0. ,  1. ,  0.5, -1. ])
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import os
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.io import _csv
from vibrospeed.io.atomic import atomic_path, atomic_write_bytes, atomic_write_text
from vibrospeed.io.mapped import ColumnSpec, load_mapping, parse_mapping
from vibrospeed.io.parquet import is_parquet
from vibrospeed.io.timebase import (
    check_increasing,
    check_nyquist,
    find_gaps,
    resample_uniform,
    sort_dedup,
    split_at_gaps,
)
from vibrospeed.io.track import read_track, write_track
from vibrospeed.types import Recording

__all__ = [
    "FORMATS",
    "ColumnSpec",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "available_formats",
    "format_takes",
    "check_increasing",
    "check_nyquist",
    "detect_format",
    "find_gaps",
    "load_mapping",
    "parse_mapping",
    "read",
    "read_track",
    "register_format",
    "resample_uniform",
    "sort_dedup",
    "unread_sidecar_note",
    "split_at_gaps",
    "write",
    "write_track",
]


@dataclass(frozen=True)
class _Format:
    description: str
    reader: str | Callable[..., Recording]  # "module:function" (lazy) or the function
    detect: str | Callable[[Path], bool] | None = None
    module: str | None = None  # module whose presence makes the format available


def _entry(mod: str, read: str, detect: str | None, description: str) -> _Format:
    return _Format(description, f"{mod}:{read}", f"{mod}:{detect}" if detect else None, mod)


#: Built-in formats in auto-detection order (lazily imported). Another module's reader is listed
#: here by "module:function" and is offered only once the module exists.
_BUILTIN: dict[str, _Format] = {
    "sensorlogger": _entry("vibrospeed.io.sensorlogger", "read_sensorlogger", "detect",
                           "Sensor Logger app export: folder or .zip of TotalAcceleration/"
                           "Accelerometer/Gyroscope/Location.csv (time in ns)"),
    "phyphox": _entry("vibrospeed.io.phyphox", "read_phyphox", "is_phyphox",
                      "phyphox export: folder or .zip of Accelerometer/Gyroscope/Location.csv"),
    "rosbag": _entry("vibrospeed.io.rosbag", "read_rosbag", "detect",
                     "ROS 1 .bag or ROS 2 bag folder (needs rosbags): sensor_msgs/Imu, "
                     "Odometry, TwistStamped, NavSatFix; --topic chooses the IMU"),
    "gopro": _entry("vibrospeed.io.gopro", "read_gopro", "detect",
                    "GoPro MP4 telemetry (GPMF gpmd track): ACCL, GYRO, GPS5/GPS9 speed"),
    "parquet": _entry("vibrospeed.io.parquet", "read_parquet", None,
                      "Parquet with canonical columns (needs pyarrow)"),
    "sensorfusion": _entry("vibrospeed.io.sensorfusion", "read_sensorfusion", "is_sensorfusion",
                           "Sensor Fusion app log: 'timestamp_ms TAG values' lines (ACC, GYR...)"),
    "comma2k19": _entry("vibrospeed.io.comma2k19", "read_comma2k19", "detect",
                        "comma2k19 segment: phone IMU, GNSS and CAN wheel speeds"),
    "f1tenth": _entry("vibrospeed.io.f1tenth", "read_f1tenth", "detect",
                      "F1TENTH friction-map logs: IMU (g, deg/s), VESC odometry"),
    "androsensor": _entry("vibrospeed.io.androsensor", "read_androsensor", "detect",
                          "AndroSensor accel.<trip>.csv (+ gps.<trip>.csv beside it)"),
    "csv": _entry("vibrospeed.io.canonical", "read_csv", None,
                  "canonical CSV: header 't,ax,ay,...' in SI units (vibrospeed's own)"),
    "mapped": _entry("vibrospeed.io.mapped", "read_mapped", None,
                     "any CSV with a column mapping (--columns t=time,ay=acc_y or a TOML file)"),
}
_REGISTRY: dict[str, _Format] = dict(_BUILTIN)


def _available(f: _Format) -> bool:
    return f.module is None or importlib.util.find_spec(f.module) is not None


def available_formats() -> dict[str, str]:
    """Format name -> one-line description, for the formats installed in this build."""
    return {k: f.description for k, f in _REGISTRY.items() if _available(f)}


#: Format name -> one-line description (for the CLI help); kept current by register_format.
FORMATS: dict[str, str] = available_formats()


def register_format(
    name: str,
    reader: Callable[..., Recording],
    *,
    description: str,
    detect: Callable[[Path], bool] | None = None,
) -> None:
    """Make ``reader`` available as ``read(path, format=name)``; with ``detect`` it also takes
    part in auto-detection (before the generic CSV formats)."""
    fmt = _Format(description, reader, detect, None)
    items = [(k, v) for k, v in _REGISTRY.items() if k not in (name, "csv", "mapped")]
    _REGISTRY.clear()
    _REGISTRY.update(items)
    _REGISTRY[name] = fmt
    for k in ("csv", "mapped"):
        _REGISTRY[k] = _BUILTIN[k]
    FORMATS.clear()
    FORMATS.update(available_formats())


def format_takes(name: str, option: str) -> bool:
    """Whether the reader of format ``name`` takes the :func:`read` option ``option``
    (``columns``, ``mapping_file``, ``rate``, ``sort``, ``topic``, ``decimal``): e.g. only the
    ROS bags take ``topic``. :class:`ReaderError`-free: an unknown or unavailable format takes
    nothing."""
    f = _REGISTRY.get(name)
    if f is None or not _available(f):
        return False
    params = inspect.signature(_resolve(f.reader)).parameters
    return option in params or any(q.kind is inspect.Parameter.VAR_KEYWORD
                                   for q in params.values())


def _resolve(ref: str | Callable, *, optional: bool = False) -> Callable | None:
    if callable(ref):
        return ref
    mod, _, fn = ref.partition(":")
    found = getattr(importlib.import_module(mod), fn, None)
    if found is None and not optional:
        raise ParameterError(f"reader {ref} is declared but its module has no '{fn}'")
    return found


def _first_line(p: Path) -> str:
    """The first non-blank line of a text file (a gzip file's text), BOM left out."""
    import gzip
    import zlib

    from vibrospeed.io._csv import excel_sep, is_gzip

    try:
        with (gzip.open(p, "rt", encoding="utf-8", errors="replace", newline="") if is_gzip(p)
              else open(p, encoding="utf-8", errors="replace", newline="")) as fh:
            for _ in range(50):
                line = fh.readline()
                if not line:
                    return ""
                if line.strip() and excel_sep(line.lstrip("\ufeff")) is None:
                    return line.lstrip("\ufeff").strip()
    except (OSError, EOFError, zlib.error):
        return ""
    return ""


_TABLE_SUFFIXES = (".csv", ".tsv", ".csv.gz", ".tsv.gz")


def _header(q: Path) -> list[str]:
    """The column names of a delimited text file's first line (``[]`` if none)."""
    from vibrospeed.io._csv import sniff_delimiter

    first = _first_line(q)
    return [h.strip().strip('"').strip() for h in first.split(sniff_delimiter(first))] \
        if first else []


def _is_time_column(name: str) -> bool:
    low = name.lower()
    return low in ("t", "ts") or "time" in low or low.startswith("t_")


def mapping_example(header: Sequence[str]) -> str:
    """A ``--columns`` mapping for a CSV with these column names, to show in an error: a time
    column (``t``, ``*time*``, ``t_*``) as ``t``, one named for a speed or velocity as
    ``gps_speed``, the first three others as ``ax ay az`` (one alone as ``ay``), and
    ``--rate HZ`` where there is no time column; quoted for a shell where a name needs it, and
    a generic example where the names are not printable column names (a binary file)."""
    head = [h for h in header if h]
    if not head or not all(h.isprintable() and len(h) <= 40 and not set(h) & set(',=*:"')
                           for h in head):  # a binary file's "header": a generic example
        return "--columns t=time,ay=acc_y"
    time = next((h for h in head if _is_time_column(h)), None)
    speed = next((h for h in head if h != time and ("speed" in h.lower()
                                                     or "vel" in h.lower())), None)
    values = [h for h in head if h not in (time, speed)][:3]
    names = ("ax", "ay", "az") if len(values) > 1 else ("ay",)
    items = ([f"t={time}"] if time else []) + [f"{ch}={col}" for ch, col in zip(
        names, values, strict=False)] + ([f"gps_speed={speed}"] if speed else [])
    cols = ",".join(items)
    cols = f'"{cols}"' if any(c.isspace() or c in "()[]'&;|<>$`\\" for c in cols) else cols
    return f"--columns {cols}" + ("" if time else " --rate HZ")


def folder_hint(folder: str | os.PathLike[str]) -> str:
    """What to say about a folder that no reader takes as one recording (empty: nothing to add,
    the caller's own message): where files in it are recordings (canonical CSVs, AndroSensor
    trips, GoPro clips, ...), to give one of them or ``vibrospeed batch``; where it holds CSV
    files of another layout (the GoPro kart's ``GX030410_accl_raw.csv`` and
    ``GX030410_gps_speed.csv``), to give one file with a column mapping built from its header
    (one named for an accelerometer, ``acc*``, else the first), then the files with their
    headers."""
    from vibrospeed.io._common import NOT_RECORDING_SUFFIXES
    from vibrospeed.io._csv import _short
    from vibrospeed.io.androsensor import accel_of
    from vibrospeed.io.canonical import is_event_sidecar

    d = Path(folder)
    try:
        files = sorted(q for q in d.iterdir() if not q.name.startswith(".") and q.is_file()
                       and q.suffix.lower() not in NOT_RECORDING_SUFFIXES)
    except OSError:
        return ""
    found = []
    for q in files:
        if is_event_sidecar(q) or accel_of(q) is not None:  # a part of a recording beside it
            continue
        try:
            _detect_format(q, mapping=False, inside=False)
        except (ReaderError, OSError):
            continue
        found.append(q.name)
    if found:
        shown = ", ".join(found[:4]) + (", ..." if len(found) > 4 else "")
        return (f"a folder of {len(found)} recording(s) ({shown}), not one itself: give one "
                "of them, or `vibrospeed batch` for all")
    tables = [q for q in files if q.name.lower().endswith(_TABLE_SUFFIXES)]
    if not tables:
        return ""
    heads = {q: _header(q) for q in tables}
    pick = next((q for q in tables if "acc" in q.name.lower()), tables[0])
    listed = "; ".join(f"{q.name} ({_short(','.join(heads[q]), 40)})" for q in tables[:4])
    more = f"; ... ({len(tables)} CSV files)" if len(tables) > 4 else ""
    return (f"a folder of CSV files, not a recording format vibrospeed reads as one: give one "
            f"file with a column mapping, e.g. {pick} {mapping_example(heads[pick])} "
            f"(units ':g', scales '*K': docs/formats.md); it holds {listed}{more}")


_csv.folder_hint = folder_hint  # check_file's message for a folder given as a file


def unread_sidecar_note(path: str | os.PathLike[str]) -> str | None:
    """A note where a canonical CSV's ``<path>.json`` is there but not read: the reader takes
    only a sidecar with ``"kind": "recording"`` (what ``vibrospeed simulate`` and
    ``vibrospeed.io.write`` write), and one a user wrote by hand without it (a wheel radius for
    a batch's drive) would otherwise be ignored without a word. None where there is none, it
    is read, or the file is not a canonical CSV."""
    import json

    q = Path(f"{path}.json")
    if not q.is_file():
        return None
    try:
        side = json.loads(q.read_text(encoding="utf-8-sig"))
    except (OSError, ValueError):
        return None  # the reader names an unreadable sidecar itself
    if isinstance(side, dict) and side.get("kind") == "recording":
        return None
    try:
        if detect_format(path) != "csv":
            return None
    except Exception:  # noqa: BLE001 - it was read, so a format was found; this is a note
        return None
    kind = side.get("kind") if isinstance(side, dict) else None
    why = (f'its "kind" is {json.dumps(kind)}' if kind is not None
           else 'it has no "kind": "recording"' if isinstance(side, dict)
           else "it is not a JSON object")
    return (f'{q.name}: not read ({why}): add "kind": "recording" for its wheel_radius, units, '
            "axes and notes to be used")


def _recording_subfolders(folder: Path) -> list[Path]:
    """The subfolders of ``folder`` (one level, hidden ones left out) that are recordings."""
    out = []
    try:
        subs = sorted(q for q in folder.iterdir() if q.is_dir() and not q.name.startswith("."))
    except OSError:
        return []
    for q in subs:
        try:
            _detect_format(q, mapping=False, inside=False)
        except (ReaderError, OSError):
            continue
        out.append(q)
    return out


def detect_format(path: str | os.PathLike[str], *, mapping: bool = False) -> str:
    """Name of the format of ``path`` (see :func:`read`); ``mapping``: a column mapping was
    given, so a non-canonical CSV is read through it. A folder that is no recording but holds
    recordings (a folder of phyphox exports) is an error naming them."""
    return _detect_format(Path(path), mapping=mapping, inside=True)


def _detect_format(p: Path, *, mapping: bool, inside: bool) -> str:
    """:func:`detect_format`; ``inside``: look one level into a folder for the error message."""
    if not p.exists():
        from vibrospeed.io._csv import not_found

        raise ReaderError(p, not_found(p))
    if mapping:
        return "mapped"
    for name, f in _REGISTRY.items():
        if name in ("csv", "mapped", "parquet") or f.detect is None or not _available(f):
            continue
        detect = _resolve(f.detect, optional=True)  # a module may offer no detector
        if detect is not None and detect(p):
            return name
    if p.is_dir():
        inner = _recording_subfolders(p) if inside else []
        if len(inner) == 1:  # e.g. one export beside other drives' files (export_folders)
            raise ReaderError(p, f"a folder holding the recording {inner[0].name}, not one "
                                 f"itself: give {inner[0].name}, or `vibrospeed batch` for all")
        if inner:
            shown = ", ".join(q.name for q in inner[:4]) + (", ..." if len(inner) > 4 else "")
            raise ReaderError(p, f"a folder of {len(inner)} recordings ({shown}), not one: give "
                                 "one of them, or `vibrospeed batch` for all")
        hint = folder_hint(p)
        if hint:
            raise ReaderError(p, hint)
        raise ReaderError(p, "unknown format: a folder that is not a phyphox export "
                             f"(no Accelerometer.csv); give --format ({', '.join(FORMATS)})")
    if p.stat().st_size == 0:
        raise ReaderError(p, "empty file")
    with open(p, "rb") as fh:
        magic = fh.read(4)
    if is_parquet(p) or p.suffix.lower() in (".parquet", ".pq"):
        return "parquet"
    if zipfile.is_zipfile(p):
        raise ReaderError(p, "unknown format: a zip file without Accelerometer.csv")
    if magic[:2] == b"PK":  # a zip's signature, yet no zip zipfile can read
        try:
            zipfile.ZipFile(p).close()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as exc:
            raise ReaderError(p, f"not a valid zip file ({exc}): truncated or damaged? "
                                 "(a phyphox or Sensor Logger export zips a folder of CSV "
                                 "files)") from None
    first = _first_line(p)
    if not first:
        raise ReaderError(p, "empty file (no header row)")
    from vibrospeed.io._csv import _short, sniff_delimiter

    delim = sniff_delimiter(first)
    head = [h.strip().strip('"').strip() for h in first.split(delim)]
    if head and head[0] == "t":
        return "csv"
    raise ReaderError(
        p,
        f"unknown format (header starts '{_short(first, 40)}'): give --format "
        f"({', '.join(FORMATS)}) or a column mapping such as {mapping_example(head)}",
        row=1,
    )


def read(
    path: str | os.PathLike[str],
    format: str = "auto",  # noqa: A002 - the CLI's word
    *,
    columns: str | None = None,
    mapping_file: str | os.PathLike[str] | None = None,
    rate: float | None = None,
    sort: bool = False,
    resample: bool | float | None = None,
    require: Sequence[str] = (),
    topic: str | None = None,
    decimal: str | None = None,
) -> Recording:
    """Read a recording in any supported format.

    Parameters
    ----------
    path : file, folder (phyphox) or zip
    format : a key of :data:`FORMATS` or ``"auto"``: folder/zip with Accelerometer.csv ->
        phyphox; ``.parquet`` or PAR1 magic -> parquet; ``<number> <TAG> ...`` lines ->
        sensorfusion; a header starting with ``t`` -> csv; with ``columns``/``mapping_file``/
        ``rate`` -> mapped; otherwise a :class:`ReaderError` asking for a mapping
    columns : column mapping ``"t=time,ay=acc_y"`` (mapped format)
    mapping_file : TOML mapping file (mapped format)
    rate : Hz, sample rate of a file without time column (mapped format)
    sort : sort by time and drop repeated timestamps instead of refusing time going backwards
    resample : ``True`` -> uniform grid at the median rate, a number -> that rate in Hz (linear
        interpolation, :func:`resample_uniform`); ``None``/``False`` -> keep the file's times
    require : channel names that must be present and not all NaN
    topic : ROS bags: the IMU topic to read (or a comma list of topics), see :mod:`.rosbag`
    decimal : a CSV's decimal mark, ``"."`` or ``","`` (``1,5`` in a ``;``-separated export;
        csv and mapped formats); None: ``.`` or the mapping file's. Never guessed

    Returns
    -------
    Recording in SI units with canonical channel names; ``notes`` says what was done.
    """
    p = Path(path)
    mapping = columns is not None or mapping_file is not None or rate is not None
    name = detect_format(p, mapping=mapping) if format == "auto" else format
    if name not in _REGISTRY or not _available(_REGISTRY[name]):
        raise ReaderError(p, f"unknown format '{name}' (choose from: auto, {', '.join(FORMATS)})")
    reader = _resolve(_REGISTRY[name].reader)
    opts: dict[str, Any] = {"columns": columns, "mapping_file": mapping_file, "rate": rate,
                            "sort": sort, "topic": topic, "decimal": decimal}
    kwargs = {}
    for k, v in opts.items():
        if format_takes(name, k):
            kwargs[k] = v
        elif v not in (None, False):
            raise ParameterError(f"{p}: format '{name}' does not take option '{k}'")
    rec = reader(p, **kwargs)
    if require:
        try:
            rec.require(*require)
        except ReaderError:
            raise
        except ValueError as exc:  # InputError from Recording: re-raise as a reader error
            msg = str(exc).split(": ", 1)[-1]
            raise ReaderError(p, msg, column=next(
                (c for c in require if f"'{c}'" in msg), None)) from None
    if resample not in (None, False):
        fs = None if resample is True else float(resample)
        rec = resample_uniform(rec, fs)
    return rec


def write(rec: Recording, path: str | os.PathLike[str], format: str = "auto") -> None:  # noqa: A002
    """Write ``rec``: Parquet for ``.parquet``/``.pq`` (or ``format="parquet"``), else canonical
    CSV with sidecars. Atomic."""
    p = Path(path)
    if format == "auto":
        format = "parquet" if p.suffix.lower() in (".parquet", ".pq") else "csv"
    if format == "parquet":
        from vibrospeed.io.parquet import write_parquet

        write_parquet(rec, p)
    elif format == "csv":
        from vibrospeed.io.canonical import write_csv

        write_csv(rec, p)
    else:
        raise ParameterError(f"{p}: cannot write format '{format}' (choose csv or parquet)")
