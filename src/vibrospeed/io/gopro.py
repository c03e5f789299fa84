# Over 500 lines: a self-contained MP4 box walker and GPMF parser (no ffmpeg), bounded on any
# input; the format's rules and their checks stay together.
"""GoPro MP4 telemetry (GPMF in the ``gpmd`` metadata track, HERO5 and later), read by a small
self-contained parser: no ffmpeg, no compiled code, bounded work on any input.

What is read
------------
The MP4 box tree is walked to the track whose sample description is ``gpmd``; its sample table
(``stsz``, ``stsc``, ``stco`` / ``co64``, ``stts``, ``mdhd`` time scale) gives each payload's file
offset, size and time span. Each payload is a GPMF KLV stream (4-byte FourCC key, 1-byte type,
1-byte struct size, 2-byte repeat count, big-endian, data padded to 4 bytes; type 0 = nested
``DEVC`` / ``STRM``). In each ``STRM`` the sticky ``SCAL`` divides the values, ``ORIN`` (HERO8+)
names the camera axis of each column, ``TYPE`` describes complex structures (GPS9).

=======  =====================================  =========================================
key      content                                vibrospeed channels
=======  =====================================  =========================================
ACCL     3-axis accelerometer, m/s^2 after SCAL ``ax ay az`` (camera X Y Z by ORIN; without
         (~200 Hz)                              ORIN the stored order, noted). **Master
                                                time line.**
GYRO     3-axis gyroscope, rad/s after SCAL     ``gx gy gz``, interpolated onto ACCL times
GPS5     lat, lon, alt, speed2d, speed3d        ``gps_speed`` (speed2d, m/s), ``gps_lat
         (~18 Hz); GPSF fix 0/2/3 per payload   gps_lon gps_alt``; NaN without a 2D/3D fix
GPS9     GPS5 fields + days, secs, DOP, fix     the same (fix per sample), HERO11+ (10 Hz)
=======  =====================================  =========================================

Time: a sensor's samples are counted over the payloads and a uniform rate is fitted (least
squares) to the payloads' start times -- the camera's own clock runs smoothly while the number of
samples per 1 s payload varies by one or two -- so ``t_k = t_0 + k / rate`` (the note gives the
rate and the largest payload misfit). GPS fixes are spread evenly inside their payload and placed
once at the nearest ACCL sample (NaN elsewhere), fix times in event ``gps_fix``. ``t = 0`` is the
start of the video.

Every inconsistency (box sizes past the end of the file, sample tables that disagree, a KLV
item longer than its container, more than :data:`MAX_SAMPLES` samples) is a one-line
:class:`~vibrospeed.errors.ReaderError` naming the file and what is wrong.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import finish
from vibrospeed.io.timebase import interp_onto, nearest_index
from vibrospeed.types import Recording

__all__ = ["GpmfError", "Klv", "detect", "iter_klv", "parse_streams", "read_gopro",
           "read_gpmd_track"]

MAX_SAMPLES = 10_000_000  # per sensor (~14 h of 200 Hz ACCL)
MAX_PAYLOAD = 64 * 1024**2
MAX_MOOV = 256 * 1024**2
MAX_DEPTH = 8
_CONTAINERS = {b"moov", b"trak", b"mdia", b"minf", b"stbl", b"edts", b"dinf"}
# GPMF type char -> (struct code, bytes)
_TYPES = {"b": ("b", 1), "B": ("B", 1), "c": ("c", 1), "s": ("h", 2), "S": ("H", 2),
          "l": ("i", 4), "L": ("I", 4), "f": ("f", 4), "d": ("d", 8), "j": ("q", 8),
          "J": ("Q", 8), "q": ("i", 4), "Q": ("q", 8), "F": ("4s", 4), "G": ("16s", 16),
          "U": ("16s", 16)}
_FIXED = {"q": 65536.0, "Q": 4294967296.0}  # Q15.16 and Q31.32 fixed point


class GpmfError(ValueError):
    """Malformed GPMF or MP4 structure (turned into a ReaderError naming the file)."""


@dataclass
class Klv:
    """One GPMF item: key, type char (``"\\0"`` = nested), struct size, repeat, raw data."""

    key: str
    type: str
    size: int
    repeat: int
    data: bytes
    children: list[Klv] = field(default_factory=list)


def iter_klv(buf: bytes, depth: int = 0) -> list[Klv]:
    """Parse a GPMF byte stream into a tree of :class:`Klv` items; :class:`GpmfError` on any
    inconsistency. Trailing zero padding is accepted."""
    if depth > MAX_DEPTH:
        raise GpmfError(f"GPMF nesting deeper than {MAX_DEPTH}")
    out: list[Klv] = []
    pos, n = 0, len(buf)
    while pos + 8 <= n:
        head = buf[pos:pos + 8]
        if head == b"\0" * 8:  # padding
            pos += 8
            continue
        key = head[:4]
        if not all(48 <= c <= 57 or 65 <= c <= 90 or 97 <= c <= 122 or c == 32 for c in key):
            raise GpmfError(f"bad GPMF key {key!r} at byte {pos}")
        typ, size, repeat = chr(head[4]), head[5], struct.unpack(">H", head[6:8])[0]
        length = size * repeat
        end = pos + 8 + length
        if end > n:
            raise GpmfError(f"GPMF item {key.decode()} ({length} bytes) runs past its container "
                            f"at byte {pos}")
        data = buf[pos + 8:end]
        item = Klv(key.decode(), typ, size, repeat, data)
        if typ == "\0":
            item.children = iter_klv(data, depth + 1)
        out.append(item)
        pos = pos + 8 + ((length + 3) & ~3)
    if pos < n and buf[pos:].strip(b"\0"):
        raise GpmfError(f"{n - pos} stray byte(s) at the end of a GPMF container")
    return out


def _values(item: Klv, typedef: str | None = None) -> np.ndarray:
    """Data of a KLV item as a (repeat, elements) float array (strings and fourccs refused)."""
    if item.type == "?":
        if not typedef:
            raise GpmfError(f"{item.key}: complex type without a TYPE definition")
        codes = typedef
    else:
        codes = item.type
    fmt, width = "", 0
    for c in codes:
        if c not in _TYPES or c in "cFGU":
            raise GpmfError(f"{item.key}: type {c!r} is not numeric")
        fmt += _TYPES[c][0]
        width += _TYPES[c][1]
    if item.type != "?":
        if item.size % width:
            raise GpmfError(f"{item.key}: struct size {item.size} is not a multiple of "
                            f"{width} ({item.type!r})")
        fmt *= item.size // width
        width = item.size
    elif item.size != width:
        raise GpmfError(f"{item.key}: struct size {item.size} differs from its TYPE "
                        f"{typedef!r} ({width} bytes)")
    vals = np.array(list(struct.iter_unpack(">" + fmt, item.data)), dtype=np.float64)
    vals = vals.reshape(item.repeat, len(fmt.replace("4s", "F").replace("16s", "G")))
    for j, c in enumerate(codes if item.type == "?" else codes * (vals.shape[1] // len(codes))):
        if c in _FIXED:
            vals[:, j] /= _FIXED[c]
    return vals


def _text(item: Klv) -> str:
    return item.data.split(b"\0", 1)[0].decode("latin-1")


@dataclass
class Stream:
    """Samples of one sensor over all payloads."""

    key: str
    chunks: list[np.ndarray] = field(default_factory=list)  # per payload, scaled
    payload: list[int] = field(default_factory=list)  # payload index of each chunk
    orin: str | None = None
    fix: list[np.ndarray] = field(default_factory=list)  # GPS fix per chunk (GPS5: GPSF)
    name: str = ""


def parse_streams(payloads: list[bytes], keys=("ACCL", "GYRO", "GPS5", "GPS9")) -> dict:
    """Scaled samples of the ``keys`` sensors from GPMF payloads: key -> :class:`Stream`."""
    out: dict[str, Stream] = {}
    total: dict[str, int] = {}
    for i, buf in enumerate(payloads):
        for devc in iter_klv(buf):
            if devc.key != "DEVC":
                continue
            for strm in devc.children:
                if strm.key != "STRM":
                    continue
                _stream(strm, i, keys, out, total)
    return out


def _stream(strm: Klv, i: int, keys, out: dict, total: dict) -> None:
    scal: np.ndarray | None = None
    typedef = orin = None
    gpsf = None
    name = ""
    for it in strm.children:
        if it.key == "SCAL":
            scal = _values(it).ravel()
        elif it.key == "TYPE":
            typedef = _text(it)
        elif it.key == "ORIN":
            orin = _text(it)
        elif it.key == "STNM":
            name = _text(it)
        elif it.key == "GPSF":
            gpsf = float(_values(it).ravel()[0])
        elif it.key in keys:
            vals = _values(it, typedef)
            if scal is not None:
                if scal.size not in (1, vals.shape[1]):
                    raise GpmfError(f"{it.key}: SCAL has {scal.size} values for "
                                    f"{vals.shape[1]} columns")
                if np.any(scal == 0):
                    raise GpmfError(f"{it.key}: SCAL is zero")
                vals = vals / scal
            total[it.key] = total.get(it.key, 0) + vals.shape[0]
            if total[it.key] > MAX_SAMPLES:
                raise GpmfError(f"more than {MAX_SAMPLES} {it.key} samples")
            s = out.setdefault(it.key, Stream(it.key))
            if s.chunks and s.chunks[0].shape[1] != vals.shape[1]:
                raise GpmfError(f"{it.key}: column count changes between payloads")
            s.chunks.append(vals)
            s.payload.append(i)
            s.orin = orin or s.orin
            s.name = name or s.name
            if it.key == "GPS5":
                s.fix.append(np.full(vals.shape[0], np.nan if gpsf is None else gpsf))
            elif it.key == "GPS9" and vals.shape[1] >= 9:
                s.fix.append(vals[:, 8] * (scal[8] if scal is not None and scal.size > 8 else 1))


# ---- MP4 ------------------------------------------------------------------------------------
def _boxes(f, start: int, end: int, fsize: int):
    """(type, payload start, payload end) of the boxes in [start, end)."""
    pos = start
    while pos + 8 <= end:
        f.seek(pos)
        head = f.read(8)
        if len(head) < 8:
            raise GpmfError(f"truncated box header at byte {pos}")
        size, typ = struct.unpack(">I4s", head)
        hdr = 8
        if size == 1:
            ext = f.read(8)
            if len(ext) < 8:
                raise GpmfError(f"truncated box header at byte {pos}")
            size, hdr = struct.unpack(">Q", ext)[0], 16
        elif size == 0:
            size = end - pos
        if size < hdr or pos + size > end:
            raise GpmfError(f"box {typ.decode('latin-1')!r} at byte {pos} has size {size}, past "
                            f"the end of its container ({end})")
        yield typ, pos + hdr, pos + size
        pos += size


def _read_box(f, a: int, b: int, limit: int = MAX_MOOV) -> bytes:
    if b - a > limit:
        raise GpmfError(f"metadata box of {b - a} bytes (limit {limit})")
    f.seek(a)
    data = f.read(b - a)
    if len(data) != b - a:
        raise GpmfError("file ends inside a box")
    return data


def _table(data: bytes, entry: str, name: str, skip: int = 0) -> np.ndarray:
    """Full-box table: version/flags, [skip bytes], count, then count entries of ``entry``."""
    if len(data) < 8 + skip:
        raise GpmfError(f"{name} box too short")
    count = struct.unpack(">I", data[4 + skip:8 + skip])[0]
    width = struct.calcsize(">" + entry)
    if 8 + skip + count * width > len(data):
        raise GpmfError(f"{name} declares {count} entries, more than its {len(data)} bytes hold")
    return np.array(list(struct.iter_unpack(">" + entry, data[8 + skip:8 + skip + count * width])),
                    dtype=np.int64).reshape(count, len(entry))


def _gpmd_trak(f, a: int, b: int, fsize: int) -> dict | None:
    boxes: dict[bytes, bytes] = {}

    def walk(a, b, depth):
        if depth > MAX_DEPTH:
            raise GpmfError("MP4 boxes nested too deeply")
        for typ, pa, pb in _boxes(f, a, b, fsize):
            if typ in _CONTAINERS:
                walk(pa, pb, depth + 1)
            elif typ in (b"hdlr", b"mdhd", b"stsd", b"stts", b"stsz", b"stsc", b"stco", b"co64"):
                boxes.setdefault(typ, _read_box(f, pa, pb))

    walk(a, b, 1)
    stsd = boxes.get(b"stsd", b"")
    if len(stsd) < 16 or stsd[12:16] != b"gpmd":
        return None
    return boxes


def read_gpmd_track(path: str | os.PathLike[str]) -> tuple[list[bytes], np.ndarray, np.ndarray]:
    """Payloads of the ``gpmd`` track of an MP4, with each payload's start and end time (s)."""
    p = Path(path)
    fsize = p.stat().st_size
    with open(p, "rb") as f:
        moov = next(((a, b) for typ, a, b in _boxes(f, 0, fsize, fsize) if typ == b"moov"), None)
        if moov is None:
            raise GpmfError("no 'moov' box (not an MP4, or the recording was cut off)")
        trak = None
        for typ, a, b in _boxes(f, moov[0], moov[1], fsize):
            if typ == b"trak":
                trak = _gpmd_trak(f, a, b, fsize)
                if trak is not None:
                    break
        if trak is None:
            raise GpmfError("no GPMF telemetry track ('gpmd') in this MP4")
        for k in (b"mdhd", b"stts", b"stsz", b"stsc"):
            if k not in trak:
                raise GpmfError(f"gpmd track has no '{k.decode()}' box")
        mdhd = trak[b"mdhd"]
        if not mdhd:
            raise GpmfError("empty mdhd box")
        off = 20 if mdhd[0] == 1 else 12
        if len(mdhd) < off + 4:
            raise GpmfError("mdhd box too short")
        timescale = struct.unpack(">I", mdhd[off:off + 4])[0]
        if timescale == 0:
            raise GpmfError("mdhd time scale is 0")
        stsz = trak[b"stsz"]
        if len(stsz) < 12:
            raise GpmfError("stsz box too short")
        uniform, count = struct.unpack(">II", stsz[4:12])
        if count > min(MAX_SAMPLES, fsize // 8):
            raise GpmfError(f"stsz declares {count} samples, more than a {fsize}-byte file holds")
        if uniform:
            sizes = np.full(count, uniform, dtype=np.int64)
        else:
            sizes = _table(stsz, "I", "stsz", skip=4)[:, 0]
            if sizes.size != count:
                raise GpmfError("stsz is inconsistent")
        if b"stco" in trak:
            chunks = _table(trak[b"stco"], "I", "stco")[:, 0]
        elif b"co64" in trak:
            chunks = _table(trak[b"co64"], "Q", "co64")[:, 0]
        else:
            raise GpmfError("gpmd track has no chunk offsets (stco/co64)")
        stsc = _table(trak[b"stsc"], "III", "stsc")
        offsets = _sample_offsets(stsc, chunks, sizes)
        stts = _table(trak[b"stts"], "II", "stts")
        if stts[:, 0].sum() < count:
            raise GpmfError("stts covers fewer samples than stsz")
        left = np.maximum(count - np.concatenate([[0], np.cumsum(stts[:, 0])[:-1]]), 0)
        deltas = np.repeat(stts[:, 1], np.minimum(stts[:, 0], left))  # never more than count
        ends = np.cumsum(deltas) / timescale
        starts = np.concatenate([[0.0], ends[:-1]])
        if int(sizes.sum()) > fsize or np.any(sizes < 8):
            raise GpmfError("gpmd sample sizes add up to more than the file (or a sample is "
                            "shorter than one GPMF item)")
        payloads = []
        for o, s in zip(offsets.tolist(), sizes.tolist(), strict=True):
            if s > MAX_PAYLOAD or o + s > fsize:
                raise GpmfError(f"gpmd sample at byte {o} ({s} bytes) lies past the end of the "
                                "file (cut off?)")
            f.seek(o)
            payloads.append(f.read(s))
    return payloads, starts, ends


def _sample_offsets(stsc: np.ndarray, chunks: np.ndarray, sizes: np.ndarray) -> np.ndarray:
    nchunk = chunks.size
    per_chunk = np.zeros(nchunk, dtype=np.int64)
    if stsc.size == 0 or stsc[0, 0] != 1:
        raise GpmfError("stsc must start at chunk 1")
    if nchunk > sizes.size or stsc.shape[0] > nchunk:
        raise GpmfError(f"{nchunk} chunks and {stsc.shape[0]} stsc runs for {sizes.size} samples")
    for k in range(stsc.shape[0]):
        first = int(stsc[k, 0]) - 1
        last = int(stsc[k + 1, 0]) - 1 if k + 1 < stsc.shape[0] else nchunk
        if not 0 <= first < last <= nchunk or stsc[k, 1] > MAX_SAMPLES:
            raise GpmfError("stsc chunk runs are inconsistent")
        per_chunk[first:last] = stsc[k, 1]
    if per_chunk.sum() != sizes.size:
        raise GpmfError(f"stsc maps {int(per_chunk.sum())} samples, stsz has {sizes.size}")
    chunk_of = np.repeat(np.arange(nchunk), per_chunk)
    first_in_chunk = np.concatenate([[0], np.cumsum(per_chunk)[:-1]])
    csum = np.concatenate([[0], np.cumsum(sizes)])
    within = csum[:-1] - csum[first_in_chunk[chunk_of]]
    return chunks[chunk_of] + within


# ---- recording ------------------------------------------------------------------------------
def detect(path: str | os.PathLike[str]) -> bool:
    """True for an MP4 / MOV-like file (``ftyp`` box first) named ``.mp4``/``.mov``/``.360``.
    Never raises."""
    p = Path(path)
    try:
        if not p.is_file() or p.suffix.lower() not in (".mp4", ".mov", ".360", ".lrv"):
            return False
        with open(p, "rb") as fh:
            head = fh.read(12)
        return len(head) == 12 and head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"wide")
    except OSError:
        return False


def _timeline(s: Stream, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, str]:
    """Uniform sample times fitted to the payload start times (see the module docstring)."""
    counts = np.array([c.shape[0] for c in s.chunks], dtype=np.float64)
    n = int(counts.sum())
    pidx = np.asarray(s.payload)
    cum = np.concatenate([[0.0], np.cumsum(counts)])
    tt = np.concatenate([starts[pidx], [ends[pidx[-1]]]])
    if tt.size >= 3 and np.ptp(tt) > 0:
        A = np.column_stack([cum, np.ones_like(cum)])
        (period, t0), *_ = np.linalg.lstsq(A, tt, rcond=None)
    else:
        period = (tt[-1] - tt[0]) / max(n, 1)
        t0 = tt[0]
    if not np.isfinite(period) or period <= 0:
        raise GpmfError(f"{s.key}: cannot fit a sample rate to the payload times")
    misfit = float(np.max(np.abs(cum * period + t0 - tt)))
    t = t0 + np.arange(n) * period
    return t, (f"{s.key}: {n} samples in {len(s.chunks)} payloads, uniform {1 / period:.6g} Hz "
               f"fitted to the payload times (largest payload misfit {misfit * 1e3:.3g} ms)")


def _axes(s: Stream, vals: np.ndarray, notes: list[str]) -> np.ndarray:
    """Columns reordered to camera X, Y, Z by ORIN (lowercase letter = negative axis)."""
    o = s.orin
    if not o or len(o) != 3 or sorted(o.upper()) != ["X", "Y", "Z"]:
        notes.append(f"{s.key}: no ORIN axis string: columns kept in stored order (GoPro docs: "
                     "HERO5 Z,X,Y; HERO6/7 Y,-X,Z)")
        return vals
    out = np.empty_like(vals)
    for j, c in enumerate(o):
        out[:, "XYZ".index(c.upper())] = vals[:, j] * (1.0 if c.isupper() else -1.0)
    notes.append(f"{s.key}: ORIN {o}: columns mapped to camera X, Y, Z")
    return out


def read_gopro(path: str | os.PathLike[str], *, sort: bool = False) -> Recording:
    """Read the GPMF telemetry of a GoPro MP4 onto the accelerometer's time line.

    Parameters
    ----------
    path : the MP4 (a chaptered recording's parts are separate files)
    sort : accepted for interface symmetry (GPMF time is always increasing)
    """
    p = Path(path)
    if not p.exists():
        raise ReaderError(p, "file not found")
    if p.is_dir():
        raise ReaderError(p, "is a folder, not an MP4 file")
    try:
        payloads, starts, ends = read_gpmd_track(p)
        streams = parse_streams(payloads)
        return _recording(p, streams, starts, ends)
    except GpmfError as exc:
        raise ReaderError(p, f"bad GoPro telemetry: {exc}") from None
    except (OSError, struct.error, ValueError, OverflowError, MemoryError) as exc:
        if isinstance(exc, ReaderError):
            raise
        raise ReaderError(p, f"bad GoPro telemetry ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:160]})") from None


def _recording(p: Path, streams: dict, starts: np.ndarray, ends: np.ndarray) -> Recording:
    if "ACCL" not in streams:
        raise GpmfError(f"no ACCL (accelerometer) stream in {len(starts)} GPMF payloads")
    notes: list[str] = []
    acc = streams["ACCL"]
    vals = np.concatenate(acc.chunks)
    if vals.shape[1] != 3:
        raise GpmfError(f"ACCL has {vals.shape[1]} columns, expected 3")
    t, note = _timeline(acc, starts, ends)
    notes.append(note + "; master time line")
    vals = _axes(acc, vals, notes)
    chans = {"ax": vals[:, 0], "ay": vals[:, 1], "az": vals[:, 2]}
    units: dict[str, str] = {}
    if "GYRO" in streams:
        g = streams["GYRO"]
        gv = np.concatenate(g.chunks)
        if gv.shape[1] == 3 and gv.shape[0] >= 2:
            tg, gnote = _timeline(g, starts, ends)
            gv = _axes(g, gv, notes)
            dt = float(np.median(np.diff(tg)))
            for j, k in enumerate(("gx", "gy", "gz")):
                chans[k] = interp_onto(tg, gv[:, j], t, 5 * dt)
                units[k] = "rad/s"
            notes.append(gnote + "; linearly interpolated onto the ACCL time line")
    events: dict[str, np.ndarray] = {}
    gkey = "GPS9" if "GPS9" in streams else "GPS5" if "GPS5" in streams else None
    if gkey:
        s = streams[gkey]
        tl, rows, fixes = [], [], []
        for c, i, fx in zip(s.chunks, s.payload, s.fix, strict=True):
            k = c.shape[0]
            tl.append(starts[i] + (ends[i] - starts[i]) * np.arange(k) / max(k, 1))
            rows.append(c)
            fixes.append(fx)
        tl, gv, fx = np.concatenate(tl), np.concatenate(rows), np.concatenate(fixes)
        if gv.shape[1] < 5:
            raise GpmfError(f"{gkey} has {gv.shape[1]} columns, expected at least 5")
        bad = np.isfinite(fx) & (fx < 2)  # 0 = no lock, 2 = 2D, 3 = 3D
        gv = gv.copy()
        gv[bad] = np.nan
        dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        inside = np.flatnonzero((tl >= t[0] - dt / 2) & (tl <= t[-1] + dt / 2))
        j = nearest_index(tl[inside], t)
        for col, name, unit in ((3, "gps_speed", "m/s"), (0, "gps_lat", "deg"),
                                (1, "gps_lon", "deg"), (2, "gps_alt", "m")):
            y = np.full(t.size, np.nan)
            y[j] = gv[inside, col]  # later fixes on the same sample overwrite earlier ones
            chans[name], units[name] = y, unit
        events["gps_fix"] = tl
        rate = tl.size / max(float(ends[-1] - starts[0]), 1e-9)
        notes.append(f"{gkey}: {tl.size} fixes (~{rate:.3g} Hz), spread evenly inside their "
                     "payloads, speed2d -> gps_speed at the nearest ACCL sample (NaN elsewhere); "
                     f"{int(bad.sum())} without a 2D/3D fix -> NaN")
    return finish(t, chans, source=str(p), sort=False, units=units, events=events, notes=notes,
                  meta={"format": "gopro", "payloads": int(len(starts))},
                  axes="GoPro camera axes (X, Y, Z by ORIN), not vehicle axes: map them for the "
                  "mounting")
