"""The commands that estimate: ``estimate`` (one recording: the method chosen where none is
given, streamed in blocks when the log is long, an optional plot), ``batch`` (many
recordings through :func:`vibrospeed.batch.run`, a summary table) and ``methods`` (each
estimator's presets and parameters)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import typer

from vibrospeed.cli.base import _check_output, _friendly, _params, _unknown_hint, err
from vibrospeed.cli.options import (
    AxisOpt,
    ColumnsOpt,
    DecimalOpt,
    FormatOpt,
    InputArg,
    MappingOpt,
    MethodOpt,
    ParamOpt,
    PresetOpt,
    RadiusOpt,
    RateOpt,
    SortOpt,
    TopicOpt,
    at_least,
)
from vibrospeed.errors import ParameterError
from vibrospeed.estimators.params import range_note


def _default_method(input: Path, *, radius_from, preset, param, grid_only: bool, plot: bool,
                    fmt, columns, mapping, rate, sort, topic, decimal=None):
    """``vibrospeed estimate``'s method without ``--method``: ``fuse`` where the recording has GPS
    speed (:func:`vibrospeed.estimators.fuse.suits`; a note says so), else ``grid``. Grid
    options (``grid_only``, a preset fuse lacks) keep ``grid``, and so does a log the grid
    streams (fuse holds the whole log in memory; where the recording has GPS speed, a note says
    that too). A preset of neither (``paper``) is refused naming the methods that have it.
    Returns the method, the recording where it was read to decide (then not read again), else
    None, and ``(rows, notes)`` where the log streams (its rows counted once, here), False where
    it was counted and does not, None where it was not counted."""
    import numpy as np

    from vibrospeed import presets
    from vibrospeed.batch import load_recording
    from vibrospeed.config import parse_params
    from vibrospeed.estimators import fuse
    from vibrospeed.estimators.common import signed_axis
    from vibrospeed.estimators.grid import stream

    if radius_from is not None:
        return "fuse", None, None
    if preset is not None and preset not in presets.presets("grid") \
            and preset not in presets.presets("fuse"):
        # "unknown preset 'paper' for method 'grid'" named a method the user never chose
        # (a name no method has stays grid's "unknown preset" error below)
        owners = [m for m in presets.PRESETS if preset in presets.presets(m)]
        if owners:
            raise ParameterError(
                f"--preset {preset} is not a preset of the method chosen without -m (fuse, "
                f"with GPS speed: {', '.join(presets.presets('fuse'))}; grid: "
                f"{', '.join(presets.presets('grid'))}); it is a preset of "
                f"{', '.join(owners)}: give the method with -m")
    if grid_only or (preset is not None and preset not in presets.presets("fuse")):
        return "grid", None, None
    given = parse_params(param)
    accel = str(given.get("accel_axis", "x"))
    channel = signed_axis(accel)[0]

    def _accel_axis_for_grid(why: str) -> None:
        """``-p accel_axis`` is fuse's: where the default falls back to grid, say why (grid
        refused it as "unknown parameter 'accel_axis' for method 'grid'", a method the user
        never chose)."""
        if "accel_axis" in given:
            raise ParameterError(f"-p accel_axis={accel}: {why}")

    def _no_channel(chans) -> None:
        have = ", ".join(c for c in ("ax", "ay", "az") if c in chans) or "no accelerometer"
        _accel_axis_for_grid(f"the recording has no channel '{channel}' (it has {have}) for "
                             "fuse, the default where it has GPS speed")

    rows = stream.stream_rows(input, method="grid", params=_params("grid", preset, param),
                              fmt=fmt, columns=columns, mapping=mapping, rate=rate, sort=sort,
                              topic=topic, plot=plot)
    if rows is not None:
        # fuse.suits from the header: a gps_speed channel with no fix at all is refused by the
        # reader, so a named one has a fix once the file reads
        chans = stream.channel_names(input, fmt, columns=columns, mapping=mapping, rate=rate,
                                     decimal=decimal)
        notes = []
        if "gps_speed" in chans and channel not in chans:
            _no_channel(chans)
        elif "gps_speed" in chans:
            _accel_axis_for_grid(
                f"it is fuse's, and this log's {rows} rows are estimated with grid in blocks "
                "(bounded memory; fuse holds the whole log in memory): -m fuse to fuse it")
            notes.append(f"the recording has GPS speed, but its {rows} rows are estimated with "
                         "grid in blocks (bounded memory; fuse holds the whole log in memory): "
                         "-m fuse to fuse it anyway")
        return "grid", None, (rows, notes)
    rec = load_recording(input, fmt, columns, mapping, rate, sort, topic=topic, decimal=decimal)
    if not fuse.suits(rec, accel):
        if "gps_speed" in rec and np.isfinite(rec.channel("gps_speed")).any():
            _no_channel(rec)  # GPS speed there: the channel is what is missing
        else:
            _accel_axis_for_grid("it is fuse's, the default only where the recording has GPS "
                                 "speed, and this one has none: -m fuse with --wheel-radius, "
                                 "or leave accel_axis out for grid")
        return "grid", rec, False
    err.print("note: the recording has GPS speed: method fuse (vibration + acceleration + GPS, "
              "one speed with its source per sample, wheel radius learned); -m grid for the "
              "vibration tracker alone")
    return "fuse", rec, False


@_friendly
def estimate(
    input: InputArg,
    output: Annotated[Path, typer.Option("-o", "--output", help="estimate CSV (t, omega, "
                      "omega_lo, omega_hi, speed, ...) + a .json sidecar")],
    method: Annotated[str | None, typer.Option("--method", "-m", help="estimator (see "
                      "`vibrospeed methods`); default: fuse where the recording has GPS speed "
                      "and ax, else grid, the most robust one-accelerometer tracker")] = None,
    axis: AxisOpt = None,
    wheel_radius: RadiusOpt = None,
    radius_from: Annotated[Path | None, typer.Option(
        "--radius-from", help="fuse: wheel radius prior from an earlier fuse estimate's .json "
        "sidecar of the same vehicle (m/s from vibration without GPS)")] = None,
    init_omega: Annotated[float | None, typer.Option(help="initial omega guess in rad/s (EKF "
                          "start; rbpmf/grid: centre of the initial prior)",
                          callback=at_least("initial omega", "rad/s", strict=False))] = None,
    preset: PresetOpt = None,
    param: ParamOpt = None,
    plot: Annotated[Path | None, typer.Option(help="also write a spectrogram plot (PNG; on a "
                    "streamed long log a decimated one, no posterior image)")] = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="offline: forward-backward smoothing "
                      "on the grid (rbpmf, grid; uses the whole log, so the past sees the "
                      "future; grid smooths by default)")]
    = False,
    lag: Annotated[float | None, typer.Option(help="fixed-lag smoothing with this delay in s "
                   "(rbpmf, grid; for devices that can wait)",
                   callback=at_least("lag", "s"))] = None,
    fit_params: Annotated[bool, typer.Option("--fit-params", help="fit q_omega, q_amp and r to "
                          "this recording by marginal likelihood first (rbpmf, grid)")] = False,
    fmt: FormatOpt = "auto",
    topic: TopicOpt = None,
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    decimal: DecimalOpt = None,
    sort: SortOpt = False,
) -> None:
    """Estimate omega / speed over a whole recording.

    Without --method: fuse (vibration + acceleration + GPS) where the recording has a GPS speed
    channel with fixes and ax (forward), else grid; grid too with --smooth, --lag,
    --fit-params, --init-omega, a grid-only preset or a log long enough to be streamed (a
    note says so where that log has GPS speed).

    Phone time stamps within 5 % of uniform are estimated at their median rate; more jitter,
    gaps or a rate change are resampled to the median rate by linear interpolation (a note says
    which); NaN samples are bridged by prediction. The band columns are a 98 % credible interval.

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

      vibrospeed estimate logger.csv --columns 't=Zeit:ms,ay=AccY:g' --decimal , -o est.csv

      (a ';'-separated export writing 1,25; a canonical t;ay file takes --decimal , too)

      vibrospeed estimate drive.csv -p smooth=none -o est.csv   (causal grid filter, online)

      vibrospeed estimate drive.csv --method rbpmf --smooth -p improved=true -o est.csv

      vibrospeed estimate drive.csv -m fuse -o est.csv   (vibration + acceleration + GPS)

      vibrospeed estimate nogps.csv -m fuse --radius-from est.csv.json -o est2.csv
    """
    from vibrospeed.batch import EstimateOptions, estimate_recording, vibration_channel

    _check_output(output)
    _check_output(plot, "--plot", figure=True)
    rec = None  # the recording, where choosing the method read it
    streamed = None  # (rows, notes) / False where choosing the method counted the rows
    if method is None:
        method, rec, streamed = _default_method(
            input, radius_from=radius_from, preset=preset, param=param,
            grid_only=smooth or lag is not None or fit_params or init_omega is not None,
            plot=plot is not None, fmt=fmt, columns=columns, mapping=mapping, rate=rate,
            sort=sort, topic=topic, decimal=decimal)
    if radius_from is not None:
        if method != "fuse":
            raise ParameterError("--radius-from is for --method fuse (the radius it learned)")
        param = [*(param or []), f"radius_from={radius_from}"]

    opts = EstimateOptions(method=method, params=_params(method, preset, param), axis=axis,
                           wheel_radius=wheel_radius, init_omega=init_omega, smooth=smooth,
                           lag=lag, fit_params=fit_params, fmt=fmt, columns=columns,
                           mapping=mapping, rate=rate, sort=sort, topic=topic, decimal=decimal)
    from vibrospeed.estimators.grid import stream

    try:
        if streamed is None:  # the rows counted once, here or while choosing the method
            rows = stream.stream_rows(input, method=method, params=opts.estimator_params(),
                                      fmt=fmt, columns=columns, mapping=mapping, rate=rate,
                                      sort=sort, topic=topic, plot=plot is not None)
            streamed = False if rows is None else (rows, [])
        if rec is None and streamed:  # a long log: in blocks, bounded memory
            from vibrospeed.eval.metrics import SummaryAccumulator

            summary = SummaryAccumulator()
            st = stream.estimate_file(input, output, params=opts.estimator_params(), axis=axis,
                                      wheel_radius=wheel_radius, fmt=fmt,
                                      meta={"preset": preset}, progress=sys.stderr.isatty(),
                                      rows=streamed[0], notes=streamed[1], columns=columns,
                                      mapping=mapping, rate=rate, plot=plot is not None,
                                      on_block=summary.add, decimal=decimal)
            _drop_stale(plot)
            said = range_note(method, opts.params, st.params, st.wheel_radius)
            for note in st.recording_notes + st.notes + ([said] if said else []):
                err.print(f"note: {note}", markup=False)  # [ms] is a unit here
            err.print(f"wrote {output} ({st.rows} rows, method {method}, in blocks)",
                      markup=False, soft_wrap=True)  # a path is text, not markup
            chans = stream.channel_names(input, fmt, columns=columns, mapping=mapping,
                                         rate=rate, decimal=decimal)
            # a gps_speed the header names has a fix (the reader refuses one without any)
            unread = method not in READS_GPS and "gps_speed" in chans
            err.print(summary_line(summary.result(), gps_unread=unread), markup=False,
                      soft_wrap=True)
            if plot is not None:
                from vibrospeed.eval.plot import plot_streamed

                plot_streamed(plot, st.drawing)
                err.print(f"wrote {plot} (decimated spectrogram, no posterior image)",
                          markup=False, soft_wrap=True)
            return
        est = estimate_recording(input, output, opts, progress=sys.stderr.isatty(),
                                 keep_posterior=plot is not None, meta={"preset": preset},
                                 recording=rec)
        _drop_stale(plot)
    except ParameterError as exc:
        raise _unknown_hint(method, exc) from None
    rec, track = est.recording, est.track
    said = range_note(method, opts.params, track.params, track.wheel_radius)
    for note in rec.notes + track.notes + ([said] if said else []):
        err.print(f"note: {note}", markup=False)
    err.print(f"wrote {output} ({len(track)} rows, method {method})", markup=False, soft_wrap=True)
    import numpy as np

    from vibrospeed.eval.metrics import track_summary

    unread = method not in READS_GPS and "gps_speed" in rec \
        and bool(np.isfinite(rec.channel("gps_speed")).any())
    err.print(summary_line(track_summary(track), gps_unread=unread), markup=False,
              soft_wrap=True)
    if plot is not None:
        from vibrospeed.eval.plot import plot_track

        plot_track(plot, rec, track, axis=vibration_channel(rec, est.axis),
                   posterior=est.grids.get("posterior"), grid=est.grids.get("grid"))
        err.print(f"wrote {plot}", markup=False, soft_wrap=True)


def _drop_stale(plot: Path | None) -> None:
    """The earlier run's figure goes once the new estimate is written: stopped (Ctrl-C) while
    the new one is drawn, it would stand beside the new CSV as if it showed it."""
    if plot is not None:
        Path(plot).unlink(missing_ok=True)


def _percent(share: float) -> str:
    """``share`` (0..1) as a percentage with one decimal; a share that is not 0 never reads 0."""
    return f"{100 * share:.1f} %" if share == 0 or 100 * share >= 0.05 else "< 0.1 %"


#: the methods that read the recording's GPS speed
READS_GPS = ("fuse", "gps-riss")


def summary_line(s: dict, *, gps_unread: bool = False) -> str:
    """What the estimate rests on, in one line, from its summary numbers ``s``
    (:func:`vibrospeed.eval.metrics.track_summary`, a batch row's): the share of samples with a
    claimed wheel line (``fuse``: the shares of the samples by what the speed rests on), the
    median speed (or omega without a radius) and the distance with
    the distances at the edges of the speed band, which count every sample: where no line is
    claimed omega is the tracker's guess, and the line says so. Where the numbers are left
    empty (``s["note"]``) on a recording with GPS speed the method does not read
    (``gps_unread``), the line points to ``-m fuse``, which reads it."""
    parts = []
    share = s["signal_share"]
    sources = s.get("source_shares") or {}
    if sources:
        parts.append("speed from " + ", ".join(
            f"{what} on {_percent(sources[name])}" for name, what in (
                ("gps", "GPS"), ("vibration", "the wheel line"),
                ("accelerometer", "the accelerometer alone"), ("standstill", "a standstill"))
            if sources[name] > 0) + " of the samples")
    elif share == share:
        guess = " (elsewhere omega is the tracker's guess: read its band)" \
            if share < 1 and not s["note"] else ""
        parts.append(f"a wheel line claimed on {100 * share:.1f} % of the samples{guess}")
    if s["median_speed"] == s["median_speed"]:
        parts.append(f"median speed {s['median_speed']:.2f} m/s")
        if s["distance_m"] == s["distance_m"]:
            lo, hi = s.get("distance_lo_m", math.nan), s.get("distance_hi_m", math.nan)
            # "to" where an edge is negative (a signed speed, algebraic's Vx): "-185-380 m"
            # reads as a range from -185 to -380 or as a subtraction
            sep = " to " if lo < 0 or hi < 0 else "-"
            band = f" ({lo:.0f}{sep}{hi:.0f} m at the edges of the speed band)" \
                if lo == lo and hi == hi else ""
            parts.append(f"distance {s['distance_m']:.0f} m{band}")
    elif s["median_omega"] == s["median_omega"]:
        parts.append(f"median omega {s['median_omega']:.1f} rad/s")
    if s["note"]:
        parts.append(s["note"])
        if gps_unread:
            parts.append("the recording has GPS speed, which this method does not read: "
                         "-m fuse reads it")
    return "summary: " + "; ".join(parts) if parts else "summary: -"


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
    init_omega: Annotated[float | None, typer.Option(help="initial omega guess in rad/s",
                          callback=at_least("initial omega", "rad/s", strict=False))] = None,
    preset: PresetOpt = None,
    param: ParamOpt = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="as for estimate (rbpmf, grid)")]
    = False,
    lag: Annotated[float | None, typer.Option(help="as for estimate (rbpmf, grid)",
                   callback=at_least("lag", "s"))] = None,
    fit_params: Annotated[bool, typer.Option("--fit-params", help="as for estimate (rbpmf, "
                          "grid)")] = False,
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", help="local worker processes "
                    "(default min(4, CPU count); 1 runs in this process)",
                    callback=at_least("worker count", lo=1, strict=False))] = None,
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
    decimal: DecimalOpt = None,
    sort: SortOpt = False,
) -> None:
    """Estimate many recordings with the same options; write a summary table.

    Each recording gets <name>_<method>.csv and .json in the output folder (two inputs with the
    same name get a short hash added). summary.csv (and summary.parquet with pyarrow) has per
    recording: file, format, duration, method, share with a wheel line, median speed,
    distance, status (ok / skipped / error), the error in one line, a note where nothing was
    measured while moving (no wheel line or GPS: the speed numbers are left empty; the count is
    printed at the end) or where the default wheel speed range was searched (estimate's note,
    printed once at the end with its count) and the wall time. Run it again and every
    recording whose output has the same input checksum, method, options and vibrospeed version
    is skipped; a bad file is an error row, never the end of the batch (exit status 2 when any
    recording failed). With --decimal , the mark applies to the CSV recordings only: those of
    other formats (Parquet, ROS bags, phone exports) are read without it, said in one note at
    the end.

    Examples:

      vibrospeed batch 'logs/*.csv' -o out -p omega_min=2 -p omega_max=30

      vibrospeed batch 'logs/*.csv' -o out --preset online   (causal estimates)

      vibrospeed batch phone_logs/ --format phyphox --axis y -o out --report

      vibrospeed batch 'fleet/**/*.parquet' -o out --scheduler tcp://10.0.0.5:8786
    """
    from vibrospeed import batch as vb

    _check_output(output, folder=True)
    opts = vb.EstimateOptions(method=method, params=_params(method, preset, param), axis=axis,
                              wheel_radius=wheel_radius, init_omega=init_omega, smooth=smooth,
                              lag=lag, fit_params=fit_params, fmt=fmt, columns=columns,
                              mapping=str(mapping) if mapping is not None else None, rate=rate,
                              sort=sort, topic=topic, decimal=decimal)
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
    from collections import Counter

    from vibrospeed.batch.task import NO_EVIDENCE_NOTE, NOTE_SEP

    notes = [[n for n in str(text).split(NOTE_SEP) if n] for text in df["note"].fillna("")]
    noted = sum(NO_EVIDENCE_NOTE in said for said in notes)
    if noted:  # drive_summary left their speed numbers empty: nothing measured while moving
        print(f"{noted} drive{'s' if noted != 1 else ''} without a wheel line or GPS while "
              "moving: speed numbers left empty (see the note column)", file=sys.stderr)
    # the others (the default range searched: range_note) once each, as estimate prints them
    for text, k in Counter(n for said in notes for n in said if n != NO_EVIDENCE_NOTE).items():
        print(f"note: {text} ({k} recording{'s' if k != 1 else ''}, see the note column)",
              file=sys.stderr)
    if counts.get("error", 0):
        raise typer.Exit(2)


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
