"""Where the tasks run: a local process pool (forkserver workers; a worker that dies is a row
saying so) or a Dask cluster (an address or a ``Client``), with a progress bar over the
recordings on stderr. Each finished task's row is handed to a callback as it comes in."""

from __future__ import annotations

import os
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from vibrospeed.batch.task import _lost, _one_line, _work
from vibrospeed.errors import ParameterError


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
    with _terminate_raises(), ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs_list)),
                                                  mp_context=ctx) as pool:
        futs = {pool.submit(_work, job): job for job in jobs_list}
        try:
            for fut in as_completed(futs):
                try:
                    done(fut.result())
                except BrokenProcessPool:
                    done(_lost(futs[fut], "its worker process died (out of memory? or a "
                                          "script calling vibrospeed.batch.run outside `if "
                                          "__name__ == '__main__':`, which each worker "
                                          "re-imports)"))
        except BaseException:  # Ctrl-C, SIGTERM: stop the workers too, never leave them behind
            # no fut.cancel() first: the pool's manager thread then fails the queued futures
            # with BrokenProcessPool, and on Python < 3.12 it raised InvalidStateError on each
            # cancelled one (a traceback on stderr after every Ctrl-C); with the workers gone
            # nothing queued can start anyway
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
            raise


@contextmanager
def _terminate_raises():
    """While the pool runs, SIGTERM (``kill``, ``timeout``, a job scheduler) raises
    ``SystemExit(143)`` in this process instead of ending it at once, so that the pool's
    workers are stopped with it (they waited, orphaned, for work that never came). Only in the
    main thread, where Python delivers signals."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def raise_exit(signum, frame):
        raise SystemExit(128 + signum)

    old = signal.signal(signal.SIGTERM, raise_exit)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


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
