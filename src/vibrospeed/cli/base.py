"""What the ``vibrospeed`` commands share: the Typer ``app`` (its help text and ``--version``),
the rich consoles, :func:`_friendly` (a library error becomes one line on stderr and exit
status 2, a bug one line and exit 1), reading a recording as the CLI does, the option types
common to several commands (input format, column mapping, preset, ``-p``, method, axis, wheel
radius) and the ``-p`` parameters with the preset applied. The commands themselves are in
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
        "Typical session:\n\n"
        "  vibrospeed simulate --scenario cart -o drive.csv\n\n"
        "  vibrospeed estimate drive.csv --method ekf -o est.csv --plot est.png\n\n"
        "  vibrospeed evaluate est.csv --truth drive.csv\n\n"
        "  vibrospeed estimate phone_drive/ --format phyphox --axis y --wheel-radius 0.31 "
        "-o est.csv\n\n"
        "Units are SI: omega in rad/s, speed in m/s, time in s."
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
        except Exception as exc:  # a bug, not bad input: one line, exit 1, traceback on demand
            if os.environ.get("VIBROSPEED_DEBUG"):
                raise
            print(f"vibrospeed: internal error: {type(exc).__name__}: {exc} (please report it; "
                  "set VIBROSPEED_DEBUG=1 for the traceback)", file=sys.stderr)
            raise typer.Exit(1) from None

    return wrapper


def _load(path: Path, fmt: str, columns: str | None, mapping: Path | None, rate: float | None,
          sort: bool, uniform: bool = True):
    from vibrospeed.batch import load_recording

    return load_recording(path, fmt, columns, mapping, rate, sort, uniform)


# ---- option types shared by commands ------------------------------------------------------
FormatOpt = Annotated[str, typer.Option("--format", "-f", help="input format: auto (detect), "
                      "csv (canonical: header t,ax,ay,...), mapped (any CSV with --columns or "
                      "--mapping), phyphox (folder or zip), sensorlogger (Sensor Logger folder or "
                      "zip), sensorfusion (app log), rosbag (ROS 1 .bag or ROS 2 folder), gopro "
                      "(GoPro MP4 telemetry), parquet, androsensor, comma2k19, f1tenth; see "
                      "docs/formats.md")]
TopicOpt = Annotated[str | None, typer.Option("--topic", help="ROS bags: the IMU topic to read "
                     "(default: the busiest sensor_msgs/Imu topic)")]
ColumnsOpt = Annotated[str | None, typer.Option(help="generic CSV column mapping, e.g. "
                       "'t=time,ay=acc_y:g' (name=column[:unit])")]
MappingOpt = Annotated[Path | None, typer.Option("--mapping", help="TOML file with the column "
                       "mapping, units and scales")]
RateOpt = Annotated[float | None, typer.Option(help="sample rate in Hz for files without a time "
                    "column")]
SortOpt = Annotated[bool, typer.Option("--sort", help="sort by time and drop duplicate time "
                    "stamps instead of refusing time that goes backwards")]


def _preset_help() -> str:
    from vibrospeed.presets import PRESETS

    per = "; ".join(f"{m}: {', '.join(p)}" for m, p in PRESETS.items())
    return (f"named parameter set of the method, applied before -p (an explicit -p wins): {per} "
            "(`vibrospeed methods` shows what each sets)")


PresetOpt = Annotated[str | None, typer.Option("--preset", help=_preset_help())]
ParamOpt = Annotated[list[str] | None, typer.Option("--param", "-p", help="estimator parameter "
                     "NAME=VALUE (repeatable; lists by comma, e.g. -p comb_rates=-0.1,0.1); "
                     "`vibrospeed methods` lists each method's parameters")]


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


MethodOpt = Annotated[str, typer.Option("--method", "-m", help="estimator (see `vibrospeed "
                      "methods`; default grid)")]
AxisOpt = Annotated[str | None, typer.Option(help="vibration axis (x, y, z or a channel name; "
                    "default y); for gps-riss the longitudinal axis (default x)")]
RadiusOpt = Annotated[float | None, typer.Option(help="wheel radius in m (gives speed)")]
