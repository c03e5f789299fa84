"""A batch job (:func:`run`): the inputs expanded, one task per recording with its output and
report names, the tasks run (:mod:`vibrospeed.batch.pool`), and the summary table in input
order written as ``summary.csv`` (and ``summary.parquet`` with pyarrow) and, with reports,
``index.html``."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from vibrospeed.batch.inputs import expand_inputs, output_names
from vibrospeed.batch.pool import _dask_client, _run_all
from vibrospeed.batch.single import EstimateOptions
from vibrospeed.batch.task import dropped_decimal

#: Summary columns in order; ``fitted_radius``, ``fitted_radius_std`` and ``report`` appear only
#: when some row has a value.
SUMMARY_COLUMNS = (
    "file", "output", "format", "duration_s", "method", "signal_share", "median_speed",
    "median_omega", "distance_m", "distance_lo_m", "distance_hi_m", "fitted_radius",
    "fitted_radius_std", "status", "error", "note", "wall_s", "report",
)


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
    pandas.DataFrame with the columns of :data:`SUMMARY_COLUMNS` (see :mod:`vibrospeed.batch`), one
    row per recording in input order.
    """
    import pandas as pd

    opts = options if options is not None else EstimateOptions(method=method,
                                                               params=dict(params or {}))
    from vibrospeed import estimators

    estimators.get(opts.method)  # an unknown method is the caller's mistake: fail at once
    opts.estimator_params()  # so are inconsistent shortcuts
    opts.check_params()  # and a -p name the method takes nowhere
    opts.check_reading()  # and reading options that no recording could satisfy
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
    df = df.drop(columns=[c for c in ("fitted_radius", "fitted_radius_std")
                          if not df[c].notna().any()])
    if not report:
        df = df.drop(columns="report")
    else:
        df["report"] = [os.path.basename(r) if isinstance(r, str) else None
                        for r in df["report"]]
    df["output"] = [None if st == "error" else os.path.relpath(p, out.absolute())
                    for p, st in zip(df["output"], df["status"], strict=True)]
    write_summary(df, out)
    said = dropped_decimal(opts.decimal, df["format"])
    if said:  # once for the batch, not in each row's note
        print(f"note: {said}", file=sys.stderr)
    if report:
        from vibrospeed.eval.report import write_index

        write_index(out / "index.html", df, title=f"vibrospeed batch: {len(df)} recordings")
    else:
        gone = remove_stale_pages(
            out, [j for j in jobs_list if rows[j["output"]]["status"] == "ok"], tag)
        if gone:  # a page that vanishes unannounced reads as a bug
            print(f"note: removed {len(gone)} page(s) of an earlier run with --report that "
                  f"showed replaced estimates ({', '.join(p.name for p in gone[:3])}"
                  f"{', ...' if len(gone) > 3 else ''}); --report writes them again",
                  file=sys.stderr)
    return df


#: the start of the title :func:`run` gives ``index.html``: a page with it is a batch's own
INDEX_TITLE = "<title>vibrospeed batch"


def remove_stale_pages(out: Path, estimated: list[dict[str, Any]], tag: str) -> list[Path]:
    """Without ``--report``: remove an earlier run's ``index.html`` (its table is the old
    summary, now contradicting ``summary.csv``) and the report page of every recording
    estimated again (it shows the replaced estimate). Pages of skipped recordings still match
    their estimate and stay; an ``index.html`` that is not a batch's own is left alone.
    Returns the removed paths."""
    removed = []
    index = out / "index.html"
    try:
        ours = INDEX_TITLE in index.read_text(encoding="utf-8", errors="replace")[:4096]
    except OSError:
        ours = False
    pages = [Path(j["output"][: -len(".csv")] + ".html") for j in estimated
             if j["output"].endswith(f"_{tag}.csv")]
    for p in ([index] if ours else []) + pages:
        try:
            p.unlink()
        except FileNotFoundError:
            continue
        removed.append(p)
    return removed


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
