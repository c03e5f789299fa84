"""The command-line options that several ``vibrospeed`` commands take, each declared once as
an ``Annotated`` type (flag names and help text; the default stays at the command, where Typer
reads it): the recording argument, the input format and its column mapping, the estimator
(method, axis, wheel radius), the preset and the ``-p`` parameters.

A command lists the ones it takes, e.g. ``fmt: FormatOpt = "auto"``, so the same flag reads and
behaves the same in ``estimate``, ``batch``, ``report``, ``plot`` and ``info``. An option that
means something different in one command (``plot --axis`` is the spectrogram's channel, default
``y``) is declared there."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import typer


def at_least(what: str, unit: str = "", lo: float = 0.0, *, strict: bool = True):
    """A Typer option callback that refuses, while the command line is parsed (before any work),
    a value that is not finite or not ``> lo`` (``>= lo`` where not ``strict``): one line on
    stderr naming the flag, what it is and the value, exit status 2. None (not given) passes.
    ``at_least("wheel radius", "m")`` turns ``--wheel-radius -1`` (or 0, nan, inf) into
    ``vibrospeed: error: --wheel-radius: wheel radius must be > 0 m, got -1``."""
    rel = ">" if strict else ">="
    bound = f"{lo:g}" + (f" {unit}" if unit else "")

    def check(param: typer.CallbackParam, value):
        if value is None:
            return value
        v = float(value)
        if not (math.isfinite(v) and (v > lo if strict else v >= lo)):
            flag = max(param.opts, key=len) if param.opts else param.name
            print(f"vibrospeed: error: {flag}: {what} must be {rel} {bound}, got {value:g}",
                  file=sys.stderr)
            raise typer.Exit(2)
        return value

    return check


# ---- the recording ----------------------------------------------------------------------------
InputArg = Annotated[Path, typer.Argument(help="recording: file, folder or zip")]
FormatOpt = Annotated[str, typer.Option("--format", "-f", help="input format: auto (detect), "
                      "csv (canonical: header t,ax,ay,...), mapped (any CSV with --columns or "
                      "--mapping), phyphox (folder or zip), sensorlogger (Sensor Logger folder or "
                      "zip), sensorfusion (app log), rosbag (ROS 1 .bag or ROS 2 folder), gopro "
                      "(GoPro MP4 telemetry), parquet, androsensor, comma2k19, f1tenth; see "
                      "docs/formats.md")]
TopicOpt = Annotated[str | None, typer.Option("--topic", help="ROS bags: the IMU topic to read "
                     "(default: the busiest sensor_msgs/Imu topic)")]


def _columns_help() -> str:
    from vibrospeed.io.mapped import UNITS

    return ("generic CSV column mapping: comma-separated NAME=COLUMN[*SCALE][:UNIT] items; NAME "
            "is a channel (t in s; ax, ay, az in m/s^2; gx, gy, gz in rad/s; gps_speed in m/s; "
            "...), COLUMN the file's header name, SCALE multiplies the raw value, UNIT converts "
            "it to SI (scale first, then unit), e.g. --columns "
            "'t=time:ms,ay=acc_y:g,gz=yaw*0.01:deg/s'; without a time column give --rate. "
            f"Units: {', '.join(UNITS)}. Offsets: a --mapping TOML file (docs/formats.md)")


ColumnsOpt = Annotated[str | None, typer.Option(help=_columns_help())]
MappingOpt = Annotated[Path | None, typer.Option("--mapping", help="TOML file with the column "
                       "mapping, units and scales")]
RateOpt = Annotated[float | None, typer.Option(help="sample rate in Hz for files without a time "
                    "column", callback=at_least("sample rate", "Hz"))]
def _decimal_mark(param: typer.CallbackParam, value: str | None) -> str | None:
    """``--decimal``'s callback: ``.`` or ``,``, else one line naming the flag and exit status
    2 while the command line is parsed (no other mark reads unambiguously)."""
    if value is not None and value not in (".", ","):
        print(f"vibrospeed: error: --decimal: the decimal mark must be '.' or ',', got "
              f"{value!r}", file=sys.stderr)
        raise typer.Exit(2)
    return value


DecimalOpt = Annotated[str | None, typer.Option(
    "--decimal", help="decimal mark of a CSV's numbers: '.' (default) or ',' for a ';' or tab "
    "separated export that writes 1,5 (canonical CSV or --columns / --mapping); never guessed. "
    "A --mapping file's decimal = \"...\" that says otherwise is refused",
    callback=_decimal_mark)]
SortOpt = Annotated[bool, typer.Option("--sort", help="sort by time and drop duplicate time "
                    "stamps instead of refusing time that goes backwards")]

# ---- the estimator ----------------------------------------------------------------------------
MethodOpt = Annotated[str, typer.Option("--method", "-m", help="estimator (see `vibrospeed "
                      "methods`; default grid)")]
AxisOpt = Annotated[str | None, typer.Option(help="vibration axis (x, y, z or a channel name; "
                    "default y); for gps-riss the longitudinal axis (default x)")]
RadiusOpt = Annotated[float | None, typer.Option(help="wheel radius in m (gives speed = radius * "
                      "omega in m/s), e.g. 0.31 for a car",
                      callback=at_least("wheel radius", "m"))]


def _preset_help() -> str:
    from vibrospeed.presets import PRESETS

    per = "; ".join(f"{m}: {', '.join(p)}" for m, p in PRESETS.items())
    return (f"named parameter set of the method, applied before -p (an explicit -p wins): {per} "
            "(`vibrospeed methods` shows what each sets)")


PresetOpt = Annotated[str | None, typer.Option("--preset", help=_preset_help())]
ParamOpt = Annotated[list[str] | None, typer.Option("--param", "-p", help="estimator parameter "
                     "NAME=VALUE (repeatable; lists by comma, e.g. -p comb_rates=-0.1,0.1); "
                     "`vibrospeed methods` lists each method's parameters")]

#: ``--truth-channel`` of ``evaluate`` and ``report``: one option, so both name and explain it alike
TruthChannelOpt = Annotated[str | None, typer.Option(
    help="the truth file's channel to compare with: omega_true or speed_true (default: "
         "whichever it has), or a speed in m/s such as gps_speed (a phone drive against "
         "its own GPS; no truth between fixes more than 2 s apart)")]
