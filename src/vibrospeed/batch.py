# Over 500 lines: one job (many recordings -> estimates, resumable, on local processes or Dask);
# its options, the per-recording step, the pool and the summary table share one record.
"""Many recordings at once: estimate each, resume, summarise; on local processes or Dask.

:func:`estimate_recording` is what ``vibrospeed estimate`` does for one recording (read, pick the
axis, run the method, write the estimate CSV and its JSON sidecar); :func:`run` does it for many
recordings, each in its own task, and returns the summary table (one row per recording):

=================  ==========================================================================
``file``           the recording (file, folder or zip) as given or found
``output``         its estimate CSV (``<name>_<method>.csv`` + ``.json``) in the output folder
``format``         the format it was read as
``duration_s``     its length in s
``method``         the estimator
``signal_share``   share of samples where the method saw a wheel line (``has_signal``; empty
                   for methods without it)
``median_speed``   median of the speed estimate in m/s (empty without a wheel radius)
``median_omega``   median of omega in rad/s
``distance_m``     integral of the speed over time in m
``fitted_radius``  wheel radius in m fitted by the method (only present when a method gives one)
``status``         ``ok``, ``skipped`` (an up-to-date output was there) or ``error``
``error``          one line saying what went wrong
``wall_s``         seconds spent on this recording
``report``         its HTML report (only with ``report=True``)
=================  ==========================================================================

A recording is skipped when its estimate and sidecar exist and the sidecar records the same
method, options, vibrospeed version and input checksum (SHA-256 of the file or the folder's
files). One bad recording never stops the batch: its row says why. The work runs on a local
process pool (:mod:`concurrent.futures`, ``jobs`` processes) or, with ``scheduler`` (an address
``tcp://host:8786`` or a ``dask.distributed.Client``), on a Dask cluster; the workers must see
the same files (a shared file system) and have vibrospeed installed.

Example
-------
>>> from vibrospeed import batch                                    # doctest: +SKIP
>>> summary = batch.run(["logs/*.csv"], "out", method="grid", params={"omega_max": 60})
>>> summary[["file", "status", "median_speed", "distance_m"]]      # doctest: +SKIP
"""

from __future__ import annotations

import glob
import hashlib
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.errors import ParameterError, ReaderError, VibrospeedError
from vibrospeed.eval.metrics import fitted_radius, track_summary  # noqa: F401 (re-exported)

__all__ = [
    "EstimateOptions",
    "Estimated",
    "SUMMARY_COLUMNS",
    "estimate_recording",
    "expand_inputs",
    "load_recording",
    "output_names",
    "run",
    "track_summary",
]

#: Summary columns in order; ``fitted_radius`` and ``report`` appear only when they have values.
SUMMARY_COLUMNS = (
    "file", "output", "format", "duration_s", "method", "signal_share", "median_speed",
    "median_omega", "distance_m", "fitted_radius", "status", "error", "wall_s", "report",
)

# files in a folder that are never recordings (outputs, sidecars, notes)
_NOT_RECORDINGS = {".json", ".png", ".jpg", ".jpeg", ".svg", ".html", ".htm", ".md", ".toml",
                   ".yaml", ".yml"}


# ---- one recording, as `vibrospeed estimate` ------------------------------------------------
@dataclass(frozen=True)
class EstimateOptions:
    """The options of ``vibrospeed estimate`` (and of every recording in a batch).

    ``params`` are the estimator's ``-p NAME=VALUE`` parameters (strings or values);
    ``init_omega``, ``smooth``, ``lag`` and ``fit_params`` are the CLI's shortcuts for some of
    them; ``fmt``, ``columns``, ``mapping``, ``rate`` and ``sort`` go to :func:`vibrospeed.io.read`.
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

    def to_json(self) -> dict[str, Any]:
        """Plain JSON form, as stored in a batch output's sidecar (``meta.options``)."""
        from vibrospeed.io._common import jsonable

        d = asdict(self)
        d["params"] = {str(k): str(v) for k, v in sorted(self.params.items())}
        return jsonable(d)


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
                   sort: bool = False, uniform: bool = True, topic: str | None = None):
    """Read a recording as the CLI does: :func:`vibrospeed.io.read`, then non-uniform time
    stamps resampled to the median rate (unless ``uniform`` is false); ``topic``: a ROS
    bag's IMU topic."""
    from vibrospeed import io
    from vibrospeed.io import timebase

    rec = io.read(path, fmt, columns=columns, mapping_file=mapping, rate=rate, sort=sort,
                  topic=topic)
    if uniform and len(rec) > 2 and not rec.is_uniform(rtol=0.05):
        rec = timebase.resample_uniform(rec)
    return rec


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
    mod = estimators.get(method)
    rec = recording if recording is not None else load_recording(
        input, options.fmt, options.columns, options.mapping, options.rate, options.sort,
        topic=options.topic)
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


# ---- inputs and output names -------------------------------------------------------------------
def _is_recording_dir(p: Path) -> bool:
    from vibrospeed import io

    try:
        io.detect_format(p)
    except Exception:  # noqa: BLE001 - not a recording (or a reader's detector failed on it)
        return False
    return True


def _inside(p: Path, folder: Path) -> bool:
    try:
        p.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True


def _not_a_recording(q: Path) -> bool:
    """Hidden and temporary files, sidecars, images, notes, and a canonical CSV's event sidecar
    (``drive.wss_ticks.csv`` beside ``drive.csv``)."""
    if q.name.startswith(".") or ".tmp" in q.name or q.suffix.lower() in _NOT_RECORDINGS:
        return True
    head, dot, _ = q.stem.partition(".")
    return bool(dot) and q.with_name(f"{head}{q.suffix}").is_file()


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


def expand_inputs(items: Iterable[str | os.PathLike[str]], *,
                  exclude: str | os.PathLike[str] | None = None) -> list[tuple[str, str | None]]:
    """Recordings named by files, folders and glob patterns, in the order given.

    A folder that is itself a recording (a phyphox export, a comma2k19 segment ...) is one
    input; any other folder stands for its files and recording subfolders (not recursive; hidden
    files, sidecars, images, HTML and anything under ``exclude`` left out); a pattern (``*``,
    ``?``, ``[...]``, ``**``) for the files and recording folders it matches. A file named
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
            matches = [q for q in matches
                       if (q.is_dir() and _is_recording_dir(q))
                       or (q.is_file() and not _not_a_recording(q))]
            if not matches:
                found.append((s, "no recording matches this pattern"))
            for q in matches:
                add(q)
        else:
            found.append((s, "file not found"))
    return found


def _stem(p: Path) -> str:
    name = p.name if p.is_dir() else p.stem
    safe = "".join(c if c.isalnum() or c in "-_.+" else "_" for c in name).strip(".")
    return safe or "recording"


def output_names(inputs: Sequence[str | os.PathLike[str]]) -> list[str]:
    """A unique output base name per input: its file name without suffix (folder name for a
    folder); inputs that share one get ``-<8 hex digits of their absolute path>`` added, so a
    name stays the same from one run to the next."""
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


# ---- the task: one recording --------------------------------------------------------------------
def _one_line(exc: BaseException) -> str:
    if isinstance(exc, VibrospeedError):
        text = str(exc)
    elif isinstance(exc, (FileNotFoundError, IsADirectoryError, PermissionError)):
        text = f"{exc.filename or ''}: {exc.strerror}"
    else:
        text = f"internal error: {type(exc).__name__}: {exc}"
    return " ".join(text.split())


def _up_to_date(job: dict[str, Any]) -> dict[str, Any] | None:
    """The output's sidecar when it records the same method, options, version and input."""
    from vibrospeed import __version__
    from vibrospeed.io._common import sha256_path

    out = Path(job["output"])
    side_path = Path(f"{out}.json")
    if not (out.is_file() and side_path.is_file()):
        return None
    try:
        side = json.loads(side_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(side, dict) or not isinstance(side.get("meta"), dict):
        return None
    meta = side["meta"]
    same = (side.get("method") == job["options"].method
            and side.get("version") == __version__
            and meta.get("options") == job["options"].to_json()
            and side.get("input_sha256") is not None
            and side.get("input_sha256") == sha256_path(job["input"]))
    return side if same else None


def _work(job: dict[str, Any]) -> dict[str, Any]:
    """Estimate (or skip) one recording; never raises: a failure is a row with the error."""
    from vibrospeed import io

    t0 = time.perf_counter()
    opts: EstimateOptions = job["options"]
    row: dict[str, Any] = {"file": job["file"], "output": job["output"], "format": None,
                           "duration_s": math.nan, "method": opts.method, "status": "error",
                           "error": "", "report": job.get("report")}
    try:
        if job.get("error"):
            raise ReaderError(job["file"], job["error"])
        side = None if job.get("force") else _up_to_date(job)
        rec = None
        if side is not None:
            track = io.read_track(job["output"])
            info = side["meta"].get("recording") or {}
            row["format"] = info.get("format")
            row["duration_s"] = float(info.get("duration", math.nan) or math.nan)
            row["status"] = "skipped"
            axis = side["meta"].get("axis")
            grids: dict[str, np.ndarray] = {}
        else:
            est = estimate_recording(job["input"], job["output"], opts, describe=True,
                                     keep_posterior=bool(job.get("report")))
            rec, track, axis, grids = est.recording, est.track, est.axis, est.grids
            row["format"] = est.format
            row["duration_s"] = float(rec.duration)
            row["status"] = "ok"
        row.update(track_summary(track))
        report = job.get("report")
        if report and (row["status"] == "ok" or not Path(report).is_file()):
            from vibrospeed.eval.report import write_report

            if rec is None:
                rec = load_recording(job["input"], opts.fmt, opts.columns, opts.mapping,
                                     opts.rate, opts.sort, topic=opts.topic)
            write_report(report, rec, track, axis=vibration_channel(rec, axis),
                         posterior=grids.get("posterior"), grid=grids.get("grid"),
                         title=Path(job["file"]).name, input_path=job["file"],
                         estimate_path=job["output"])
    except Exception as exc:  # noqa: BLE001 - one bad recording never stops the batch
        row["status"] = "error"
        row["error"] = _one_line(exc)
        row["report"] = None
    row["wall_s"] = time.perf_counter() - t0
    return row


# ---- running many --------------------------------------------------------------------------------
def default_jobs() -> int:
    """min(4, CPU count)."""
    return max(1, min(4, os.cpu_count() or 1))


def _progress_bar(total: int, enabled: bool):
    from contextlib import nullcontext

    if not enabled:
        return nullcontext(None)
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TimeRemainingColumn(),
                    TextColumn("{task.fields[last]}", markup=False),
                    console=Console(stderr=True), transient=False)


def _run_local(jobs_list, n_jobs: int, done: Callable[[dict], None]) -> None:
    if n_jobs <= 1 or len(jobs_list) <= 1:
        for job in jobs_list:
            done(_work(job))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    # forkserver: workers start from a clean process, not a fork of one with threads running
    ctx = multiprocessing.get_context("forkserver")
    with ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs_list)), mp_context=ctx) as pool:
        futs = {pool.submit(_work, job): job for job in jobs_list}
        for fut in as_completed(futs):
            try:
                done(fut.result())
            except BrokenProcessPool:
                done(_lost(futs[fut], "its worker process died (out of memory?)"))


def _lost(job: dict[str, Any], why: str) -> dict[str, Any]:
    return {"file": job["file"], "output": job["output"], "format": None,
            "duration_s": math.nan, "method": job["options"].method, "status": "error",
            "error": why, "wall_s": math.nan, "report": None}


def _dask_client(scheduler):
    """``(client, own)``: a Client for ``scheduler`` (an address or a Client); ``own``: made
    here, to be closed here."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise ParameterError("--scheduler needs Dask: pip install 'vibrospeed[fleet]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    try:
        return Client(scheduler), True
    except (OSError, ValueError, TypeError) as exc:
        raise ParameterError(f"cannot reach the Dask scheduler at {scheduler}: "
                             f"{' '.join(str(exc).split())}") from None


def _run_dask(jobs_list, client, done: Callable[[dict], None]) -> None:
    from dask.distributed import as_completed

    futs = {client.submit(_work, job, pure=False): job for job in jobs_list}
    for fut in as_completed(list(futs)):
        try:
            done(fut.result())
        except Exception as exc:  # noqa: BLE001 - a lost worker, a cancelled task
            done(_lost(futs[fut], "dask: " + _one_line(exc)))


def _run_all(jobs_list, client, jobs: int | None, progress: bool,
             rows: dict[str, dict[str, Any]]) -> None:
    with _progress_bar(len(jobs_list), progress) as bar:
        task = bar.add_task("estimating", total=len(jobs_list), last="") if bar else None

        def done(row: dict[str, Any]) -> None:
            rows[row["output"]] = row
            if bar is not None:
                bar.update(task, advance=1, last=f"{Path(row['file']).name}: {row['status']}")

        if client is None:
            _run_local(jobs_list, jobs or default_jobs(), done)
        else:
            _run_dask(jobs_list, client, done)


def run(
    inputs: Iterable[str | os.PathLike[str]],
    outdir: str | os.PathLike[str],
    *,
    method: str = "grid",
    params: dict[str, Any] | None = None,
    options: EstimateOptions | None = None,
    scheduler: Any = None,
    jobs: int | None = None,
    report: bool = False,
    force: bool = False,
    progress: bool = False,
):
    """Estimate every recording in ``inputs`` into ``outdir`` and return the summary.

    Parameters
    ----------
    inputs : files, folders and glob patterns (:func:`expand_inputs`)
    outdir : output folder (created): ``<name>_<method>.csv`` + ``.json`` per recording,
        ``summary.csv`` and ``summary.parquet`` (with pyarrow), with ``report`` also
        ``<name>_<method>.html`` per recording and ``index.html``
    method, params : the estimator and its parameters (``-p``); or all of the estimate
        command's options as ``options`` (then ``method`` and ``params`` are ignored)
    scheduler : ``None``: local processes; a Dask scheduler address or ``Client``: Dask
    jobs : local processes (default ``min(4, cpu count)``; 1 runs in this process)
    force : estimate again even where an up-to-date output exists
    progress : a progress bar over the recordings on stderr

    Returns
    -------
    pandas.DataFrame with the columns of :data:`SUMMARY_COLUMNS` (see the module's doc), one
    row per recording in input order.
    """
    import pandas as pd

    opts = options if options is not None else EstimateOptions(method=method,
                                                               params=dict(params or {}))
    from vibrospeed import estimators

    estimators.get(opts.method)  # an unknown method is the caller's mistake: fail at once
    opts.estimator_params()  # so are inconsistent shortcuts
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    found = expand_inputs(inputs, exclude=out)
    names = output_names([f for f, _ in found])
    tag = opts.method.replace("-", "_")
    jobs_list = []
    for (f, error), name in zip(found, names, strict=True):
        jobs_list.append({
            "file": f, "input": os.path.abspath(f), "error": error,
            "output": os.fspath((out / f"{name}_{tag}.csv").absolute()),
            "report": os.fspath((out / f"{name}_{tag}.html").absolute()) if report else None,
            "options": opts, "force": force,
        })
    rows: dict[str, dict[str, Any]] = {}
    client, own = _dask_client(scheduler) if scheduler is not None else (None, False)
    try:
        _run_all(jobs_list, client, jobs, progress, rows)
    finally:
        if own:
            client.close()
    table = [rows[j["output"]] for j in jobs_list]
    df = pd.DataFrame(table, columns=list(SUMMARY_COLUMNS))
    df["file"] = df["file"].astype(str)
    if not df["fitted_radius"].notna().any():
        df = df.drop(columns="fitted_radius")
    if not report:
        df = df.drop(columns="report")
    else:
        df["report"] = [os.path.basename(r) if isinstance(r, str) else None
                        for r in df["report"]]
    df["output"] = [None if st == "error" else os.path.relpath(p, out.absolute())
                    for p, st in zip(df["output"], df["status"], strict=True)]
    write_summary(df, out)
    if report:
        from vibrospeed.eval.report import write_index

        write_index(out / "index.html", df, title=f"vibrospeed batch: {len(df)} recordings")
    return df


def write_summary(df, outdir: Path) -> list[Path]:
    """``summary.csv`` and, where pyarrow is installed, ``summary.parquet`` (both atomic)."""
    import importlib.util

    from vibrospeed.io.atomic import atomic_path

    written = []
    with atomic_path(outdir / "summary.csv") as tmp:
        df.to_csv(tmp, index=False)
    written.append(outdir / "summary.csv")
    if importlib.util.find_spec("pyarrow") is not None:
        with atomic_path(outdir / "summary.parquet") as tmp:
            df.to_parquet(tmp, index=False)
        written.append(outdir / "summary.parquet")
    return written


def print_errors(df, file=sys.stderr) -> None:  # pragma: no cover - trivial
    for _, r in df[df["status"] == "error"].iterrows():
        print(f"{r['file']}: {r['error']}", file=file)
