"""Reading members of an untrusted zip file into memory, with limits against zip bombs.

Member names are only compared with the names a reader looks for; nothing is ever extracted to
disk, so a name such as ``../../etc/passwd`` or an absolute path cannot escape anywhere. A member is
refused (one-line :class:`~vibrospeed.errors.ReaderError`) when

* its declared uncompressed size exceeds :data:`MAX_MEMBER_BYTES` (2 GiB),
* the members read so far would exceed :data:`MAX_TOTAL_BYTES` (4 GiB) together,
* it is larger than :data:`RATIO_FLOOR_BYTES` (16 MiB) and compressed more than
  :data:`MAX_RATIO` (200:1; sensor CSVs compress 3-15:1, a deflate bomb ~1000:1),
* it decompresses to more bytes than it declares (the read is cut one byte after the declared
  size), or it is encrypted, or its data is corrupt (bad CRC, truncated).
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path
from typing import TextIO

from vibrospeed.errors import ReaderError

__all__ = ["MAX_MEMBER_BYTES", "MAX_RATIO", "MAX_TOTAL_BYTES", "SafeZip"]

MAX_MEMBER_BYTES = 2 * 1024**3
MAX_TOTAL_BYTES = 4 * 1024**3
MAX_RATIO = 200.0
RATIO_FLOOR_BYTES = 16 * 1024**2
_CHUNK = 1 << 20


class SafeZip:
    """Members of a zip file by base name (first occurrence wins, ``__MACOSX/`` and folders
    skipped); :meth:`read` returns a member's bytes after the size checks."""

    def __init__(self, path: str | Path, *, max_member: int = MAX_MEMBER_BYTES,
                 max_total: int = MAX_TOTAL_BYTES, max_ratio: float = MAX_RATIO) -> None:
        self.path = Path(path)
        self.max_member, self.max_total, self.max_ratio = max_member, max_total, max_ratio
        self._read_total = 0
        try:
            with zipfile.ZipFile(self.path) as zf:
                infos = zf.infolist()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as exc:
            raise ReaderError(self.path, f"unreadable zip file ({_msg(exc)})") from None
        self.members: dict[str, zipfile.ZipInfo] = {}
        self._folders: dict[str, set[str]] = {}  # base name -> the zip folders holding one
        for info in infos:
            name = info.filename.replace("\\", "/")
            if info.is_dir() or "__MACOSX/" in name:
                continue
            folder, _, base = name.rpartition("/")
            if base:
                self._folders.setdefault(base, set()).add(folder)
            if base and base not in self.members:
                self.members[base] = info

    def folders(self, names) -> list[str]:
        """The zip folders (``""``: the top) holding a member named one of ``names``, sorted:
        more than one means the zip holds several exports."""
        return sorted(set().union(*(self._folders.get(n, set()) for n in names)))

    def label(self, base: str) -> str:
        """``zipfile:member`` for messages (control characters escaped)."""
        name = self.members[base].filename
        return f"{self.path}:{''.join(c if c.isprintable() else '?' for c in name)[:120]}"

    def read(self, base: str) -> bytes:
        """The bytes of member ``base`` (see the module docstring for the checks)."""
        info = self.members[base]
        label = self.label(base)
        size, csize = int(info.file_size), int(info.compress_size)
        if info.flag_bits & 0x1:
            raise ReaderError(label, "encrypted zip member")
        if size > self.max_member:
            raise ReaderError(label, f"zip member too large ({size} bytes uncompressed, limit "
                                     f"{self.max_member})")
        if self._read_total + size > self.max_total:
            raise ReaderError(label, f"zip members too large together (limit {self.max_total} "
                                     "bytes uncompressed)")
        if size > RATIO_FLOOR_BYTES and size > self.max_ratio * max(csize, 1):
            raise ReaderError(label, f"zip member compressed {size / max(csize, 1):.0f}:1 "
                                     f"(limit {self.max_ratio:.0f}:1): refused as a possible "
                                     "zip bomb")
        buf = io.BytesIO()
        try:
            with zipfile.ZipFile(self.path) as zf, zf.open(info) as fh:
                while True:
                    block = fh.read(min(_CHUNK, size + 1 - buf.tell()) or 1)
                    if not block:
                        break
                    buf.write(block)
                    if buf.tell() > size:
                        raise ReaderError(label, "zip member is larger than its header says")
        except ReaderError:
            raise
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError,
                NotImplementedError, RuntimeError) as exc:
            raise ReaderError(label, f"unreadable zip member ({_msg(exc)})") from None
        except Exception as exc:  # noqa: BLE001 - zlib/bz2/lzma errors on corrupt data
            raise ReaderError(label, f"unreadable zip member ({_msg(exc)})") from None
        self._read_total += size
        return buf.getvalue()

    def head(self, base: str, n: int = 512) -> bytes:
        """The first ``n`` bytes of member ``base`` (bounded read, for format detection)."""
        try:
            with zipfile.ZipFile(self.path) as zf, zf.open(self.members[base]) as fh:
                return fh.read(n)
        except Exception:  # noqa: BLE001 - detection never raises
            return b""

    def text(self, base: str) -> TextIO:
        """Member ``base`` as a text stream for :class:`~vibrospeed.io._csv.CsvTable`."""
        return io.TextIOWrapper(io.BytesIO(self.read(base)), encoding="utf-8", newline="")


def _msg(exc: BaseException) -> str:
    s = " ".join(str(exc).split()) or type(exc).__name__
    return s[:160]
