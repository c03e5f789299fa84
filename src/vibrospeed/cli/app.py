# Over 500 lines: the command line's subcommands, each a short function over the library, with
# their --help texts and examples; one place to read what the CLI offers.
"""The ``vibrospeed`` commands: simulate, estimate, batch, report, evaluate, plot, methods."""

from __future__ import annotations

import functools
import json
import os
import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

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


@app.command()
@_friendly
def simulate(
    output: Annotated[Path | None, typer.Option("-o", "--output",
                                                help="output file (.csv or .parquet)")] = None,
    scenario: Annotated[str, typer.Option(help="scenario name (see --list)")] = "cart",
    seed: Annotated[int, typer.Option(help="random seed (same seed, same drive)")] = 0,
    duration: Annotated[float | None, typer.Option(help="length in s (scenario default)")] = None,
    fs: Annotated[float | None, typer.Option(help="accelerometer sample rate in Hz (scenario "
                  "default: 100, GPS scenarios 400)")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="override a scenario knob, "
                    "NAME=VALUE (repeatable; dotted for nested knobs, lists by comma: "
                    "--set vibration.harmonic_amps=0.1,0.05)")] = None,
    list_: Annotated[bool, typer.Option("--list", help="list scenarios and exit")] = False,
) -> None:
    """Simulate a drive with ground truth (omega_true, speed_true) and write it.

    Examples:

      vibrospeed simulate --scenario cart -o cart.csv

      vibrospeed simulate --scenario car --seed 3 --duration 120 -o car.parquet

      vibrospeed simulate --scenario car --set M=4 -o car.csv

      vibrospeed simulate --scenario random --seed 7 -o drive7.csv   (the randomised family)

      vibrospeed simulate --list
    """
    from vibrospeed import io, sim
    from vibrospeed.config import parse_params

    if list_:
        for name, desc in sim.describe().items():
            out.print(f"{name:14s} {desc}")
        return
    if output is None:
        raise ParameterError("simulate: missing -o / --output (the file to write)")
    kw = {} if fs is None else {"fs": fs}
    rec = sim.simulate(scenario, seed=seed, duration=duration, **kw, **parse_params(set_))
    io.write(rec, output)
    err.print(f"wrote {output}: {len(rec)} samples, {rec.duration:.1f} s at {rec.fs:.4g} Hz, "
              f"channels {', '.join(rec.channels)}")


def _default_method(input: Path, *, radius_from, preset, param, grid_only: bool, plot: bool,
                    fmt, columns, mapping, rate, sort, topic):
    """``vibrospeed estimate``'s method without ``--method``: ``fuse`` where the recording has
    GPS speed (:func:`vibrospeed.estimators.fuse.suits`; a note says so), else ``grid``. Grid
    options (``grid_only``, a preset fuse lacks) keep ``grid``, and so does a log the grid
    streams (fuse holds the whole log in memory). Returns the method and the recording where
    it was read to decide (then not read again), else None."""
    from vibrospeed import presets
    from vibrospeed.batch import load_recording
    from vibrospeed.config import parse_params
    from vibrospeed.estimators import fuse
    from vibrospeed.estimators.grid import stream

    if radius_from is not None:
        return "fuse", None
    if grid_only or (preset is not None and preset not in presets.presets("fuse")):
        return "grid", None
    plain = not (columns or mapping or rate or sort or topic)
    if stream.wants_stream(input, method="grid", params=_params("grid", preset, param), fmt=fmt,
                           plain_read=plain, plot=plot):
        return "grid", None
    rec = load_recording(input, fmt, columns, mapping, rate, sort, topic=topic)
    if not fuse.suits(rec, str(parse_params(param).get("accel_axis", "x"))):
        return "grid", rec
    err.print("note: the recording has GPS speed: method fuse (vibration + acceleration + GPS, "
              "one speed with its source per sample, wheel radius learned); -m grid for the "
              "vibration tracker alone")
    return "fuse", rec


@app.command()
@_friendly
def estimate(
    input: Annotated[Path, typer.Argument(help="recording: file, folder or zip")],
    output: Annotated[Path, typer.Option("-o", "--output", help="estimate CSV (t, omega, "
                      "omega_lo, omega_hi, speed, ...) + a .json sidecar")],
    method: Annotated[str | None, typer.Option("--method", "-m", help="estimator (see "
                      "`vibrospeed methods`); default: fuse where the recording has GPS speed "
                      "and ax, else grid, the most robust one-accelerometer tracker")] = None,
    axis: Annotated[str | None, typer.Option(help="vibration axis (x, y, z or a channel name; "
                    "default y); for gps-riss the longitudinal axis (default x)")] = None,
    wheel_radius: Annotated[float | None, typer.Option(help="wheel radius in m (gives speed)")]
    = None,
    radius_from: Annotated[Path | None, typer.Option(
        "--radius-from", help="fuse: wheel radius prior from an earlier fuse estimate's .json "
        "sidecar of the same vehicle (m/s from vibration without GPS)")] = None,
    init_omega: Annotated[float | None, typer.Option(help="initial omega guess in rad/s (EKF "
                          "start; rbpmf/grid: centre of the initial prior)")] = None,
    preset: PresetOpt = None,
    param: ParamOpt = None,
    plot: Annotated[Path | None, typer.Option(help="also write a spectrogram plot (PNG)")] = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="offline: forward-backward smoothing "
                      "on the grid (rbpmf, grid; uses the whole log, so the past sees the "
                      "future; grid smooths by default)")]
    = False,
    lag: Annotated[float | None, typer.Option(help="fixed-lag smoothing with this delay in s "
                   "(rbpmf, grid; for devices that can wait)")] = None,
    fit_params: Annotated[bool, typer.Option("--fit-params", help="fit q_omega, q_amp and r to "
                          "this recording by marginal likelihood first (rbpmf, grid)")] = False,
    fmt: FormatOpt = "auto",
    topic: TopicOpt = None,
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    sort: SortOpt = False,
) -> None:
    """Estimate omega / speed over a whole recording.

    Without --method: fuse (vibration + acceleration + GPS) where the recording has a GPS speed
    channel with fixes and ax (forward), else grid; grid too with --smooth, --lag,
    --fit-params, --init-omega, a grid-only preset or a log long enough to be streamed.

    Non-uniform (phone) time stamps are resampled to the median rate by linear interpolation;
    NaN samples are bridged by prediction. The band columns are a 98 % credible interval.

    Examples:

      vibrospeed estimate drive.csv -o est.csv --plot est.png   (grid; fuse with GPS speed)

      vibrospeed estimate cart.csv -p omega_min=2 -p omega_max=30 -o est.csv

      (the grid covers 10-120 rad/s, a car's wheels; give a slow vehicle's range, v / r)

      vibrospeed estimate drive.csv -p comb_axes=all -o est.csv

      (comb evidence from ax, ay and az together; tracking stays on --axis)

      vibrospeed estimate drive.csv --preset lock -o est.csv

      (causal tracker switched on while the vehicle moves; `vibrospeed methods grid`)

      vibrospeed estimate drive.csv --preset online -o est.csv   (causal, no smoothing)

      vibrospeed estimate drive.csv -m rbpmf --preset paper -o est.csv   (the paper's filter)

      vibrospeed estimate drive.csv --method ekf --init-omega 10 -o est.csv

      vibrospeed estimate rsq_q2_00/ --format phyphox --axis y -o est.csv

      vibrospeed estimate kart.csv --columns ax=c1,ay=c2,az=c3 --rate 198.4 -o est.csv

      vibrospeed estimate kart.csv --columns ax=c1,ay=c2,az=c3 --rate 198.4 --axis z
      -p omega_min=60 -p omega_max=300 -p prefilter=paper-hp -p M=2 -o est.csv

      (range: v / r for the kart's speeds and radius; M = 2: its line has a weak 2nd only)

      vibrospeed estimate drive.csv -p smooth=none -o est.csv   (causal grid filter, online)

      vibrospeed estimate drive.csv --method rbpmf --smooth -p improved=true -o est.csv

      vibrospeed estimate drive.csv -m fuse -o est.csv   (vibration + acceleration + GPS)

      vibrospeed estimate nogps.csv -m fuse --radius-from est.csv.json -o est2.csv
    """
    from vibrospeed.batch import EstimateOptions, estimate_recording, vibration_channel

    rec = None  # the recording, where choosing the method read it
    if method is None:
        method, rec = _default_method(input, radius_from=radius_from, preset=preset,
                                      param=param, grid_only=smooth or lag is not None
                                      or fit_params or init_omega is not None,
                                      plot=plot is not None, fmt=fmt, columns=columns,
                                      mapping=mapping, rate=rate, sort=sort, topic=topic)
    if radius_from is not None:
        if method != "fuse":
            raise ParameterError("--radius-from is for --method fuse (the radius it learned)")
        param = [*(param or []), f"radius_from={radius_from}"]

    opts = EstimateOptions(method=method, params=_params(method, preset, param), axis=axis,
                           wheel_radius=wheel_radius, init_omega=init_omega, smooth=smooth,
                           lag=lag, fit_params=fit_params, fmt=fmt, columns=columns,
                           mapping=mapping, rate=rate, sort=sort, topic=topic)
    from vibrospeed.estimators.grid import stream

    try:
        if rec is None and stream.wants_stream(
                input, method=method, params=opts.estimator_params(), fmt=fmt,
                plain_read=not (columns or mapping or rate or sort or topic),
                plot=plot is not None):  # a long log: in blocks, bounded memory
            st = stream.estimate_file(input, output, params=opts.estimator_params(), axis=axis,
                                      wheel_radius=wheel_radius, fmt=fmt,
                                      meta={"preset": preset}, progress=sys.stderr.isatty())
            for note in st.recording_notes + st.notes:
                err.print(f"note: {note}")
            err.print(f"wrote {output} ({st.rows} rows, method {method}, in blocks)")
            return
        est = estimate_recording(input, output, opts, progress=sys.stderr.isatty(),
                                 keep_posterior=plot is not None, meta={"preset": preset},
                                 recording=rec)
    except ParameterError as exc:
        raise _unknown_hint(method, exc) from None
    rec, track = est.recording, est.track
    for note in rec.notes + track.notes:
        err.print(f"note: {note}")
    err.print(f"wrote {output} ({len(track)} rows, method {method})")
    if plot is not None:
        from vibrospeed.eval.plot import plot_track

        plot_track(plot, rec, track, axis=vibration_channel(rec, est.axis),
                   posterior=est.grids.get("posterior"), grid=est.grids.get("grid"))
        err.print(f"wrote {plot}")


MethodOpt = Annotated[str, typer.Option("--method", "-m", help="estimator (see `vibrospeed "
                      "methods`; default grid)")]
AxisOpt = Annotated[str | None, typer.Option(help="vibration axis (x, y, z or a channel name; "
                    "default y); for gps-riss the longitudinal axis (default x)")]
RadiusOpt = Annotated[float | None, typer.Option(help="wheel radius in m (gives speed)")]


@app.command()
@_friendly
def batch(
    inputs: Annotated[list[str], typer.Argument(help="recordings: files, folders (a folder "
                      "that is a recording, e.g. a phyphox export, counts as one) and glob "
                      "patterns ('logs/**/*.csv', quoted)")],
    output: Annotated[Path, typer.Option("-o", "--output", help="output folder: one estimate "
                      "(.csv + .json) per recording, summary.csv and summary.parquet")],
    method: MethodOpt = "grid",
    axis: AxisOpt = None,
    wheel_radius: RadiusOpt = None,
    init_omega: Annotated[float | None, typer.Option(help="initial omega guess in rad/s")]
    = None,
    preset: PresetOpt = None,
    param: ParamOpt = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="as for estimate (rbpmf, grid)")]
    = False,
    lag: Annotated[float | None, typer.Option(help="as for estimate (rbpmf, grid)")] = None,
    fit_params: Annotated[bool, typer.Option("--fit-params", help="as for estimate (rbpmf, "
                          "grid)")] = False,
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", help="local worker processes "
                    "(default min(4, CPU count); 1 runs in this process)")] = None,
    scheduler: Annotated[str | None, typer.Option(help="run on a Dask cluster: its scheduler "
                         "address, e.g. tcp://10.0.0.5:8786 (workers must see the same files)")]
    = None,
    report: Annotated[bool, typer.Option("--report", help="also one HTML report per recording "
                      "and an index.html linking them")] = False,
    force: Annotated[bool, typer.Option("--force", help="estimate again even where an "
                     "up-to-date output exists")] = False,
    fmt: FormatOpt = "auto",
    topic: TopicOpt = None,
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    sort: SortOpt = False,
) -> None:
    """Estimate many recordings with the same options; write a summary table.

    Each recording gets <name>_<method>.csv and .json in the output folder (two inputs with the
    same name get a short hash added). summary.csv (and summary.parquet with pyarrow) has per
    recording: file, format, duration, method, share with a wheel line, median speed,
    distance, status (ok / skipped / error), the error in one line and the wall time. Run it
    again and every recording whose output has the same input checksum, method, options and
    vibrospeed version is skipped; a bad file is an error row, never the end of the batch (exit
    status 2 when any recording failed).

    Examples:

      vibrospeed batch 'logs/*.csv' -o out -p omega_min=2 -p omega_max=30

      vibrospeed batch 'logs/*.csv' -o out --preset online   (causal estimates)

      vibrospeed batch phone_logs/ --format phyphox --axis y -o out --report

      vibrospeed batch 'fleet/**/*.parquet' -o out --scheduler tcp://10.0.0.5:8786
    """
    from vibrospeed import batch as vb

    opts = vb.EstimateOptions(method=method, params=_params(method, preset, param), axis=axis,
                              wheel_radius=wheel_radius, init_omega=init_omega, smooth=smooth,
                              lag=lag, fit_params=fit_params, fmt=fmt, columns=columns,
                              mapping=str(mapping) if mapping is not None else None, rate=rate,
                              sort=sort, topic=topic)
    if jobs is not None and jobs < 1:
        raise ParameterError(f"--jobs must be at least 1, got {jobs}")
    df = vb.run(inputs, output, options=opts, scheduler=scheduler, jobs=jobs, report=report,
                force=force, progress=True)
    for _, r in df[df["status"] == "error"].iterrows():  # one line each, never wrapped
        msg = r["error"] if str(r["file"]) in r["error"] else f"{r['file']}: {r['error']}"
        print(f"vibrospeed: error: {msg}", file=sys.stderr)
    counts = df["status"].value_counts()
    said = ", ".join(f"{counts.get(k, 0)} {k}" for k in ("ok", "skipped", "error"))
    extra = " + index.html and a report per recording" if report else ""
    print(f"wrote {output / 'summary.csv'}{extra}: {len(df)} recordings ({said})",
          file=sys.stderr)
    if counts.get("error", 0):
        raise typer.Exit(2)


@app.command()
@_friendly
def report(
    input: Annotated[Path, typer.Argument(help="recording: file, folder or zip")],
    output: Annotated[Path, typer.Option("-o", "--output", help="HTML page to write")],
    estimate_csv: Annotated[Path | None, typer.Option("--estimate", help="estimate CSV "
                            "(from `estimate`); without it the recording is estimated first "
                            "with --method and -p")] = None,
    truth: Annotated[Path | None, typer.Option(help="truth recording (default: the input's "
                     "omega_true / speed_true if any)")] = None,
    method: MethodOpt = "grid",
    axis: AxisOpt = None,
    wheel_radius: RadiusOpt = None,
    preset: PresetOpt = None,
    param: ParamOpt = None,
    fmt: FormatOpt = "auto",
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    sort: SortOpt = False,
) -> None:
    """One self-contained HTML page for a drive: spectrogram with the estimate, band and truth
    or GPS, speed over time, where a wheel line was seen, notes, summary numbers.

    Images are embedded in the page; it has no external links and no scripts.

    Examples:

      vibrospeed report drive.csv --estimate est.csv -o drive.html

      vibrospeed report drive.csv -p omega_min=2 -p omega_max=30 -o drive.html
    """
    import tempfile

    from vibrospeed import batch as vb
    from vibrospeed import io
    from vibrospeed.eval.report import write_report

    ref = io.read(truth) if truth else None
    if estimate_csv is not None:
        rec = _load(input, fmt, columns, mapping, rate, sort)
        track = io.read_track(estimate_csv)
        side_path = Path(f"{estimate_csv}.json")
        meta = {}
        if side_path.is_file():
            try:
                meta = json.loads(side_path.read_text(encoding="utf-8")).get("meta") or {}
            except (OSError, ValueError):
                meta = {}
        used_axis = axis or meta.get("axis")
        grids: dict = {}
    else:
        opts = vb.EstimateOptions(method=method, params=_params(method, preset, param),
                                  axis=axis,
                                  wheel_radius=wheel_radius, fmt=fmt, columns=columns,
                                  mapping=mapping, rate=rate, sort=sort)
        with tempfile.TemporaryDirectory(prefix="vibrospeed-") as d:
            est = vb.estimate_recording(input, Path(d) / "estimate.csv", opts,
                                        keep_posterior=True, progress=sys.stderr.isatty())
        rec, track, used_axis, grids = est.recording, est.track, est.axis, est.grids
    write_report(output, rec, track, axis=vb.vibration_channel(rec, used_axis), truth=ref,
                 posterior=grids.get("posterior"), grid=grids.get("grid"),
                 title=input.name or str(input), input_path=input, estimate_path=estimate_csv)
    err.print(f"wrote {output}")


@app.command()
@_friendly
def evaluate(
    estimate_csv: Annotated[Path, typer.Argument(help="estimate written by `estimate`")],
    truth: Annotated[Path, typer.Option(help="recording with omega_true or speed_true")],
    truth_format: Annotated[str, typer.Option(help="format of the truth file")] = "auto",
    min_omega: Annotated[float, typer.Option(help="truth below this (rad/s) = standing, "
                         "excluded")] = 1.0,
    warmup: Annotated[float, typer.Option(help="seconds at the start excluded")] = 0.0,
    json_out: Annotated[Path | None, typer.Option("--json", help="also write metrics as JSON")]
    = None,
) -> None:
    """Compare an estimate with ground truth: RMSE (thesis eq. 3.18, truth linearly
    interpolated, moving samples only), bias, relative error, band coverage, harmonic errors.

    Example:

      vibrospeed evaluate est.csv --truth drive.csv
    """
    from vibrospeed import io
    from vibrospeed.eval.metrics import evaluate as ev
    from vibrospeed.io.atomic import atomic_write_text

    track = io.read_track(estimate_csv)
    ref = io.read(truth, truth_format)
    m = ev(track, ref, min_omega=min_omega, warmup=warmup)
    tab = Table(title=f"{estimate_csv.name} vs truth {truth.name}", title_justify="left")
    tab.add_column("metric")
    tab.add_column("value", justify="right")
    tab.add_column("unit")
    rows = [
        ("samples evaluated (moving)", f"{m.n}", ""),
        ("moving share", f"{m.moving_share:.1%}", ""),
        ("RMSE", f"{m.rmse:.3f}", m.unit),
        ("MAE", f"{m.mae:.3f}", m.unit),
        ("bias", f"{m.bias:+.3f}", m.unit),
        ("relative error", f"{m.rel_error:.1%}", ""),
        (f"coverage of the {m.level:.0%} band",
         f"{m.coverage:.1%}" if m.coverage == m.coverage else "n/a (no band)", ""),
    ]
    if m.unit != "m/s":
        rows += [("share within max(2 rad/s, 10 %)", f"{m.ok_share:.1%}", ""),
                 ("share at omega/2", f"{m.half_share:.1%}", ""),
                 ("share at 2 omega", f"{m.double_share:.1%}", "")]
    if m.claimed_share == m.claimed_share:
        rows += [("share where it claims a signal", f"{m.claimed_share:.1%}", ""),
                 ("  RMSE there", f"{m.rmse_claimed:.3f}", m.unit),
                 ("  within max(2 rad/s, 10 %) there", f"{m.ok_claimed:.1%}", ""),
                 ("  band coverage there", f"{m.coverage_claimed:.1%}", "")]
    if m.rmse_speed == m.rmse_speed and m.unit != "m/s":
        rows.append(("RMSE speed", f"{m.rmse_speed:.3f}", "m/s"))
    for row in rows:
        tab.add_row(*row)
    out.print(tab)
    if json_out is not None:
        atomic_write_text(json_out, json.dumps(m.to_dict(), indent=2))


@app.command()
@_friendly
def plot(
    input: Annotated[Path, typer.Argument(help="recording: file, folder or zip")],
    output: Annotated[Path, typer.Option("-o", "--output", help="PNG to write")],
    estimate_csv: Annotated[Path | None, typer.Option("--estimate", help="estimate CSV to "
                            "draw over the spectrogram")] = None,
    truth: Annotated[Path | None, typer.Option(help="truth recording (default: the input's "
                     "omega_true if any)")] = None,
    axis: Annotated[str, typer.Option(help="channel or axis for the spectrogram")] = "y",
    harmonics: Annotated[int, typer.Option(help="harmonics of the estimate to draw")] = 3,
    window: Annotated[float, typer.Option(help="STFT window in s")] = 3.0,
    fmt: FormatOpt = "auto",
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    sort: SortOpt = False,
) -> None:
    """Spectrogram of a vibration axis with the estimate, its band, harmonics and truth.

    Example:

      vibrospeed plot drive.csv --estimate est.csv -o drive.png
    """
    from vibrospeed import io
    from vibrospeed.estimators.common import axis_channel
    from vibrospeed.eval.plot import plot_track

    rec = _load(input, fmt, columns, mapping, rate, sort)
    track = io.read_track(estimate_csv) if estimate_csv else None
    ref = io.read(truth) if truth else None
    plot_track(output, rec, track, axis=axis_channel(axis), truth=ref, harmonics=harmonics,
               window_s=window)
    err.print(f"wrote {output}")


@app.command()
@_friendly
def truth(
    ticks: Annotated[Path, typer.Argument(help="cog-wheel tick times: a one-column CSV (s), or "
                     "a recording with a wss_ticks event stream (--from-recording)")],
    output: Annotated[Path, typer.Option("-o", "--output", help="truth recording to write "
                      "(t, omega_true, speed_true)")],
    cogs: Annotated[int, typer.Option(help="cogs per revolution of the sensor wheel")] = 12,
    r_sensor: Annotated[float, typer.Option(help="radius of the cog wheel in m")] = 0.0625,
    r_wheel: Annotated[float, typer.Option(help="radius of the vehicle wheel in m")] = 0.08,
    scale: Annotated[float, typer.Option(help="multiply tick values (1e-3 for ms)")] = 1.0,
    spike_rel: Annotated[float, typer.Option(help="relative size of a single-sample spike "
                         "replaced by its neighbours' mean (0 = off)")] = 0.3,
    max_gap: Annotated[float, typer.Option(help="a longer tick interval (s) means standstill")]
    = 0.5,
    from_recording: Annotated[bool, typer.Option("--from-recording", help="read the ticks from "
                              "the wss_ticks events of a recording")] = False,
) -> None:
    """Ground truth omega from a cog-wheel speed sensor (thesis appendix B.4).

    Tick intervals give omega = 2 pi / (cogs dt) * r_sensor / r_wheel; single-sample spikes
    (missed or doubled cogs) are replaced by the mean of their neighbours.

    Examples:

      vibrospeed truth ticks.csv --cogs 12 --r-sensor 0.0625 --r-wheel 0.08 -o truth.csv

      vibrospeed evaluate est.csv --truth truth.csv
    """
    from vibrospeed import io
    from vibrospeed.eval import truth as tr

    kw = dict(n_cogs=cogs, r_sensor=r_sensor, r_wheel=r_wheel, spike_rel=spike_rel,
              max_gap=max_gap)
    if from_recording:
        rec = tr.truth_from_recording(io.read(ticks), **kw)
    else:
        rec = tr.ticks_to_truth(tr.read_ticks(ticks, scale=scale), source=str(ticks), **kw)
    io.write(rec, output)
    for note in rec.notes:
        err.print(f"note: {note}")
    err.print(f"wrote {output}: {len(rec)} truth samples over {rec.duration:.1f} s")


@app.command()
@_friendly
def info(
    input: Annotated[Path, typer.Argument(help="recording: file, folder or zip")],
    fmt: FormatOpt = "auto",
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    sort: SortOpt = False,
) -> None:
    """Describe a recording: format, time line, channels with units and ranges, what the reader
    did, and which methods it can feed.

    Example:

      vibrospeed info ../shared/datasets/hungary_car_phyphox/rsq_q2_00
    """
    from vibrospeed.io.timebase import describe_timebase

    rec = _load(input, fmt, columns, mapping, rate, sort, uniform=False)
    out.print(f"{rec.source or input}: {len(rec)} samples, {rec.duration:.2f} s, "
              f"median rate {rec.fs:.4g} Hz" + (f", wheel radius {rec.wheel_radius} m"
                                                 if rec.wheel_radius else ""))
    tab = Table(title_justify="left")
    for col in ("channel", "unit", "finite", "min", "median", "max"):
        tab.add_column(col, justify="left" if col in ("channel", "unit") else "right")
    for name, x in rec.channels.items():
        ok = np.isfinite(x)
        if ok.any():
            lo, med, hi = np.percentile(x[ok], [0, 50, 100])
            tab.add_row(name, rec.units.get(name, ""), f"{ok.mean():.1%}", f"{lo:.4g}",
                        f"{med:.4g}", f"{hi:.4g}")
        else:
            tab.add_row(name, rec.units.get(name, ""), "0%", "", "", "")
    out.print(tab)
    for name, ev in rec.events.items():
        out.print(f"event stream {name}: {ev.size} events")
    notes = list(rec.notes)
    notes += [n for n in describe_timebase(rec) if n not in notes]
    for note in notes:
        out.print(f"note: {note}", markup=False)
    ch = set(rec.channels)
    uses = []
    if ch & {"ax", "ay", "az"}:
        top = np.pi * rec.fs / 2  # highest omega with M = 2 harmonics below Nyquist
        limit = "" if top >= 120 else f"; only up to omega = {top:.0f} rad/s at this rate, M = 2"
        axes = sorted(ch & {"ax", "ay", "az"})
        both = f"; grid -p comb_axes=all reads {', '.join(axes)} together" if len(axes) > 1 else ""
        uses.append(f"ekf, rbpmf, grid, rbpf, shs (vibrations{limit}{both})")
    if "ax" in ch or "ay" in ch:
        uses.append("aided (with a longitudinal axis and the wheel radius)")
    if "gps_speed" in ch:
        uses.append("gps-riss")
    if {"gz", "ax", "ay"} <= ch and all(f"wheel_omega_{w}" in ch for w in ("fl", "fr", "rl", "rr")):
        uses.append("algebraic")
    out.print("can feed: " + ("; ".join(uses) if uses else "no estimator (no known channel)"),
              markup=False)


@app.command()
@_friendly
def methods(
    method: Annotated[str | None, typer.Argument(help="one method to describe (default: all)")]
    = None,
) -> None:
    """List the estimators: what each needs, its presets (--preset) and its parameters (-p).

    Examples:

      vibrospeed methods

      vibrospeed methods grid
    """
    from vibrospeed import presets
    from vibrospeed.estimators import METHODS, available, get

    have = available()
    names = have if method is None else [method]
    if method is not None:
        get(method)  # an unknown method is the usual one-line error
    for name in names:
        desc = METHODS[name][1]
        print(f"{name}: {desc}")
        table = presets.presets(name)
        print("  presets (--preset NAME):")
        width = max(len(p) for p in table)
        for pname, pre in table.items():
            flags = presets.as_flags(pre.params) or "(nothing set)"
            print(f"    {pname:{width}s}  {pre.about}")
            print(f"    {'':{width}s}  = {flags}")
        params = presets.PARAMETERS.get(name, {})
        if params:
            print("  parameters (-p NAME=VALUE; all of them: the reference pages):")
            width = max(len(k) + len(v.example) + 1 for k, v in params.items())
            for pname, par in params.items():
                print(f"    {pname + '=' + par.example:{width}s}  {par.about}")
        print()
