"""What the ``vibrospeed`` commands share: the Typer ``app`` (its help text and ``--version``),
the rich consoles, :func:`_friendly` (a library error becomes one line on stderr and exit
status 2, a bug one line and exit 1), reading a recording as the CLI does and the ``-p``
parameters with the preset applied; the option types common to several commands are in
:mod:`vibrospeed.cli.options`. The commands themselves are in
:mod:`vibrospeed.cli.recordings`, :mod:`vibrospeed.cli.estimate` and
:mod:`vibrospeed.cli.results`; :mod:`vibrospeed.cli.app` registers them in order."""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from vibrospeed.errors import ParameterError, VibrospeedError

app = typer.Typer(
    name="vibrospeed",
    help=(
        "Estimate vehicle speed from a chassis accelerometer (wheel harmonics), longitudinal "
        "acceleration, GPS, yaw rate and wheel speeds.\n\n"
        "Typical session (a slow cart: wheel omega 2-30 rad/s, the default grid method "
        "searches 10-120 rad/s, a car's wheels):\n\n"
        "  vibrospeed simulate --scenario cart -o cart.csv\n\n"
        "  vibrospeed estimate cart.csv -p omega_min=2 -p omega_max=30 -o est.csv "
        "--plot est.png\n\n"
        "  vibrospeed evaluate est.csv --truth cart.csv\n\n"
        "A phone log (non-uniform, gaps and NaN are fine; fuse where it has GPS speed):\n\n"
        "  vibrospeed info phone_drive/\n\n"
        "  vibrospeed estimate phone_drive/ --format phyphox --axis y --wheel-radius 0.31 "
        "-o est.csv\n\n"
        "Units are SI: omega in rad/s, speed = wheel radius * omega in m/s, time in s, "
        "accelerations in m/s^2."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)
err = Console(stderr=True)
out = Console()


def _version(value: bool) -> None:
    if value:
        from vibrospeed import __version__

        print(f"vibrospeed {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", help="print the version and exit",
                                          callback=_version, is_eager=True)] = False,
) -> None:
    """Estimate vehicle speed from a chassis accelerometer (wheel harmonics), longitudinal
    acceleration, GPS, yaw rate and wheel speeds."""


def _friendly(fn):
    """Turn library errors into one line on stderr and exit status 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except VibrospeedError as exc:
            print(f"vibrospeed: error: {exc}", file=sys.stderr)
            raise typer.Exit(2) from None
        except (FileNotFoundError, IsADirectoryError, PermissionError) as exc:
            print(f"vibrospeed: error: {exc.filename or ''}: {exc.strerror}", file=sys.stderr)
            raise typer.Exit(2) from None
        except (typer.Exit, typer.Abort, KeyboardInterrupt):
            raise
        except BrokenPipeError:
            # the reader went away (``vibrospeed ... | head``): stop quietly, and point stdout
            # at /dev/null so that the interpreter's final flush does not fail again
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            raise typer.Exit(0) from None
        except Exception as exc:  # a bug, not bad input: one line, exit 1, traceback on demand
            if os.environ.get("VIBROSPEED_DEBUG"):
                raise
            print(f"vibrospeed: internal error: {type(exc).__name__}: {exc} (please report it; "
                  "set VIBROSPEED_DEBUG=1 for the traceback)", file=sys.stderr)
            raise typer.Exit(1) from None

    return wrapper


def _check_output(path: Path | None, flag: str = "-o", *, folder: bool = False) -> None:
    """Refuse, before any work, an output that cannot be written: a file output whose folder
    is missing, is no folder or is not writable, or that is itself a folder; a ``folder``
    output (``batch -o``, created with its parents) that is a file or whose nearest existing
    folder is not writable. Writability is tried (a temporary file made and removed there), not
    guessed from permission bits, which say yes to root on read-only or virtual file systems.
    The error names the user's path and its folder, as a :class:`ParameterError` (one line,
    exit status 2)."""
    import tempfile

    if path is None:
        return
    if folder:
        if path.exists() and not path.is_dir():
            raise ParameterError(f"{flag} {path}: is a file, not a folder")
        where = path
        while not where.exists() and where != where.parent:
            where = where.parent
        if not where.is_dir():
            raise ParameterError(f"{flag} {path}: {where} is not a folder")
    else:
        if path.is_dir():
            raise ParameterError(f"{flag} {path}: is a folder; give a file name")
        where = path.parent
        if not where.exists():
            raise ParameterError(f"{flag} {path}: folder {where} does not exist")
        if not where.is_dir():
            raise ParameterError(f"{flag} {path}: {where} is not a folder")
    try:
        with tempfile.NamedTemporaryFile(dir=where, prefix=".vibrospeed-probe-"):
            pass
    except OSError as exc:
        raise ParameterError(f"{flag} {path}: folder {where} is not writable "
                             f"({exc.strerror or exc})") from None


def _load(path: Path, fmt: str, columns: str | None, mapping: Path | None, rate: float | None,
          sort: bool, uniform: bool = True):
    from vibrospeed.batch import load_recording

    return load_recording(path, fmt, columns, mapping, rate, sort, uniform)


def _params(method: str, preset: str | None, param: list[str] | None) -> dict[str, str]:
    """The estimator parameters: the preset's, then the -p flags over them."""
    from vibrospeed import presets
    from vibrospeed.config import parse_params

    return presets.apply(method, preset, parse_params(param))


def _unknown_hint(method: str, exc: ParameterError) -> ParameterError:
    """An unknown-parameter error from one of a method's nested Configs, its suggestions taken
    from all of the method's parameter names (the flat ``-p`` namespace)."""
    import dataclasses
    import re

    from vibrospeed import estimators, presets
    from vibrospeed.config import flat_names, unknown

    m = re.match(r"unknown parameter '([^']+)' for \w+", str(exc))
    if m is None or method not in estimators.METHODS:
        return exc
    names = set(presets.PARAMETERS.get(method, {}))
    cfg = getattr(estimators.get(method), "Config", None)
    if dataclasses.is_dataclass(cfg):
        names |= flat_names(cfg)
    return unknown(m.group(1), f"method '{method}'", names)
