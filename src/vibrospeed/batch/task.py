"""One batch task, run in a worker process (local or Dask): skip the recording when its output's
sidecar records the same method, options, version and input checksum, else estimate it
(:func:`vibrospeed.batch.single.estimate_recording`) and write its report; a failure is a row
with a one-line error, never an exception, so one bad recording never stops the batch. The
row's numbers are :func:`drive_summary`'s, the rule of the drive report
(:func:`vibrospeed.eval.metrics.track_summary`), so a row and its report never disagree; its
``note`` adds the note ``vibrospeed estimate`` prints where the default wheel speed range was
searched (:func:`vibrospeed.estimators.params.range_note`)."""

from __future__ import annotations

import glob
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from vibrospeed.batch.single import (
    EstimateOptions,
    estimate_recording,
    load_recording,
    read_with_sha256,
    vibration_channel,
)
from vibrospeed.errors import ReaderError, VibrospeedError
from vibrospeed.estimators.params import range_note
from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE, track_summary  # noqa: F401 (re-exported)

#: A batch row's numbers for one track (and its ``note``): the rule of the drive report,
#: :func:`vibrospeed.eval.metrics.track_summary`, under its batch name.
drive_summary = track_summary

#: Between the notes of one row's ``note``: the drive summary's (:data:`NO_EVIDENCE_NOTE`),
#: then the default range's (:func:`vibrospeed.estimators.params.range_note`)
NOTE_SEP = "; "


def _one_line(exc: BaseException) -> str:
    if isinstance(exc, VibrospeedError):
        text = str(exc)
    elif isinstance(exc, OSError) and exc.strerror:  # the file system's word: no bug of ours
        text = f"{exc.filename or ''}: {exc.strerror}" if exc.filename else exc.strerror
    else:
        text = f"internal error: {type(exc).__name__}: {exc}"
    return " ".join(text.split())


def _naming_file(job: dict[str, Any], text: str) -> str:
    """``text`` naming the recording: a reader's error names it already (by the absolute path
    the task reads); an option's (``unknown parameter ...``) or a lost worker's does not, so
    ``job["file"]`` goes first, as the summary's ``error`` column promises."""
    if str(job["file"]) in text or str(job.get("input", job["file"])) in text:
        return text
    return f"{job['file']}: {text}"


def _for_recording(opts: EstimateOptions, path: str) -> EstimateOptions:
    """``opts`` for the recording at ``path``: ``topic`` (a ROS bag's IMU topic) and
    ``decimal`` (a CSV's decimal mark) only where its format's reader takes them, so one
    ``--topic`` serves the bags and one ``--decimal ,`` the CSV files of a fleet that also
    holds files of other formats (each of which :func:`vibrospeed.io.read` would refuse with
    it; :func:`dropped_decimal` says so once for the batch). Where the format cannot be told
    the options stay as given: reading then says why."""
    given = [k for k in DROPPABLE if getattr(opts, k) is not None]
    if not given:
        return opts
    import dataclasses

    from vibrospeed import io

    try:
        fmt = opts.fmt
        if fmt == "auto":
            fmt = io.detect_format(path, mapping=opts.columns is not None
                                   or opts.mapping is not None or opts.rate is not None)
        if fmt not in io.available_formats():
            return opts  # reading says why
    except (VibrospeedError, ImportError, OSError):
        return opts
    drop = {k: None for k in given if not io.format_takes(fmt, k)}
    return dataclasses.replace(opts, **drop) if drop else opts


#: the reading options a batch leaves out for a recording whose format's reader has no use for
#: them (:func:`_for_recording`)
DROPPABLE = ("topic", "decimal")


def dropped_decimal(decimal: str | None, formats) -> str | None:
    """The batch's one note where ``--decimal`` was given and some recordings (their
    ``formats``, the summary's column, None for a failed one) are of a format whose reader
    takes no decimal mark (Parquet, a ROS bag, a phone app's export): read without it, so a
    user sees the mark was not applied there. None where it applied to all."""
    from collections import Counter

    from vibrospeed import io

    if decimal is None:
        return None
    other = Counter(f for f in formats if isinstance(f, str) and f in io.available_formats()
                    and not io.format_takes(f, "decimal"))
    if not other:
        return None
    n = sum(other.values())
    kinds = ", ".join(f"{k} {c}" for k, c in sorted(other.items()))
    return (f"--decimal '{decimal}' applies to the CSV recordings only: {n} recording"
            f"{'s' if n != 1 else ''} of another format ({kinds}) read without it")


def _up_to_date(job: dict[str, Any]) -> dict[str, Any] | None:
    """The output's sidecar when it records the same method, options, version and input (the
    file or folder, and the files read with it: :func:`vibrospeed.batch.single.read_with`)."""
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
            and job["options"].same_as(meta.get("options"))
            and side.get("input_sha256") is not None
            and side.get("input_sha256") == sha256_path(job["input"])
            and meta.get("read_with_sha256") == read_with_sha256(job["input"], job["options"]))
    return side if same else None


def _remove_dead_temporaries(*targets: Path) -> None:
    """Remove the temporary files that a writer of ``targets`` stopped mid-write left beside
    them (:func:`vibrospeed.io.atomic.atomic_path`'s ``.<name>.<pid>-<hex>.tmp<suffix>``: a
    worker killed by Ctrl-C or SIGTERM gets no chance to) where that process is gone; one of a
    live process (another batch writing the same output) is left alone."""
    for target in targets:
        for q in target.parent.glob(f".{glob.escape(target.name)}.*.tmp*"):
            pid = q.name[len(target.name) + 2:].split("-", 1)[0]
            if not pid.isdigit():
                continue
            try:
                os.kill(int(pid), 0)
            except ProcessLookupError:
                q.unlink(missing_ok=True)
            except (OSError, OverflowError):  # alive under another user, or not a pid
                continue


def _stale(report: Path, estimate: Path) -> bool:
    """A skipped recording's report is written again when it is missing or older than its
    estimate: a run without ``--report`` replaced the estimate and left the old page, which
    shows the old options' numbers."""
    try:
        return report.stat().st_mtime_ns < estimate.stat().st_mtime_ns
    except OSError:  # no report (or no estimate: then estimating failed and this is not asked)
        return True


def _work(job: dict[str, Any]) -> dict[str, Any]:
    """Estimate (or skip) one recording; never raises: a failure is a row with the error."""
    from vibrospeed import io

    t0 = time.perf_counter()
    opts: EstimateOptions = job["options"]
    row: dict[str, Any] = {"file": job["file"], "output": job["output"], "format": None,
                           "duration_s": math.nan, "method": opts.method, "status": "error",
                           "error": "", "note": "", "report": job.get("report")}
    try:
        if job.get("error"):
            raise ReaderError(job["file"], job["error"])
        opts = _for_recording(opts, job["input"])
        job = {**job, "options": opts}
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
            out = Path(job["output"])
            _remove_dead_temporaries(out, Path(f"{out}.json"),
                                     *([Path(job["report"])] if job.get("report") else []))
            est = estimate_recording(job["input"], job["output"], opts, describe=True,
                                     keep_posterior=bool(job.get("report")))
            rec, track, axis, grids = est.recording, est.track, est.axis, est.grids
            row["format"] = est.format
            row["duration_s"] = float(rec.duration)
            row["status"] = "ok"
        row.update(drive_summary(track))
        said = range_note(opts.method, opts.params, track.params, track.wheel_radius)
        if said:  # the note vibrospeed estimate prints: the default range searched
            row["note"] = NOTE_SEP.join(n for n in (row["note"], said) if n)
        report = job.get("report")
        if report and (row["status"] == "ok" or _stale(Path(report), Path(job["output"]))):
            from vibrospeed.eval.report import write_report

            if rec is None:
                rec = load_recording(job["input"], opts.fmt, opts.columns, opts.mapping,
                                     opts.rate, opts.sort, topic=opts.topic,
                                     decimal=opts.decimal)
            write_report(report, rec, track, axis=vibration_channel(rec, axis),
                         posterior=grids.get("posterior"), grid=grids.get("grid"),
                         title=Path(job["file"]).name, input_path=job["file"],
                         estimate_path=os.path.relpath(job["output"], Path(report).parent))
    except Exception as exc:  # noqa: BLE001 - one bad recording never stops the batch
        row["status"] = "error"
        row["error"] = _naming_file(job, _one_line(exc))
        row["report"] = None
    row["wall_s"] = time.perf_counter() - t0
    return row


def _lost(job: dict[str, Any], why: str) -> dict[str, Any]:
    return {"file": job["file"], "output": job["output"], "format": None,
            "duration_s": math.nan, "method": job["options"].method, "status": "error",
            "error": _naming_file(job, why), "note": "", "wall_s": math.nan, "report": None}
