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
from typing import Annotated, Any

import typer
from rich.console import Console
from typer.core import TyperCommand, TyperGroup

from vibrospeed.errors import ParameterError, VibrospeedError

try:  # typer >= 0.2x carries its own copy of click
    from typer._click.exceptions import BadParameter, MissingParameter, UsageError
except ImportError:  # pragma: no cover - older typer on click
    from click.exceptions import BadParameter, MissingParameter, UsageError


def _number_type(param) -> type | None:
    """float or int where ``param`` takes one number (``float | None`` included), else None:
    the annotation (typer >= 0.2x) or click's parameter type (older typer)."""
    annotation = getattr(getattr(param, "type_descriptor", None), "annotation", None)
    if annotation is None:
        name = getattr(getattr(param, "type", None), "name", None)
        return {"float": float, "integer": int}.get(name)
    return annotation if annotation in (float, int) else None


def _usage_line(command, ctx, argv: list[str], exc: Exception) -> str:
    """Click's usage error ``exc`` (raised while ``command`` parsed ``argv``) as one line: a
    number option given text names the option and the text (``--wheel-radius: 'abc' is not a
    number``, ``--jobs: 'two' is not an integer``; the text as Python writes it, so a newline
    in it stays on the line); any other (an unknown option, a missing argument) is Click's
    message and where ``--help`` is."""
    param = getattr(exc, "param", None)
    kind = _number_type(param) if isinstance(exc, BadParameter) else None
    if kind is not None:
        raw = None
        try:  # the text as given: the command's own option parser run again on its arguments
            raw = command.make_parser(ctx).parse_args(args=list(argv))[0].get(param.name)
        except (UsageError, AttributeError, TypeError):
            pass
        flag = max(param.opts, key=len) if param.opts else param.name
        if isinstance(raw, str):
            line = f"{flag}: {raw!r} is not {'a number' if kind is float else 'an integer'}"
            if kind is float and raw.count(",") == 1:  # a decimal comma (0,31): say so
                try:
                    float(raw.replace(",", "."))
                    line += " (write the decimal point as '.')"
                except ValueError:
                    pass
            return line
    text = " ".join(exc.format_message().split()).rstrip(".")
    if isinstance(exc, BadParameter) and not isinstance(exc, MissingParameter) \
            and getattr(param, "opts", None):
        text = f"{max(param.opts, key=len)}: {text}"
    return f"{text[:1].lower()}{text[1:]}; see '{ctx.command_path} --help'"


def _refuse(command, ctx, argv: list[str], exc: Exception):
    """Print ``exc`` as :func:`_usage_line` and exit with status 2 (no usage block)."""
    print(f"vibrospeed: error: {_usage_line(command, ctx, argv, exc)}", file=sys.stderr)
    raise typer.Exit(2) from None


class _OneLine:
    """Click's usage errors while a command line is parsed as one line and exit status 2
    (:func:`_usage_line`); no arguments at all still print the help."""

    def parse_args(self, ctx, args: list[str]) -> list[str]:
        argv = list(args)  # the parser consumes its list
        try:
            return super().parse_args(ctx, args)
        except UsageError as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # no arguments: the help, as asked
                raise
            _refuse(self, ctx, argv, exc)


class OneLineCommand(_OneLine, TyperCommand):
    """A ``vibrospeed`` command whose command-line errors are one line on stderr and exit
    status 2, as the library's (:func:`_friendly`): a value that is not a number
    (``vibrospeed: error: --wheel-radius: 'abc' is not a number``), an unknown option, a missing
    argument; Click would print its usage block. ``--help`` is Typer's."""


class OneLineGroup(_OneLine, TyperGroup):
    """The ``vibrospeed`` group: an unknown option before the command or an unknown command is
    one line and exit status 2 (:class:`OneLineCommand` does the commands' own options);
    ``vibrospeed`` alone prints the help."""

    def resolve_command(self, ctx, args: list[str]) -> Any:
        try:
            return super().resolve_command(ctx, args)
        except UsageError as exc:
            _refuse(self, ctx, list(args), exc)


app = typer.Typer(
    cls=OneLineGroup,
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
        except Exception as exc:  # one line, exit 1, the traceback on demand
            if os.environ.get("VIBROSPEED_DEBUG"):
                raise
            if isinstance(exc, OSError) and exc.strerror:  # a full disk, an I/O error: the
                where = f"{exc.filename}: " if exc.filename else ""  # system's word, no bug
                print(f"vibrospeed: error: {where}{exc.strerror}", file=sys.stderr)
            else:  # a bug, not bad input
                print(f"vibrospeed: internal error: {type(exc).__name__}: {exc} (please report "
                      "it; set VIBROSPEED_DEBUG=1 for the traceback)", file=sys.stderr)
            raise typer.Exit(1) from None

    return wrapper


def _check_output(path: Path | None, flag: str = "-o", *, folder: bool = False,
                  figure: bool = False) -> None:
    """Refuse, before any work, an output that cannot be written: a file output whose folder
    is missing, is no folder or is not writable, or that is itself a folder; a ``folder``
    output (``batch -o``, created with its parents) that is a file or whose nearest existing
    folder is not writable; a ``figure`` whose suffix is no format matplotlib writes (no
    suffix is PNG, as the plot writers save it). Writability is tried (a temporary file made
    and removed there), not guessed from permission bits, which say yes to root on read-only or
    virtual file systems. The error names the user's path and its folder, as a
    :class:`ParameterError` (one line, exit status 2)."""
    import tempfile

    if path is None:
        return
    if figure and path.suffix:
        # matplotlib only here: a figure was asked for (the CLI's start-up does not import it)
        from matplotlib.backend_bases import FigureCanvasBase

        kinds = sorted(FigureCanvasBase.get_supported_filetypes())
        if path.suffix[1:].lower() not in kinds:
            raise ParameterError(f"{flag} {path}: {path.suffix} is not a figure format; give "
                                 f"one of {', '.join('.' + k for k in kinds)}")
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
          sort: bool, uniform: bool = True, decimal: str | None = None):
    from vibrospeed.batch import load_recording

    return load_recording(path, fmt, columns, mapping, rate, sort, uniform, decimal=decimal)


def _params(method: str, preset: str | None, param: list[str] | None) -> dict[str, str]:
    """The estimator parameters: the preset's, then the -p flags over them; a value its types
    cannot read is refused here, before any work, with the line ``batch`` refuses it with
    (:func:`vibrospeed.estimators.params.check_values`)."""
    from vibrospeed import presets
    from vibrospeed.config import parse_params
    from vibrospeed.estimators.params import check_values

    params = presets.apply(method, preset, parse_params(param))
    check_values(method, params)
    return params


def _unknown_hint(method: str, exc: ParameterError) -> ParameterError:
    """An unknown-parameter error from one of a method's nested Configs, its suggestions taken
    from all of the method's parameter names (the flat ``-p`` namespace,
    :func:`vibrospeed.estimators.parameters`). A name that only another tracker of the method
    takes (``-m aided -p amp0=1`` with the grid tracker) is said to be that tracker's, with the
    flag that picks it: the merged names held it, so it was "did you mean 'amp0'"."""
    import re

    from vibrospeed import estimators
    from vibrospeed.config import unknown
    from vibrospeed.estimators.params import other_trackers_name

    m = re.match(r"unknown parameter '([^']+)' for \w+", str(exc))
    if m is None or method not in estimators.METHODS:
        return exc
    name = m.group(1)
    # the tracker in use refused it, so a name one tracker alone takes is the other one's (the
    # batch refuses it so before it starts: EstimateOptions.check_params)
    other = other_trackers_name(method, name)
    if other is not None:
        return other
    return unknown(name, f"method '{method}'", estimators.parameters(method))
