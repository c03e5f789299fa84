"""What a batch reads and writes where: files, folders (one that is itself a recording, or its
recordings) and glob patterns expanded to recordings, with an error row for an item that
names none (:func:`expand_inputs`); one stable output base name per recording
(:func:`output_names`)."""

from __future__ import annotations

import glob
import hashlib
import itertools
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

# files in a folder that are never recordings (outputs, sidecars, notes): the readers' own list
from vibrospeed.io._common import NOT_RECORDING_SUFFIXES as _NOT_RECORDINGS


def _is_recording_dir(p: Path) -> bool:
    from vibrospeed import io

    try:
        io.detect_format(p)
    except Exception:  # noqa: BLE001 - not a recording (or a reader's detector failed on it)
        return False
    return True


def _inside(p: Path, folder: Path) -> bool:
    """``p`` is ``folder`` or under it, symbolic links followed (``os.path.realpath``: a link
    loop, which ``Path.resolve`` raises on, stays a path and is not inside)."""
    folder_real = os.path.realpath(folder)
    real = os.path.realpath(p)
    return real == folder_real or real.startswith(folder_real.rstrip(os.sep) + os.sep)


def _not_a_recording(q: Path) -> bool:
    """Hidden and temporary files, sidecars, images, notes, and a file that another recording
    beside it reads as a part of it: a canonical CSV's event streams (``drive.wss_ticks.csv``
    beside ``drive.csv``), an AndroSensor trip's ``gps.<trip>.csv`` (beside its
    ``accel.<trip>.csv``)."""
    from vibrospeed.io.androsensor import accel_of
    from vibrospeed.io.canonical import is_event_sidecar

    if q.name.startswith(".") or ".tmp" in q.name or q.suffix.lower() in _NOT_RECORDINGS:
        return True
    return is_event_sidecar(q) or accel_of(q) is not None


def _folder_entries(folder: Path, exclude: Path | None) -> list[Path]:
    out = []
    for q in sorted(folder.iterdir()):
        if exclude is not None and _inside(q, exclude):
            continue
        if q.is_dir():
            if not q.name.startswith(".") and _is_recording_dir(q):
                out.append(q)
        elif not _not_a_recording(q):
            out.append(q)
    return out


def _glob_base(pattern: str) -> Path:
    """The leading folders of ``pattern`` without a wildcard (``logs`` for ``logs/**/*.csv``)."""
    parts = Path(pattern).parts
    fixed = list(itertools.takewhile(lambda c: not glob.has_magic(c), parts[:-1]))
    return Path(*fixed) if fixed else Path(".")


def _recordings_matched(matches: list[Path], base: Path) -> list[Path]:
    """The recordings among a pattern's ``matches`` (all at or below the pattern's fixed
    ``base``): a recording folder, or the one it is a part of; a file, unless it is a part of
    a recording folder at or below ``base``, matched or not (a phyphox export's
    ``Accelerometer.csv``, which its reader reads as the whole export: it stands for that
    folder, the outermost where one holds the other, so ``logs/**/*.csv`` and ``logs/**``
    estimate each export once, not once per CSV in it) or not a recording at all; nothing
    that ``**`` found through a symbolic link back to a folder above it (a link loop, which
    :func:`glob.glob` follows some 40 levels deep)."""
    is_rec: dict[Path, bool] = {}
    looped: dict[Path, bool] = {}

    def rec_dir(d: Path) -> bool:
        if d not in is_rec:
            is_rec[d] = _is_recording_dir(d)
        return is_rec[d]

    top = base.parts  # () for "."

    def below(d: Path) -> list[Path]:  # d and its parents down to base, base excluded
        parts = d.parts
        if parts[:len(top)] != top:
            return []
        return [Path(*parts[:k]) for k in range(len(parts), len(top), -1)]

    def loops(d: Path) -> bool:  # a link on the way from base to d points back up
        if d not in looped:
            if d.parts[:len(top)] != top or len(d.parts) <= len(top):
                looped[d] = False  # base itself, or not below it
            elif loops(d.parent):
                looped[d] = True
            else:
                real = os.path.realpath(d).rstrip(os.sep) + os.sep
                looped[d] = d.is_symlink() and (os.path.realpath(d.parent).rstrip(os.sep)
                                                + os.sep).startswith(real)
        return looped[d]

    out = []
    for q in matches:
        if loops(q.parent) or loops(q):
            continue
        is_dir = q.is_dir()
        if not (is_dir or q.is_file()):
            continue
        # the outermost recording folder it is (a folder) or is a part of, at or below base:
        # an export unpacked into a folder of its own is that folder, as in a folder listing
        inner = below(q) if is_dir else below(q)[1:]
        folder = next((a for a in [base, *reversed(inner)] if rec_dir(a)), None)
        if folder is not None:
            out.append(folder)
        elif not is_dir and not _not_a_recording(q):
            out.append(q)
    return out


def expand_inputs(items: Iterable[str | os.PathLike[str]], *,
                  exclude: str | os.PathLike[str] | None = None) -> list[tuple[str, str | None]]:
    """Recordings named by files, folders and glob patterns, in the order given.

    A folder that is itself a recording (a phyphox export, a comma2k19 segment ...) is one
    input; any other folder stands for its files and recording subfolders (not recursive; hidden
    files, sidecars, images, HTML and anything under ``exclude`` left out); a pattern (``*``,
    ``?``, ``[...]``, ``**``) for the files and recording folders it matches (a file inside a
    recording folder stands for the folder: :func:`_recordings_matched`). A file named
    explicitly is always an input. Returns ``(path, None)`` per recording and ``(item, error)``
    for an item that names nothing, so that a batch can report it as a row.
    """
    excl = Path(exclude) if exclude is not None else None
    found: list[tuple[str, str | None]] = []
    seen: set[str] = set()

    def add(p: Path) -> None:
        key = os.path.realpath(p)
        if key not in seen:
            seen.add(key)
            found.append((os.fspath(p), None))

    for item in items:
        s = os.fspath(item)
        p = Path(s)
        if p.exists():
            if p.is_dir() and not _is_recording_dir(p):
                entries = _folder_entries(p, excl)
                if not entries:
                    found.append((s, "no recording in this folder"))
                for q in entries:
                    add(q)
            else:
                add(p)
        elif glob.has_magic(s):
            matches = [Path(m) for m in sorted(glob.glob(s, recursive=True))]
            matches = [q for q in matches if excl is None or not _inside(q, excl)]
            matches = _recordings_matched(matches, _glob_base(s))
            if not matches:
                found.append((s, "no recording matches this pattern"))
            for q in matches:
                add(q)
        else:
            from vibrospeed.io._csv import not_found

            found.append((s, not_found(p)))
    return found


def _stem(p: Path) -> str:
    """The output base name of input ``p``: a folder's name, a file's name without its suffix
    and without a compression suffix before it (``a.csv.gz`` -> ``a``, as ``a.csv``)."""
    from vibrospeed.io.canonical import uncompressed

    name = p.name if p.is_dir() else uncompressed(p).stem
    safe = "".join(c if c.isalnum() or c in "-_.+" else "_" for c in name).strip(".")
    return safe or "recording"


def output_names(inputs: Sequence[str | os.PathLike[str]]) -> list[str]:
    """A unique output base name per input: its file name without suffix (and without ``.gz``,
    :func:`_stem`; a folder's name for a folder); inputs that share one get ``-<8 hex digits of
    their absolute path>`` added, so a name stays the same from one run to the next."""
    stems = [_stem(Path(p)) for p in inputs]
    count: dict[str, int] = {}
    for s in stems:
        count[s.lower()] = count.get(s.lower(), 0) + 1
    out = []
    for p, s in zip(inputs, stems, strict=True):
        if count[s.lower()] > 1:
            h = hashlib.sha256(os.path.abspath(os.fspath(p)).encode()).hexdigest()[:8]
            s = f"{s}-{h}"
        out.append(s)
    return out
