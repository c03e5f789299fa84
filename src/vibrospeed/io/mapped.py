"""Generic CSV with a column mapping: any delimited text file with a header row.

A mapping names, for each wanted channel, the file's column and how to bring it to SI::

    value_SI = (raw * scale + offset) * UNITS[unit].factor

On the command line (:func:`parse_mapping`)::

    t=time:ms,ay=acc_y:g,gz=yaw*0.01:deg/s      # NAME=COLUMN[*SCALE][:UNIT], comma-separated

with ``--decimal ,`` (``decimal=","``) for numbers written ``1,234``,

or in a small TOML file (:func:`load_mapping`)::

    rate = 198.4          # Hz; only for files without a time column: t = i / rate
    delimiter = ","       # optional; sniffed from the header otherwise
    decimal = "."         # optional decimal mark
    encoding = "utf-8"    # optional text encoding (e.g. "cp1252" for a Windows Excel export)
    dayfirst = true       # optional: a time column of dates 03/12/2026 14:05:01.250 is day first
                          # (false: month first); without it such dates are refused
    [columns]
    ay = "acc_y"                                        # plain column, already SI
    t  = { column = "time", unit = "ms" }
    ax = { column = "c1", scale = 0.00478 }             # raw counts -> m/s^2, explicit scale
    gz = { column = "yaw", unit = "deg/s", offset = -0.3 }

Only mapped columns are parsed; the rest of the file is ignored (text columns such as dates do no
harm).
"""

from __future__ import annotations

import codecs
import contextlib
import io
import math
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, TextIO

import numpy as np

from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.io._common import finish
from vibrospeed.io._csv import CsvTable, check_decimal, nan_notes, open_text
from vibrospeed.io.parquet import is_parquet, iter_columns
from vibrospeed.types import CHANNEL_UNITS, Recording

__all__ = ["UNITS", "ColumnSpec", "MappedSetup", "load_mapping", "mapping_options",
           "parse_mapping", "read_mapped", "resolve_mapping"]

#: unit name -> (factor to SI, SI unit)
UNITS: dict[str, tuple[float, str]] = {
    "m/s^2": (1.0, "m/s^2"),
    "m/s2": (1.0, "m/s^2"),
    "g": (9.80665, "m/s^2"),
    "mg": (9.80665e-3, "m/s^2"),
    "rad/s": (1.0, "rad/s"),
    "deg/s": (math.pi / 180.0, "rad/s"),
    "rpm": (2.0 * math.pi / 60.0, "rad/s"),
    "m/s": (1.0, "m/s"),
    "km/h": (1.0 / 3.6, "m/s"),
    "kmh": (1.0 / 3.6, "m/s"),
    "mph": (0.44704, "m/s"),
    "kn": (1852.0 / 3600.0, "m/s"),
    "s": (1.0, "s"),
    "ms": (1e-3, "s"),
    "us": (1e-6, "s"),
    "ns": (1e-9, "s"),
    "rad": (1.0, "rad"),
    "deg": (math.pi / 180.0, "rad"),
    "m": (1.0, "m"),
    "1": (1.0, "1"),
    "counts": (1.0, "1"),
}


#: how loggers and spreadsheets spell some units -> the name in :data:`UNITS`
_SPELLINGS = {"m/s²": "m/s^2", "m/s/s": "m/s^2", "m s^-2": "m/s^2", "m s-2": "m/s^2",
              "°/s": "deg/s", "dps": "deg/s", "°": "deg", "sec": "s", "µs": "us", "μs": "us",
              "kph": "km/h", "kt": "kn", "knots": "kn"}


def unit_name(text: str) -> str | None:
    """The :data:`UNITS` name of a unit as a units row or a header writes it (``[m/s²]``,
    ``(g)``, ``°/s``, ``ms``), None for anything else (``°C``, a word)."""
    u = text.strip()
    if len(u) > 2 and (u[0], u[-1]) in (("[", "]"), ("(", ")"), ("{", "}")):
        u = u[1:-1].strip()
    for cand in (u, u.lower()):
        cand = _SPELLINGS.get(cand, cand)
        if cand in UNITS:
            return cand
    return None


def header_unit(column: str) -> str | None:
    """The unit a header name ends with in brackets (``ax [m/s²]``, ``AccX (g)``), else None."""
    c = column.strip()
    for a, b in (("[", "]"), ("(", ")")):
        if c.endswith(b) and a in c[:-1]:
            return unit_name(c[c.rindex(a):])
    return None


class ColumnSpec(NamedTuple):
    """Where a channel comes from: ``value_SI = (raw * scale + offset) * UNITS[unit][0]``."""

    column: str
    scale: float = 1.0
    offset: float = 0.0
    unit: str | None = None

    def factor(self) -> float:
        return 1.0 if self.unit is None else UNITS[self.unit][0]


def _check_unit(unit: str, where: str) -> str:
    if unit not in UNITS:
        raise ParameterError(f"{where}: unknown unit '{unit}' (known: {', '.join(UNITS)})")
    return unit


def _at(source: str | None, text: str) -> str:
    """``text`` prefixed with ``source: `` (the file or option at fault), or as it is."""
    return text if source is None else f"{source}: {text}"


def _check_channel_unit(name: str, unit: str, source: str | None) -> None:
    """Refuse an unknown unit, or one of another quantity than channel ``name``'s SI unit
    (``ax=acc:m/s`` for m/s^2, ``gz=yaw:deg`` for deg/s, ``t=time:g``): its factor would be
    applied and the channel labelled with the wrong unit. Raw ``counts`` / ``1`` go with any
    channel (the vibration trackers normalise their input); channels vibrospeed does not know
    take any unit."""
    _check_unit(unit, f"column mapping '{name}'")
    want = "s" if name == "t" else CHANNEL_UNITS.get(name)
    have = UNITS[unit][1]
    if want is None or have in (want, "1"):
        return
    fits = ", ".join(u for u, (_, si) in UNITS.items() if si == want)
    raise ParameterError(_at(source, f"column mapping '{name}': unit '{unit}' gives {have}, "
                                     f"but {name} is in {want} (units for it: {fits}, or counts)"))


def _finite(x: Any, what: str, where: str) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ParameterError(f"{where}: {what} '{x}' is not a number") from None
    if not math.isfinite(v):
        raise ParameterError(f"{where}: {what} must be finite, got {x}")
    return v


def parse_mapping(text: str) -> dict[str, ColumnSpec]:
    """Parse ``"t=time,ay=acc_y"``-style mappings: ``NAME=COLUMN[*SCALE][:UNIT]`` items (the
    unit and the scale in either order). A ``:SUFFIX`` that is no unit stays part of the column
    name; the reader refuses it as an unknown unit where the header has no such column.

    >>> parse_mapping("t=time:ms,ay=acc_y:g")["ay"]
    ColumnSpec(column='acc_y', scale=1.0, offset=0.0, unit='g')
    """
    out: dict[str, ColumnSpec] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        name, eq, col = item.partition("=")
        name, col = name.strip(), col.strip()
        if not eq or not name or not col:
            raise ParameterError(f"column mapping '{item}': expected NAME=COLUMN (e.g. ay=acc_y)")
        if name in out:
            raise ParameterError(f"column mapping: '{name}' is given twice")
        unit = None
        head, colon, tail = col.rpartition(":")
        if colon and tail.strip() in UNITS:
            col, unit = head.strip(), tail.strip()
        scale = 1.0
        head, star, tail = col.rpartition("*")
        if star:
            try:
                scale = _finite(tail, "scale", f"column mapping '{item}'")
                col = head.strip()
            except ParameterError:
                pass  # a '*' that belongs to the column name
        head, colon, tail = col.rpartition(":")
        if unit is None and colon and tail.strip() in UNITS:  # COLUMN:UNIT*SCALE
            col, unit = head.strip(), tail.strip()
        out[name] = ColumnSpec(col, scale, 0.0, unit)
    if not out:
        raise ParameterError("column mapping is empty")
    return out


def date_columns(spec: dict[str, ColumnSpec]) -> tuple[str, ...]:
    """The column that may hold ISO-8601 time stamps: ``t``'s, when mapped with no unit but
    seconds, no scale and no offset."""
    s = spec.get("t")
    ok = s is not None and s.unit in (None, "s") and s.scale == 1.0 and s.offset == 0.0
    return (s.column,) if ok else ()


def mapping_text(spec: dict[str, ColumnSpec]) -> str:
    """The mapping as the reader's note shows it: ``gz<-yaw*0.01-0.3 [deg/s]`` is
    ``(yaw * 0.01 - 0.3)`` in deg/s (the offset with its own sign)."""
    return ", ".join(
        f"{k}<-{s.column}" + (f"*{s.scale:g}" if s.scale != 1 else "")
        + (f"{s.offset:+g}" if s.offset else "") + (f" [{s.unit}]" if s.unit else "")
        for k, s in spec.items()
    )


def _check_suffixes(spec: dict[str, ColumnSpec], header: list[str], source: str) -> None:
    """Refuse a ``--columns`` item whose ``:SUFFIX`` is no known unit. :func:`parse_mapping`
    keeps such a suffix in the column name (a header may hold ``a:b``); where the header has no
    such column, the suffix was meant as a unit: say that it is unknown and list the units,
    rather than "column not found"."""
    have = set(header)
    for name, s in spec.items():
        head, colon, tail = s.column.rpartition(":")
        if not colon or s.column in have or not head.strip() or not tail.strip() \
                or tail.strip() in UNITS:
            continue
        missing = "" if head.strip() in have else f"; and the header has no column '{head}'"
        raise ParameterError(
            f"{source}: column mapping '{name}={s.column}': unknown unit '{tail.strip()}' "
            f"(known: {', '.join(UNITS)}){missing}"
        )


def declared_units(spec: dict[str, ColumnSpec], units_row: dict[str, str],
                   units_line: int | None, source: str) -> tuple[dict[str, ColumnSpec], list[str]]:
    """``spec`` with the units the file declares (a units row under the header, or a header
    name ending in ``[unit]`` / ``(unit)``) filled in where the mapping gives none, and notes.

    A mapping item with a scale or offset keeps its values as they are (its scale may be the
    conversion already; noted). A declared unit that contradicts the mapping's unit, or that
    does not measure what the channel holds, is a :class:`ParameterError` naming both."""
    out = dict(spec)
    notes = []
    for name, s in spec.items():
        row = units_row.get(s.column)
        declared = unit_name(row) if row is not None else header_unit(s.column)
        where = (f"the units row (line {units_line}) says '{row}'" if row is not None
                 else f"the header '{s.column}' says {declared}")
        if declared is None:
            if row is not None and s.unit is None:
                notes.append(f"column '{s.column}': units row says '{row}', no unit vibrospeed "
                             "converts; read as it is")
            continue
        if s.unit is not None:
            if UNITS[s.unit] != UNITS[declared]:
                raise ParameterError(f"{source}: column mapping '{name}' gives unit '{s.unit}' "
                                     f"but {where}: give the file's unit, or none")
            continue
        if s.scale != 1.0 or s.offset != 0.0:
            notes.append(f"column '{s.column}': {where}; the mapping's scale/offset applied "
                         "and no unit (give :UNIT to convert)")
            continue
        _check_channel_unit(name, declared, f"{source}: {where} for column mapping '{name}'")
        out[name] = s._replace(unit=declared)
        notes.append(f"column '{s.column}': unit {declared} from the "
                     + ("units row" if row is not None else "header"))
    return out, notes


def load_mapping(path: str | os.PathLike[str]) -> tuple[dict[str, ColumnSpec], dict[str, Any]]:
    """Read a TOML mapping file; returns ``(columns, options)`` with options among ``rate``,
    ``delimiter``, ``decimal``, ``encoding``, ``dayfirst``."""
    p = Path(path)
    if not p.is_file():
        raise ReaderError(p, "mapping file not found")
    try:
        doc = tomllib.loads(p.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ReaderError(p, f"not a valid TOML mapping ({exc})") from None
    cols = doc.get("columns")
    if not isinstance(cols, dict) or not cols:
        raise ReaderError(p, "needs a [columns] table, e.g. ay = \"acc_y\"")
    out: dict[str, ColumnSpec] = {}
    for name, spec in cols.items():
        where = f"{p}: columns.{name}"
        if isinstance(spec, str):
            out[name] = ColumnSpec(spec)
            continue
        if not isinstance(spec, dict) or not isinstance(spec.get("column"), str):
            raise ParameterError(f"{where}: give a column name or {{ column = \"...\", ... }}")
        unknown = set(spec) - {"column", "scale", "offset", "unit"}
        if unknown:
            raise ParameterError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
        unit = spec.get("unit")
        if unit is not None:  # a unit of another quantity: the mistake is this file's
            unit = _check_unit(str(unit), where)
            _check_channel_unit(name, unit, str(p))
        out[name] = ColumnSpec(
            spec["column"],
            _finite(spec.get("scale", 1.0), "scale", where),
            _finite(spec.get("offset", 0.0), "offset", where),
            unit,
        )
    opts = {}
    unknown = set(doc) - {"columns", "rate", "delimiter", "decimal", "encoding", "dayfirst"}
    if unknown:
        raise ParameterError(f"{p}: unknown key(s) {', '.join(sorted(unknown))}")
    if "rate" in doc:
        opts["rate"] = _finite(doc["rate"], "rate", str(p))
    for k in ("delimiter", "decimal"):
        if k in doc:
            if not isinstance(doc[k], str) or len(doc[k]) != 1:
                raise ParameterError(f"{p}: {k} must be one character")
            opts[k] = doc[k]
    if "dayfirst" in doc:
        if not isinstance(doc["dayfirst"], bool):
            raise ParameterError(f"{p}: dayfirst must be true or false, got {doc['dayfirst']!r}")
        opts["dayfirst"] = doc["dayfirst"]
    if "encoding" in doc:
        try:
            codecs.lookup(str(doc["encoding"]))
            io.TextIOWrapper(io.BytesIO(), encoding=str(doc["encoding"]))  # a text encoding
        except LookupError:
            raise ParameterError(f"{p}: unknown encoding '{doc['encoding']}' (e.g. utf-8, "
                                 "cp1252, latin-1)") from None
        opts["encoding"] = str(doc["encoding"])
    return out, opts


@dataclass(frozen=True)
class MappedSetup:
    """A column mapping resolved for one file (:func:`resolve_mapping`): the channels' column
    specs, the text options (``delimiter``, ``decimal``, ``encoding``, ``dayfirst``) and the
    sample rate (None with a time column). Shared by :func:`read_mapped` and the chunked
    reader (:class:`vibrospeed.io.chunks.ChunkedRecording`), so that both check a mapping by
    the same rules, with the same words, in the same order."""

    source: Path
    spec: dict[str, ColumnSpec]
    opts: dict[str, Any]
    rate: float | None

    def table(self, fh: TextIO) -> CsvTable:
        """The CSV table of the open text ``fh`` read with the mapping's options."""
        return CsvTable(fh, str(self.source), delimiter=self.opts.get("delimiter"),
                        decimal=self.opts.get("decimal", "."), unit_name=unit_name,
                        dates=date_columns(self.spec), dayfirst=self.opts.get("dayfirst"))

    def open_table(self) -> contextlib.AbstractContextManager[TextIO]:
        """The file opened as text in the mapping's encoding (for :meth:`table`)."""
        return open_text(self.source, self.opts.get("encoding", "utf-8"))

    def columns_for(self, tab: CsvTable | None) -> tuple[dict[str, ColumnSpec], list[str],
                                                           list[str]]:
        """``(spec, notes, source columns)`` for the file's header (``tab``; None for a
        Parquet table): a ``:SUFFIX`` that is no unit refused, the units the file declares
        filled in (:func:`declared_units`), each source column once."""
        if tab is None:
            spec, notes = declared_units(self.spec, {}, None, str(self.source))
        else:
            _check_suffixes(self.spec, tab.header, str(self.source))
            spec, notes = declared_units(self.spec, tab.units, tab.units_line, str(self.source))
        return spec, notes, list(dict.fromkeys(s.column for s in spec.values()))


def mapping_options(
    columns: str | dict[str, ColumnSpec] | None = None,
    mapping_file: str | os.PathLike[str] | None = None,
    rate: float | None = None,
    *,
    source: str | None = None,
    decimal: str | None = None,
) -> tuple[dict[str, ColumnSpec], dict[str, Any], float | None]:
    """The rules of a mapping that need no data file: ``(spec, options, rate)`` from the TOML
    ``mapping_file``'s columns and options, ``columns`` items over them, ``rate`` over the
    file's, ``decimal`` (``--decimal``: ``.`` or ``,``) beside the file's; a
    :class:`ParameterError` for no mapping, a time column beside a rate, neither, a
    rate that is not positive, a unit of another quantity than its channel's, a ``decimal``
    that the file gives otherwise, or a decimal mark that is the delimiter too. ``source``
    (the data file) starts each such message; a batch checks its options with none, before
    any recording is read (:meth:`vibrospeed.batch.EstimateOptions.check_reading`)."""
    spec: dict[str, ColumnSpec] = {}
    opts: dict[str, Any] = {}
    if mapping_file is not None:
        spec, opts = load_mapping(mapping_file)
    if columns is not None:
        spec.update(parse_mapping(columns) if isinstance(columns, str) else dict(columns))
    if check_decimal(decimal, source) is not None:
        said = opts.get("decimal")
        if said is not None and said != decimal:  # which one is meant cannot be told
            raise ParameterError(_at(source, f"--decimal '{decimal}' but {mapping_file} says "
                                             f"decimal = \"{said}\": give one of them"))
        opts["decimal"] = decimal
    if opts.get("decimal") is not None and opts.get("decimal") == opts.get("delimiter"):
        raise ParameterError(_at(source, f"decimal '{opts['decimal']}' and delimiter "
                                         f"'{opts['delimiter']}' are the same mark: a number "
                                         f"1{opts['decimal']}5 would read as two fields"))
    if not spec:
        raise ParameterError(_at(source, "a column mapping is needed (e.g. --columns "
                                         "t=time,ay=acc_y)"))
    if rate is None:
        rate = opts.pop("rate", None)
    else:
        opts.pop("rate", None)
    if "t" in spec and rate is not None:
        raise ParameterError(_at(source, "give either a time column 't' or a sample rate, "
                                         "not both"))
    if "t" not in spec:
        if rate is None:
            raise ParameterError(_at(source, "no time column mapped; map one (t=COLUMN) or "
                                             "give the sample rate (rate=Hz)"))
        if not (math.isfinite(rate) and rate > 0):
            raise ParameterError(_at(source, f"sample rate must be positive, got {rate}"))
    for name, s in spec.items():
        if s.unit is not None:
            _check_channel_unit(name, s.unit, source)
    return spec, opts, rate


def resolve_mapping(
    path: str | os.PathLike[str],
    *,
    columns: str | dict[str, ColumnSpec] | None = None,
    mapping_file: str | os.PathLike[str] | None = None,
    rate: float | None = None,
    decimal: str | None = None,
) -> MappedSetup:
    """The mapping for ``path`` (:func:`mapping_options`, its messages naming ``path``),
    checked before the file is opened."""
    p = Path(path)
    return MappedSetup(p, *mapping_options(columns, mapping_file, rate, source=str(p),
                                           decimal=decimal))


def to_si(spec: dict[str, ColumnSpec], raw: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each channel's column brought to SI, ``(raw * scale + offset) * factor`` (a column
    without scale, offset or unit as it is: the same float64 values in every reader)."""
    out = {}
    for name, s in spec.items():
        x = raw[s.column]
        if s.scale != 1.0 or s.offset != 0.0 or s.unit is not None:
            x = (x * s.scale + s.offset) * s.factor()
        out[name] = x
    return out


def si_units(spec: dict[str, ColumnSpec]) -> dict[str, str]:
    """Each channel's SI unit: its mapped unit's, else the channel's canonical unit."""
    return {name: UNITS[s.unit][1] if s.unit else CHANNEL_UNITS.get(name, "")
            for name, s in spec.items()}


def read_mapped(
    path: str | os.PathLike[str],
    *,
    columns: str | dict[str, ColumnSpec] | None = None,
    mapping_file: str | os.PathLike[str] | None = None,
    rate: float | None = None,
    sort: bool = False,
    decimal: str | None = None,
) -> Recording:
    """Read a delimited text file through a column mapping (see module docstring).

    Parameters
    ----------
    columns : ``"t=time,ay=acc_y"`` string or a parsed mapping; overrides ``mapping_file`` items
    mapping_file : TOML mapping file
    rate : Hz; required when no ``t`` column is mapped, then ``t = i / rate`` (i = 0, 1, ...)
    sort : sort by time and drop repeated timestamps instead of refusing them
    decimal : the numbers' decimal mark, ``"."`` or ``","`` (a ``;``-separated European
        export); a ``mapping_file`` that gives another is refused. Never guessed: None reads
        the mapping file's, else ``"."``
    """
    setup = resolve_mapping(path, columns=columns, mapping_file=mapping_file, rate=rate,
                            decimal=decimal)
    p, rate = setup.source, setup.rate
    if is_parquet(p):  # a Parquet table with its own column names
        spec, notes, srcs = setup.columns_for(None)
        parts = list(iter_columns(p, srcs))
        raw = {c: np.concatenate([b[c] for b in parts]) if parts else np.empty(0)
               for c in srcs}
        lines = np.arange(1, raw[srcs[0]].size + 1)
        if lines.size == 0:
            raise ReaderError(p, "no data rows")
    else:
        with setup.open_table() as fh:
            tab = setup.table(fh)
            spec, unit_notes, srcs = setup.columns_for(tab)
            tab.notes.extend(unit_notes)
            raw, lines = tab.read(srcs)
        notes = list(tab.notes)
    tcol = spec["t"].column if "t" in spec else None
    notes.extend(nan_notes({c: x for c, x in raw.items() if c != tcol}, str(p)))
    chans = to_si(spec, raw)
    units = si_units(spec)
    notes.append(f"columns mapped: {mapping_text(spec)}")
    if "t" in chans:
        t = chans.pop("t")
        units.pop("t", None)
    else:
        t = np.arange(lines.size) / rate
        notes.append(f"no time column: t = i / {rate:g} Hz")
    return finish(t, chans, source=str(p), lines=lines, sort=sort, units=units, notes=notes,
                  meta={"mapping": {k: s._asdict() for k, s in spec.items()}, "rate": rate})
