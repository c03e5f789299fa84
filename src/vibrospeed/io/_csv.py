"""Streaming numeric CSV parsing with exact line numbers in every error (shared by the readers).

Rows are read with the :mod:`csv` module (so quoted headers, CRLF / CR line endings and a UTF-8
BOM are handled), buffered ``chunk_rows`` at a time and converted per column with NumPy; a chunk
that does not convert is re-scanned cell by cell to report the first bad cell's line and column.
A gzip-compressed file (``log.csv.gz``, recognised by its magic bytes) is read as its text; a
units row under the header (``s;g;g``, a logger's or spreadsheet's) and ISO-8601 time stamps are
read where the reader asks for them.
"""

from __future__ import annotations

import contextlib
import csv
import gzip
import io
import itertools
import os
import zlib
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np

from vibrospeed.errors import ParameterError, ReaderError

#: Cells read as NaN besides the empty cell (case-insensitive; "nan"/"inf" are numbers anyway).
NA_STRINGS = frozenset({"", "na", "n/a", "nan", "null", "none", "-"})
CHUNK_ROWS = 65536


def _short(s: str, n: int = 24) -> str:
    """``s`` shortened to ``n`` characters, control characters escaped (messages stay one line)."""
    s = "".join(c if c.isprintable() else repr(c)[1:-1] for c in s)
    return s if len(s) <= n else s[: n - 3] + "..."


def not_found(p: Path) -> str:
    """What to say about a path that does not exist: "file not found", or for a symbolic link
    (which ``ls`` lists) that its target is missing or that it loops."""
    if not p.is_symlink():
        return "file not found"
    try:
        target = os.readlink(p)
    except OSError:  # pragma: no cover - gone in between
        return "file not found"
    return f"broken symbolic link (to '{_short(target, 60)}': missing, or a link loop)"


#: what to say about a folder given where a file is read (``vibrospeed.io.folder_hint``, set by
#: the package, which imports this module: no import cycle); None: nothing more to say
folder_hint: Callable[[Path], str] | None = None


def check_file(path: str | os.PathLike[str]) -> Path:
    """``path`` as a Path; :class:`ReaderError` if it is missing, a folder or empty."""
    p = Path(path)
    if not p.exists():
        raise ReaderError(p, not_found(p))
    if p.is_dir():  # a folder of CSV files: which one to give, with what mapping
        raise ReaderError(p, (folder_hint(p) if folder_hint else "") or "is a folder, not a file")
    if p.stat().st_size == 0:
        raise ReaderError(p, "empty file")
    return p


GZIP_MAGIC = b"\x1f\x8b"


def is_gzip(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` starts with the gzip magic bytes (``.csv.gz``); False if unreadable."""
    try:
        with open(path, "rb") as fh:
            return fh.read(2) == GZIP_MAGIC
    except OSError:
        return False


@contextlib.contextmanager
def open_text(path: str | os.PathLike[str], encoding: str = "utf-8") -> Iterator[TextIO]:
    """Open a text file for :class:`CsvTable` (UTF-8 unless told, newlines untranslated); a
    gzip file is decompressed on the fly, and a damaged or truncated one is a one-line
    :class:`ReaderError` wherever in the file the damage is found."""
    p = check_file(path)
    gz = is_gzip(p)
    try:
        fh = gzip.open(p, "rt", encoding=encoding, newline="") if gz \
            else open(p, encoding=encoding, newline="")
    except OSError as exc:
        raise ReaderError(p, f"cannot open ({exc.strerror})") from None
    with fh:
        try:
            yield fh
        except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
            if not gz:
                raise
            raise ReaderError(p, f"damaged or truncated gzip file ({exc})") from None


def text_stream(raw: io.BufferedIOBase) -> TextIO:
    """Wrap a binary stream (e.g. a zip member) like :func:`open_text`."""
    return io.TextIOWrapper(raw, encoding="utf-8", newline="")


def sniff_delimiter(line: str) -> str:
    """The most frequent of ``,`` ``;`` tab in a header line (``,`` on a tie or none)."""
    counts = {d: line.count(d) for d in (",", ";", "\t")}
    best = max(counts.values())
    if best == 0:
        return ","
    return next(d for d in (",", ";", "\t") if counts[d] == best)


def excel_sep(line: str) -> str | None:
    """The delimiter an Excel ``sep=;`` first line names (one character), else None."""
    s = line.strip()
    return s[4] if len(s) == 5 and s[:4].lower() == "sep=" and s[4] not in "\"'" else None


def _not_text(fh: TextIO, source: str, exc: UnicodeDecodeError) -> ReaderError:
    """The error for bytes ``fh``'s encoding cannot decode, with its line; for UTF-8, how to
    read a Windows / Excel export (cp1252, Latin-1)."""
    enc = getattr(fh, "encoding", None) or "utf-8"
    head = b""
    with contextlib.suppress(AttributeError, OSError, ValueError):
        fh.buffer.seek(0)
        head = fh.buffer.read(4096)
    if head[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return ReaderError(source, "UTF-16 text (Excel's 'Unicode Text' export): save it as "
                                   "UTF-8, or read it through a --mapping TOML file with "
                                   "encoding = \"utf-16\"")
    if b"\0" in head:  # no text encoding writes NUL bytes in a CSV: Parquet, zip, MP4, ...
        return ReaderError(source, "a binary file, not CSV text: give its --format, or none "
                                   "to detect it")
    utf8 = enc.lower().replace("-", "").replace("_", "") in ("utf8", "utf8sig")
    hint = (": a Windows or Excel export? save it as UTF-8, or read it through a --mapping "
            "TOML file with encoding = \"cp1252\"" if utf8 else "")
    return ReaderError(source, f"not {'UTF-8' if utf8 else enc} text ({exc.reason}){hint}",
                       row=_undecodable_line(fh))


def _undecodable_line(fh: TextIO) -> int | None:
    """1-based line of the first bytes of ``fh`` that are not UTF-8, read again from the start.

    The text layer decodes a block of several kB ahead of the line it hands out, so the line
    being parsed when the error is raised is not the one that holds the bytes (it said line 0
    for a bad byte in the first block). ``None`` where the stream cannot be read again."""
    raw = getattr(fh, "buffer", None)
    enc = getattr(fh, "encoding", None) or "utf-8"
    try:
        raw.seek(0)
    except (AttributeError, OSError, ValueError):
        return None
    for line, chunk in enumerate(iter(raw.readline, b""), start=1):
        try:
            chunk.decode(enc)
        except UnicodeDecodeError:
            return line
    return None


class CsvTable:
    """A numeric CSV file with a header row, read column-wise and chunk-wise.

    Parameters
    ----------
    fh : text stream opened with ``newline=""``
    source : name used in error messages
    delimiter : field separator; ``None`` sniffs it from the header line
    decimal : decimal mark of the numbers (``","`` for e.g. semicolon-separated European exports)
    unit_name : where given, the first row after the header is a units row (skipped, its cells
        in :attr:`units`) when none of its cells is a number and one of them is a unit:
        ``unit_name(cell)`` returns the unit's name, None for no unit
    dates : columns that may hold ISO-8601 time stamps instead of numbers (read as seconds
        since 1970-01-01 UTC; a time without an offset is taken as UTC)
    dayfirst : how those columns' slash dates (``03/12/2026 14:05:01.250``) are read: True
        day first (``dd/mm/yyyy hh:mm:ss[.fff]``), False month first; None refuses them (which
        one is meant cannot be told from a date such as 03/12)

    Attributes
    ----------
    header : stripped column names; header_line : 1-based line of the header;
    units : column -> units-row cell (empty without a units row); units_line : its line;
    notes : what was noticed (BOM, CRLF, blank lines, empty cells, a units row, ISO times).
    """

    def __init__(
        self,
        fh: TextIO,
        source: str,
        *,
        delimiter: str | None = None,
        decimal: str = ".",
        unit_name: Callable[[str], str | None] | None = None,
        dates: Sequence[str] = (),
        dayfirst: bool | None = None,
    ) -> None:
        self.source = source
        self.decimal = decimal
        self.dates = frozenset(dates)
        self.dayfirst = dayfirst
        self.notes: list[str] = []
        self.units: dict[str, str] = {}
        self.units_line: int | None = None
        self._fh = fh
        self._peeked: list[str] = []  # lines read after the header, fed to the row reader
        line_no = 0
        first = ""
        sep = None
        try:
            while True:
                first = fh.readline()
                line_no += 1
                if line_no == 1 and first.startswith("\ufeff"):
                    first = first[1:]
                    self.notes.append("UTF-8 byte-order mark skipped")
                if sep is None and excel_sep(first) is not None:
                    sep = excel_sep(first)
                    self.notes.append(f"Excel 'sep={sep}' line {line_no} read: fields "
                                      f"separated by {sep!r}")
                    continue
                if not first or first.strip():
                    break
        except UnicodeDecodeError as exc:
            raise _not_text(fh, source, exc) from None
        if not first.strip():
            raise ReaderError(source, "empty file (no header row)")
        if first.endswith("\r\n"):
            self.notes.append("CRLF line endings")
        self.delimiter = delimiter or sep or sniff_delimiter(first)
        if self.decimal == self.delimiter:  # 1,5 would be two fields
            raise ReaderError(source, f"decimal mark '{decimal}' is also the field separator: "
                                      f"a number such as 1{decimal}5 would read as two fields "
                                      "(a decimal comma needs ';' or tab separated fields)",
                              row=line_no)
        try:
            header = next(csv.reader([first], delimiter=self.delimiter))
        except csv.Error as exc:
            raise ReaderError(source, f"malformed header: {exc}", row=line_no) from None
        self.header = [h.strip() for h in header]
        self.header_line = line_no
        while self.header and self.header[-1] == "":  # trailing delimiter
            self.header.pop()
        seen: set[str] = set()
        for name in self.header:
            if name and name in seen:
                raise ReaderError(source, "duplicate column name", row=line_no, column=name)
            seen.add(name)
        self._base = line_no  # file line before the first line the row reader sees
        if unit_name is not None:
            self._units_row(unit_name)

    def _units_row(self, unit_name: Callable[[str], str | None]) -> None:
        """Read ahead to the first non-blank line after the header; skip it as a units row
        when no cell is a number and some cell is a unit, else keep it for the row reader."""
        line = ""
        try:
            while True:
                line = self._fh.readline()
                self._peeked.append(line)
                if not line or line.strip():
                    break
        except UnicodeDecodeError as exc:
            raise _not_text(self._fh, self.source, exc) from None
        if not line.strip() or '"' in line and line.count('"') % 2:
            return  # no row, or a quoted field running on over lines: no units row
        try:
            cells = [c.strip() for c in next(csv.reader([line], delimiter=self.delimiter))]
        except (csv.Error, StopIteration):
            return
        if any(_is_number(c, self.decimal) for c in cells) or \
                not any(c and unit_name(c) is not None for c in cells):
            return
        self.units_line = self._base + len(self._peeked)
        self.units = {h: c for h, c in zip(self.header, cells, strict=False) if h and c}
        self._base = self.units_line
        blank = len(self._peeked) - 1
        self._peeked = []
        self.notes.append(f"units row (line {self.units_line}) read and skipped: "
                          + ", ".join(f"{h}: '{u}'" for h, u in self.units.items())
                          + (f"; {blank} blank line(s) before it" if blank else ""))

    def index(self, name: str) -> int:
        """Column index of ``name``; :class:`ReaderError` listing the header if absent."""
        try:
            return self.header.index(name)
        except ValueError:
            have = ", ".join(repr(h) for h in self.header if h)
            raise ReaderError(
                self.source, f"column not found (header has: {have})", row=self.header_line,
                column=name,
            ) from None

    def read(
        self,
        usecols: Sequence[str],
        *,
        allow_empty: bool = False,
        chunk_rows: int = CHUNK_ROWS,
    ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Parse the named columns to float64 (empty / NA cells -> NaN).

        Returns ``(columns, lines)`` with ``lines`` the 1-based file line of each row. Rows with
        a wrong number of fields, cells that are not numbers, and malformed CSV raise
        :class:`ReaderError` naming the line and column.
        """
        out: list[list[np.ndarray]] = [[] for _ in usecols]
        lines_out: list[np.ndarray] = []
        for cols, lines in self.iter_chunks(usecols, allow_empty=allow_empty,
                                            chunk_rows=chunk_rows):
            for k, name in enumerate(usecols):
                out[k].append(cols[name])
            lines_out.append(lines)
        lines = np.concatenate(lines_out) if lines_out else np.empty(0, dtype=np.int64)
        cols = {
            name: (np.concatenate(parts) if parts else np.empty(0))
            for name, parts in zip(usecols, out, strict=True)
        }
        return cols, lines

    def iter_chunks(
        self,
        usecols: Sequence[str],
        *,
        allow_empty: bool = False,
        chunk_rows: int = CHUNK_ROWS,
    ) -> Iterator[tuple[dict[str, np.ndarray], np.ndarray]]:
        """:meth:`read` ``chunk_rows`` rows at a time: yields ``(columns, lines)`` per chunk
        (memory bounded by one chunk of text and numbers), the same errors at the same lines;
        the blank-line note is added when the file is exhausted."""
        if chunk_rows < 1:
            raise ValueError(f"chunk_rows must be at least 1, got {chunk_rows}")
        idx = [self.index(c) for c in usecols]
        ncols = len(self.header)
        rows: list[list[str]] = []
        line_buf: list[int] = []
        blank = 0
        total = 0
        reader = csv.reader(itertools.chain(self._peeked, self._fh), delimiter=self.delimiter)
        self._peeked = []
        base = self._base  # csv counts lines from where it starts reading
        it = iter(reader)
        while True:
            try:
                row = next(it)
            except StopIteration:
                break
            except csv.Error as exc:
                raise ReaderError(
                    self.source, f"malformed CSV ({exc})", row=base + reader.line_num
                ) from None
            except UnicodeDecodeError as exc:
                raise _not_text(self._fh, self.source, exc) from None
            if len(row) != ncols:
                if not any(c.strip() for c in row):
                    blank += 1
                    continue
                if len(row) < ncols or any(c.strip() for c in row[ncols:]):
                    raise ReaderError(
                        self.source,
                        f"expected {ncols} fields, found {len(row)}",
                        row=base + reader.line_num,
                    )
                row = row[:ncols]  # trailing empty fields
            elif not row[0].strip() and not any(c.strip() for c in row):
                blank += 1
                continue
            rows.append(row)
            line_buf.append(base + reader.line_num)
            if len(rows) >= chunk_rows:
                total += len(rows)
                yield self._convert(rows, idx, line_buf, usecols)
        if rows:
            total += len(rows)
            yield self._convert(rows, idx, line_buf, usecols)
        if total == 0 and not allow_empty:
            raise ReaderError(self.source, "no data rows after the header", row=self.header_line)
        if blank:
            self.notes.append(f"skipped {blank} blank line(s)")

    def _convert(self, rows, idx, line_buf, names) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The buffered rows as float columns (buffers emptied)."""
        lines = np.asarray(line_buf, dtype=np.int64)
        cols = list(zip(*rows, strict=True))
        out = {name: self._to_float(cols[j], lines, name)
               for j, name in zip(idx, names, strict=True)}
        rows.clear()
        line_buf.clear()
        return out, lines

    def _to_float(self, cells: Sequence[str], lines: np.ndarray, name: str) -> np.ndarray:
        if self.decimal != ".":
            cells = [c.replace(self.decimal, ".") for c in cells]
        try:
            return np.array(cells, dtype=np.float64)
        except (ValueError, OverflowError):
            pass
        first = next((c for c in cells if c.strip().lower() not in NA_STRINGS), "")
        if name in self.dates and first and not _is_number(first, "."):
            return self._iso_seconds(cells, lines, name)
        vals = np.empty(len(cells))
        for k, c in enumerate(cells):
            try:
                vals[k] = float(c)
            except (ValueError, OverflowError):
                if c.strip().lower() in NA_STRINGS:
                    vals[k] = np.nan
                else:
                    raise ReaderError(
                        self.source,
                        f"'{_short(c.strip())}' is not a number{self._comma_hint(c)}",
                        row=int(lines[k]),
                        column=name,
                    ) from None
        return vals

    def _iso_seconds(self, cells: Sequence[str], lines: np.ndarray, name: str) -> np.ndarray:
        """ISO-8601 time stamps as float64 seconds since 1970-01-01 UTC (NA cells NaN); the
        first cell that is none is a :class:`ReaderError` naming its line."""
        import pandas as pd

        na = np.array([c.strip().lower() in NA_STRINGS for c in cells])
        text = [c.strip() for c in cells]
        if "/" in next(c for c, m in zip(text, na, strict=True) if not m):
            return self._slash_seconds(text, na, lines, name)
        try:
            stamps = pd.to_datetime([c for c, m in zip(text, na, strict=True) if not m],
                                    format="ISO8601", utc=True)
        except (ValueError, OverflowError, TypeError):
            for k, c in enumerate(text):
                if na[k]:
                    continue
                try:
                    pd.to_datetime([c], format="ISO8601", utc=True)
                except (ValueError, OverflowError, TypeError):
                    raise ReaderError(self.source, f"'{_short(c)}' is neither a number nor an "
                                      "ISO-8601 time (e.g. 2024-05-01T12:00:00.250Z)"
                                      + self._comma_hint(c),
                                      row=int(lines[k]), column=name) from None
            raise  # pragma: no cover - every cell parsed alone
        out = np.full(len(cells), np.nan)
        out[~na] = stamps.as_unit("ns").asi8 * 1e-9
        note = (f"column '{name}': ISO-8601 time stamps read as seconds since 1970-01-01 UTC "
                "(a time without an offset taken as UTC)")
        if note not in self.notes:
            self.notes.append(note)
        return out

    def _slash_seconds(self, text: list[str], na: np.ndarray, lines: np.ndarray,
                       name: str) -> np.ndarray:
        """Slash dates ``dd/mm/yyyy hh:mm:ss[.fff]`` (``mm/dd/...`` with ``dayfirst=False``) as
        float64 seconds since 1970-01-01 UTC, taken as UTC (NA cells NaN). Without
        ``dayfirst`` the first date is a :class:`ReaderError`: a day above 12 asks for
        ``dayfirst = true``, an ambiguous one (03/12) for either."""
        import pandas as pd

        if self.dayfirst is None:
            k = int(np.flatnonzero(~na)[0])
            first = text[k].split("/", 1)[0]
            if first.isdigit() and int(first) > 12:
                what = (f"'{_short(text[k])}' is a day-first date ({first} is no month): give "
                        "dayfirst = true in the mapping file")
            else:
                what = (f"'{_short(text[k])}' is a slash date, day or month first?: give "
                        "dayfirst = true (dd/mm/yyyy) or dayfirst = false (mm/dd/yyyy) in the "
                        "mapping file")
            raise ReaderError(self.source, what, row=int(lines[k]), column=name)
        said = "dd/mm/yyyy" if self.dayfirst else "mm/dd/yyyy"
        fmt = f"{'%d/%m' if self.dayfirst else '%m/%d'}/%Y %H:%M:%S.%f"
        # the fraction is optional in the file, not in the format: ".0" where a cell has none
        cells = [c if "." in c else c + ".0" for c, m in zip(text, na, strict=True) if not m]
        try:
            stamps = pd.to_datetime(cells, format=fmt, utc=True)
        except (ValueError, OverflowError, TypeError):
            for k, c in enumerate(text):
                if na[k]:
                    continue
                try:
                    pd.to_datetime([c if "." in c else c + ".0"], format=fmt, utc=True)
                except (ValueError, OverflowError, TypeError):
                    raise ReaderError(self.source, f"'{_short(c)}' is not a {said} "
                                      f"hh:mm:ss[.fff] time (dayfirst = "
                                      f"{str(self.dayfirst).lower()})",
                                      row=int(lines[k]), column=name) from None
            raise  # pragma: no cover - every cell parsed alone
        out = np.full(len(text), np.nan)
        out[~na] = stamps.as_unit("ns").asi8 * 1e-9
        note = (f"column '{name}': {said} dates read as seconds since 1970-01-01 UTC (taken as "
                "UTC)")
        if note not in self.notes:
            self.notes.append(note)
        return out

    def _comma_hint(self, cell: str) -> str:
        """What to do about ``cell`` when it is a number written with a decimal comma in a file
        whose fields are not separated by commas (a European spreadsheet's ``;`` export), else
        nothing: the reader keeps ``.`` unless told, so that ``1,234`` is never guessed."""
        if self.decimal != "." or self.delimiter == "," or "," not in cell:
            return ""
        try:
            float(cell.strip().replace(",", "."))
        except ValueError:
            return ""
        return (" (a decimal comma? give --decimal , or decimal = \",\" in a --mapping TOML "
                "file, see docs/formats.md)")


#: the decimal marks a caller may give (``decimal=``, ``--decimal``): no other is unambiguous
DECIMAL_MARKS = (".", ",")


def check_decimal(decimal: str | None, source: str | None = None) -> str | None:
    """``decimal`` as given (None: not given, the file's reader keeps ``.``); a
    :class:`ParameterError` naming ``source`` (where given) for a mark that is neither ``.``
    nor ``,``. Never guessed from the file: ``1,234`` is a thousand or one and a bit."""
    if decimal is None or decimal in DECIMAL_MARKS:
        return decimal
    where = f"{source}: " if source else ""
    raise ParameterError(f"{where}decimal mark must be '.' or ',', got {decimal!r}")


def _is_number(cell: str, decimal: str) -> bool:
    """Whether ``cell`` is a number written with the decimal mark ``decimal``."""
    try:
        float(cell.replace(decimal, ".") if decimal != "." else cell)
    except (ValueError, OverflowError):
        return False
    return True


def nan_notes(columns: dict[str, np.ndarray], source: str) -> list[str]:
    """Notes on empty / NaN cells and, counted apart, infinite ones (``inf``, ``-inf`` in the
    file: no measurement either, but not an empty cell); :class:`ReaderError` for a column
    with no finite number at all."""
    counts = {name: nonfinite_counts(x) for name, x in columns.items()}
    return count_notes(counts, {name: x.size for name, x in columns.items()}, source)


def nonfinite_counts(x: np.ndarray) -> tuple[int, int]:
    """``(NaN count, infinite count)`` of ``x``."""
    return int(np.count_nonzero(np.isnan(x))), int(np.count_nonzero(np.isinf(x)))


def count_notes(counts: dict[str, tuple[int, int]], sizes: dict[str, int],
                source: str) -> list[str]:
    """:func:`nan_notes` from the counts (:func:`nonfinite_counts`, summed over the chunks of a
    streamed file) and each channel's number of samples."""
    notes = []
    for name, (nnan, ninf) in counts.items():
        n = sizes[name]
        if n and nnan + ninf == n:
            what = ("channel has no finite value (all empty, NaN or infinite)" if ninf
                    else "channel has no numeric value (all empty or NaN)")
            raise ReaderError(source, what, column=name)
        said = [f"{nnan} empty or NaN cell(s)"] if nnan else []
        if ninf:
            said.append(f"{ninf} infinite value(s) (inf or -inf)")
        if said:
            notes.append(f"channel '{name}': {' and '.join(said)} of {n}")
    return notes
