"""One recording, as ``vibrospeed estimate`` does it: its options (:class:`EstimateOptions`, the
CLI's shortcuts folded into the estimator's parameters), reading (:func:`load_recording`:
resampled to a uniform time line), the estimate with the axis rule, the quality annotation and
the CSV + JSON sidecar written (:func:`estimate_recording`). A batch task calls the same code,
so a batch output is the one ``vibrospeed estimate`` writes."""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.estimators.params import canonical_params, check_values


@dataclass(frozen=True)
class EstimateOptions:
    """The options of ``vibrospeed estimate`` (and of every recording in a batch).

    ``params`` are the estimator's ``-p NAME=VALUE`` parameters (strings or values);
    ``init_omega``, ``smooth``, ``lag`` and ``fit_params`` are the CLI's shortcuts for some of
    them; ``fmt``, ``columns``, ``mapping``, ``rate``, ``sort`` and ``decimal`` go to
    :func:`vibrospeed.io.read`.
    """

    method: str = "grid"
    params: dict[str, Any] = field(default_factory=dict)
    axis: str | None = None
    wheel_radius: float | None = None
    init_omega: float | None = None
    smooth: bool = False
    lag: float | None = None
    fit_params: bool = False
    fmt: str = "auto"
    columns: str | None = None
    mapping: str | None = None
    rate: float | None = None
    sort: bool = False
    topic: str | None = None
    decimal: str | None = None

    def __post_init__(self) -> None:
        # a radius that is not a finite number > 0 m is refused here, before anything is read
        # or written (the estimate CSV would be written and its JSON sidecar fail on nan/inf)
        from vibrospeed.io.track import check_wheel_radius

        check_wheel_radius(self.wheel_radius)

    def estimator_params(self) -> dict[str, Any]:
        """``params`` with the shortcuts folded in (as the CLI always did)."""
        params = dict(self.params)
        if self.init_omega is not None:
            params["omega0"] = str(self.init_omega)
        if self.smooth or self.lag is not None or self.fit_params:
            if self.method not in ("rbpmf", "grid"):
                raise ParameterError("--smooth, --lag and --fit-params need --method rbpmf or grid")
            if self.smooth:
                params["smooth"] = "fb"
            elif self.lag is not None:
                params["smooth"] = "lag"
                params["lag"] = str(self.lag)
            if self.fit_params:
                params["fit"] = "q_omega,q_amp,r"
        return params

    def check_params(self) -> None:
        """Refuse a ``-p`` name that the method takes nowhere (its Config's fields, the names
        its ``estimate()`` takes besides them and its presets': :func:`vibrospeed.estimators.
        parameters`), or a value that none of the name's types reads (``-p comb=1.0``,
        ``-p tracker=bogus``), before any recording is read: one line naming the method and
        the nearest accepted names, or the parameter and its value, instead of one error row
        per recording."""
        from vibrospeed import estimators
        from vibrospeed.config import unknown

        names = estimators.parameters(self.method)
        params = self.estimator_params()
        for name in params:
            if name not in names:
                raise unknown(name, f"method '{self.method}'", names)
        check_values(self.method, params)

    def check_reading(self) -> None:
        """Refuse reading options that no recording could satisfy, before any is read: a format
        name that is not one, a ``columns`` mapping or a ``mapping`` file that does not parse,
        and, where every recording is read through the mapping, the mapped reader's own rules
        (:func:`vibrospeed.io.mapped.mapping_options`: a unit of another quantity, a time column
        beside a sample rate, neither, ...) in its words, without the file name that
        ``vibrospeed estimate`` puts first (the options are at fault, not one recording), and a
        decimal mark with a ``fmt`` whose reader takes none (Parquet). A
        batch calls it first, so such a mistake is one error instead of one error row per
        recording."""
        from vibrospeed import io
        from vibrospeed.io.mapped import mapping_options

        if self.fmt != "auto" and self.fmt not in io.FORMATS:
            raise ParameterError(f"unknown format '{self.fmt}' (choose from: auto, "
                                 f"{', '.join(io.FORMATS)})")
        from vibrospeed.io._csv import check_decimal

        check_decimal(self.decimal)
        if self.decimal is not None and self.fmt != "auto" \
                and not io.format_takes(self.fmt, "decimal"):  # every recording would drop it
            raise ParameterError(f"format '{self.fmt}' does not take option 'decimal' (a "
                                 "decimal mark is for the CSV formats)")
        given = self.columns is not None or self.mapping is not None or self.rate is not None
        if self.fmt == "mapped" or (self.fmt == "auto" and given):  # io.read: all mapped
            mapping_options(self.columns, self.mapping, self.rate, decimal=self.decimal)
            return
        if self.mapping is not None:  # another format's reader refuses them, each recording
            io.load_mapping(self.mapping)
        if self.columns is not None:
            io.parse_mapping(self.columns)

    def to_json(self) -> dict[str, Any]:
        """Plain JSON form, as stored in a batch output's sidecar (``meta.options``)."""
        from vibrospeed.io._common import jsonable

        d = asdict(self)
        if d["decimal"] is None:  # not given: the sidecars written before it was an option
            del d["decimal"]
        d["params"] = canonical_params(self.method, self.params)
        return jsonable(d)

    def same_as(self, stored: Any) -> bool:
        """``stored`` (a sidecar's ``meta.options``) are these options: its ``params`` compared
        by value (:func:`vibrospeed.estimators.params.canonical_params`), so ``omega_max=30``
        is ``omega_max=30.0`` and a sidecar written before the params were stored canonical
        still matches."""
        want = self.to_json()
        if isinstance(stored, dict) and isinstance(stored.get("params"), dict):
            stored = {**stored, "params": canonical_params(self.method, stored["params"],
                                                           stored=True)}
        return stored == want


@dataclass
class Estimated:
    """What :func:`estimate_recording` produced: the recording (as read), the track (as
    written), the vibration axis used, grid posteriors kept out of the CSV, the format read."""

    recording: Any
    track: Any
    axis: str | None
    grids: dict[str, np.ndarray]
    format: str


def load_recording(path: str | os.PathLike[str], fmt: str = "auto", columns: str | None = None,
                   mapping: str | os.PathLike[str] | None = None, rate: float | None = None,
                   sort: bool = False, uniform: bool = True, topic: str | None = None,
                   decimal: str | None = None):
    """Read a recording as the CLI does: :func:`vibrospeed.io.read`, then non-uniform time
    stamps resampled to the median rate (:func:`vibrospeed.io.timebase.as_uniform`, unless
    ``uniform`` is false); ``topic``: a ROS bag's IMU topic; ``decimal``: a CSV's decimal
    mark."""
    from vibrospeed import io
    from vibrospeed.io import timebase

    rec = io.read(path, fmt, columns=columns, mapping_file=mapping, rate=rate, sort=sort,
                  topic=topic, decimal=decimal)
    if fmt in ("auto", "csv") and columns is None and mapping is None and rate is None:
        said = io.unread_sidecar_note(path)
        if said:
            rec.notes.append(said)
    return timebase.as_uniform(rec) if uniform else rec


def read_with(path: str | os.PathLike[str], options: EstimateOptions) -> list[Path]:
    """The files besides ``path`` itself that reading it with ``options`` takes numbers from:
    a canonical CSV's ``<path>.json`` (units, wheel radius) and event files
    (``drive.wss_ticks.csv``), an AndroSensor trip's ``gps.<trip>.csv``, the ``--mapping``
    file. A folder's own files are in its checksum already."""
    from vibrospeed.io.canonical import event_sidecars, sidecar_json

    p = Path(path)
    out: list[Path] = []
    if p.is_file():  # drive.csv.gz: drive.csv's sidecars, as the reader takes them
        out.append(sidecar_json(p))
        out.extend(sorted(event_sidecars(p).values()))
        if "accel" in p.name:
            out.append(p.with_name(p.name.replace("accel", "gps", 1)))
    if options.mapping is not None:
        out.append(Path(options.mapping))
    return [q for q in out if q.is_file()]


def read_with_sha256(path: str | os.PathLike[str], options: EstimateOptions) -> str:
    """SHA-256 over :func:`read_with`'s files (names and contents): a batch output whose
    sidecar records another is not up to date, though the input file itself is unchanged (a
    corrected wheel radius in ``drive.csv.json``, a corrected unit in the mapping file)."""
    import hashlib

    from vibrospeed.io._common import sha256_path

    h = hashlib.sha256()
    for q in read_with(path, options):
        h.update(q.name.encode() + b"\0" + sha256_path(q).encode() + b"\0")
    return h.hexdigest()


def estimate_recording(
    input: str | os.PathLike[str],  # noqa: A002 - the CLI's word
    output: str | os.PathLike[str],
    options: EstimateOptions,
    *,
    progress: bool = False,
    keep_posterior: bool = False,
    meta: dict[str, Any] | None = None,
    describe: bool = False,
    recording=None,
) -> Estimated:
    """Estimate one recording and write ``output`` (CSV) and ``output.json``, as
    ``vibrospeed estimate`` does.

    ``keep_posterior``: ask a grid method for its posterior (returned in ``grids``, for a plot);
    ``meta``: extra entries for the sidecar's ``meta``; ``describe``: also record the options
    (``meta.options``) and the recording's format, duration and length (``meta.recording``), as
    a batch does to resume. ``recording``: ``input`` already read as :func:`load_recording`
    reads it with these options (not read again). Raises the library's one-line errors.
    """
    from vibrospeed import __version__, estimators, io

    method = options.method
    params = options.estimator_params()
    read_sha = read_with_sha256(input, options) if describe else None  # before reading
    mod = estimators.get(method)
    rec = recording if recording is not None else load_recording(
        input, options.fmt, options.columns, options.mapping, options.rate, options.sort,
        topic=options.topic, decimal=options.decimal)
    extra_kw: dict[str, Any] = {}
    if keep_posterior:  # every method's estimate() takes it (the estimator protocol)
        extra_kw["return_posterior"] = True
    axis, axis_note = options.axis, None
    if method not in ("gps-riss", "algebraic"):  # their axis is the longitudinal one
        from vibrospeed.estimators.common import only_axis

        axis, axis_note = only_axis(rec, axis)
    if axis is not None:
        extra_kw["axis"] = axis
    track = mod.estimate(rec, wheel_radius=options.wheel_radius, params=params,
                         progress=progress, **extra_kw)
    if axis_note:
        track.notes.insert(0, axis_note)
    used = track.params.get("axis")  # the axis the estimator chose when --axis was not given
    axis = used if isinstance(used, str) else axis
    # saturated / stuck / spike samples: notes and a per-sample 'quality' column (bit flags)
    from vibrospeed.signal.quality import annotate

    annotate(track, rec, vibration_channel(rec, axis))
    # per-sample columns go to the CSV; a grid posterior (n, N) only to the plot
    grids = {k: v for k, v in track.extras.items() if np.shape(v) != (len(track),)}
    for k in grids:
        del track.extras[k]
    fmt = options.fmt
    if fmt == "auto":
        mapped = (options.columns is not None or options.mapping is not None
                  or options.rate is not None)
        fmt = io.detect_format(input, mapping=mapped)
    side_meta = {"version": __version__, "axis": axis, "recording_notes": rec.notes}
    if describe:
        side_meta["options"] = options.to_json()
        side_meta["read_with_sha256"] = read_sha
        side_meta["recording"] = {"format": fmt, "duration": float(rec.duration),
                                  "samples": len(rec)}
    side_meta.update(meta or {})
    io.write_track(track, output, meta=side_meta, input_path=input)
    return Estimated(rec, track, axis, grids, fmt)


def vibration_channel(rec, axis: str | None) -> str:
    """The channel to draw a spectrogram of: the axis used, else the first channel."""
    from vibrospeed.estimators.common import axis_channel

    ch = axis_channel(axis or "y")
    return ch if ch in rec.channels else next(iter(rec.channels))
