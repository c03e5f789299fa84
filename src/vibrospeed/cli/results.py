"""The commands that look at an estimate: ``report`` (an HTML drive report), ``evaluate``
(metrics against a truth file, optionally as JSON) and ``plot`` (a spectrogram with the
track)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table
from rich.text import Text

from vibrospeed.cli.base import _check_output, _friendly, _load, _params, err, out
from vibrospeed.cli.options import (
    AxisOpt,
    ColumnsOpt,
    FormatOpt,
    InputArg,
    MappingOpt,
    ParamOpt,
    PresetOpt,
    RadiusOpt,
    RateOpt,
    SortOpt,
    TruthChannelOpt,
    _decimal_mark,
    at_least,
)
from vibrospeed.errors import ParameterError, VibrospeedError

#: ``--decimal`` of ``report`` and ``plot``: as ``estimate``'s, and for a CSV ``--truth`` too
TruthDecimalOpt = Annotated[str | None, typer.Option(
    "--decimal", help="decimal mark of the numbers of the CSV inputs (the recording and the "
    "--truth file, whichever is a CSV): '.' (default) or ',' for a ';' or tab separated "
    "export that writes 1,5 (canonical CSV or --columns / --mapping); never guessed. A "
    "--mapping file's decimal = \"...\" that says otherwise is refused",
    callback=_decimal_mark)]


@_friendly
def report(
    input: InputArg,
    output: Annotated[Path, typer.Option("-o", "--output", help="HTML page to write")],
    estimate_csv: Annotated[Path | None, typer.Option("--estimate", help="estimate CSV "
                            "(from `estimate`); without it the recording is estimated first "
                            "with --method and -p")] = None,
    truth: Annotated[Path | None, typer.Option(help="truth recording (default: the input's "
                     "omega_true / speed_true if any); a CSV one read with --decimal")] = None,
    truth_channel: TruthChannelOpt = None,
    method: Annotated[str | None, typer.Option("--method", "-m", help="estimator without "
                      "--estimate (see `vibrospeed methods`); default as `estimate`: fuse "
                      "where the recording has GPS speed and ax, else grid")] = None,
    axis: AxisOpt = None,
    wheel_radius: RadiusOpt = None,
    preset: PresetOpt = None,
    param: ParamOpt = None,
    fmt: FormatOpt = "auto",
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    decimal: TruthDecimalOpt = None,
    sort: SortOpt = False,
) -> None:
    """One self-contained HTML page for a drive: spectrogram with the estimate, band and truth
    or GPS, speed over time, where a wheel line was seen, notes, summary numbers.

    Images are embedded in the page; it has no external links and no scripts.

    Examples:

      vibrospeed report drive.csv --estimate est.csv -o drive.html

      vibrospeed report drive.csv -p omega_min=2 -p omega_max=30 -o drive.html

      vibrospeed report phone_drive --truth-channel gps_speed -o phone.html
    """
    import tempfile

    from vibrospeed import batch as vb
    from vibrospeed import io
    from vibrospeed.eval.report import write_report

    _check_output(output)
    if estimate_csv is not None:
        given = [flag for flag, v in (("-p", param), ("--preset", preset),
                                      ("--wheel-radius", wheel_radius), ("--method", method))
                 if v]
        if given:  # they make an estimate; one given would silently do nothing
            raise ParameterError(f"{', '.join(given)} with --estimate: they set how the "
                                 "recording is estimated, and --estimate gives the estimate; "
                                 "leave out one or the other")
    decimal, decimal_truth = _recording_marks(input, fmt, columns, mapping, rate, truth,
                                              decimal)
    ref = io.read(truth, decimal=decimal_truth) if truth else None
    if ref is not None and truth_channel is not None:
        ref.require(truth_channel)  # before estimating: a typo is an error in a second
    if estimate_csv is not None:
        rec = _load(input, fmt, columns, mapping, rate, sort, decimal=decimal)
        track = io.read_track(estimate_csv)
        side = _sidecar(estimate_csv)
        _check_same_input(estimate_csv, side, input)
        meta = side.get("meta") or {}
        used_axis = axis or meta.get("axis")
        grids: dict = {}
    else:
        method, read = _report_method(input, method, preset, param, fmt, columns, mapping, rate,
                                      sort, decimal)
        opts = vb.EstimateOptions(method=method, params=_params(method, preset, param),
                                  axis=axis,
                                  wheel_radius=wheel_radius, fmt=fmt, columns=columns,
                                  mapping=mapping, rate=rate, sort=sort, decimal=decimal)
        with tempfile.TemporaryDirectory(prefix="vibrospeed-") as d:
            est = vb.estimate_recording(input, Path(d) / "estimate.csv", opts,
                                        keep_posterior=True, progress=sys.stderr.isatty(),
                                        recording=read)
        rec, track, used_axis, grids = est.recording, est.track, est.axis, est.grids
    write_report(output, rec, track, axis=vb.vibration_channel(rec, used_axis), truth=ref,
                 truth_channel=truth_channel,
                 posterior=grids.get("posterior"), grid=grids.get("grid"),
                 title=input.name or str(input), input_path=input, estimate_path=estimate_csv)
    err.print(f"wrote {output}", markup=False, soft_wrap=True)  # a path is text, not markup


def _report_method(input: Path, method: str | None, preset, param, fmt, columns, mapping, rate,
                   sort, decimal=None):
    """The method ``report`` estimates with: ``method`` where given, else the one ``vibrospeed
    estimate`` would choose (fuse with GPS speed, it says so; else grid), so the page shows
    the estimate the user gets from ``estimate``. Above the streaming threshold ``estimate``
    runs grid in blocks, so the page does too, and a note says why. Returns the method and the
    recording where choosing read it (else None)."""
    if method is not None:
        return method, None
    from vibrospeed.cli.estimate import _default_method

    chosen, rec, streamed = _default_method(
        input, radius_from=None, preset=preset, param=param, grid_only=False, plot=False,
        fmt=fmt, columns=columns, mapping=mapping, rate=rate, sort=sort, topic=None,
        decimal=decimal)
    if streamed and streamed[1]:  # GPS speed on a long log: estimate keeps grid there
        err.print(f"note: method {chosen}, as `vibrospeed estimate` for this log: "
                  + "; ".join(streamed[1]), markup=False, soft_wrap=True)
    return chosen, rec


def _sidecar(estimate_csv: Path) -> dict:
    """The estimate's ``.json`` sidecar as a dict (empty where there is none or it is not
    JSON: the estimate still draws, without what the sidecar says)."""
    side_path = Path(f"{estimate_csv}.json")
    try:
        side = json.loads(side_path.read_text(encoding="utf-8")) if side_path.is_file() else {}
    except (OSError, ValueError):
        side = {}
    return side if isinstance(side, dict) else {}


def _check_same_input(estimate_csv: Path, side: dict, recording: Path,
                      hint: str = "leave out --estimate to estimate this one") -> None:
    """Refuse to draw an estimate over a recording it was not made from: the estimate's sidecar
    records its input's SHA-256 (of the file, or of all files of a folder), and a page pairing
    one drive's spectrogram with another drive's speed would look plausible and be wrong."""
    from vibrospeed.io._common import sha256_path

    want = side.get("input_sha256")
    if not isinstance(want, str) or sha256_path(recording) == want:
        return
    made = side.get("input") or "another recording"
    raise ParameterError(f"{estimate_csv}: estimated from {made}, not from {recording} (the "
                         f"input checksum in its .json sidecar differs): give that recording, "
                         f"or {hint}")


@_friendly
def evaluate(
    estimate_csv: Annotated[Path, typer.Argument(help="estimate written by `estimate`")],
    truth: Annotated[Path, typer.Option(help="recording with omega_true or speed_true")],
    truth_format: Annotated[str, typer.Option(help="format of the truth file")] = "auto",
    truth_channel: TruthChannelOpt = None,
    truth_columns: Annotated[str | None, typer.Option(
        help="column mapping of a truth file in another CSV layout, as --columns of "
             "`estimate` (e.g. t=t_video_s,gps_speed=gps_speed2d_mps, then --truth-channel "
             "gps_speed; or speed_true=COLUMN)")] = None,
    min_omega: Annotated[float, typer.Option(help="truth below this (rad/s) = standing, "
                         "excluded (speeds compared in m/s, an estimate or truth without a "
                         "wheel radius: below 0.3 m/s)",
                         callback=at_least("min omega", "rad/s", strict=False))]
    = 1.0,
    warmup: Annotated[float, typer.Option(help="seconds at the start excluded",
                                          callback=at_least("warm-up", "s", strict=False))]
    = 0.0,
    json_out: Annotated[Path | None, typer.Option("--json", help="also write metrics as JSON")]
    = None,
    baseline: Annotated[Path | None, typer.Option(
        "--baseline", help="the recording the estimate was made from (for a simulated drive "
        "often the --truth file): also score the plain 3 s STFT harmonic sum on it (the "
        "estimate's axis, search range, causality and wheel radius), side by side")] = None,
    decimal: Annotated[str | None, typer.Option(
        "--decimal", help="decimal mark of the numbers of the CSV inputs (the --truth file "
        "and the --baseline recording): '.' (default) or ',' (a ';'-separated export that "
        "writes 1,5), as --decimal of `estimate`; a batch estimate's sidecar says the "
        "baseline's", callback=_decimal_mark)] = None,
) -> None:
    """Compare an estimate with ground truth: RMSE (thesis eq. 3.18, truth linearly
    interpolated, moving samples only), bias, relative error (median and mean), band coverage,
    harmonic errors; the lateral velocity Vy (RMSE, MAE, bias, correlation) where the estimate
    has ``vy`` (algebraic) and the truth ``vy_true``. With --baseline the plain 3 s STFT
    harmonic sum on the same recording is scored beside it: where it does better, the
    estimate loses to the plainest method there.

    Examples:

      vibrospeed evaluate est.csv --truth drive.csv

      vibrospeed evaluate est.csv --truth drive.csv --baseline drive.csv

      vibrospeed evaluate phone_est.csv --truth phone_drive --truth-channel gps_speed

      vibrospeed evaluate kart_est.csv --truth GX030410_gps_speed.csv
      --truth-columns t=t_video_s,gps_speed=gps_speed2d_mps --truth-channel gps_speed
    """
    from vibrospeed import io
    from vibrospeed.eval.metrics import evaluate as ev
    from vibrospeed.io._common import jsonable
    from vibrospeed.io.atomic import atomic_write_text

    _check_output(json_out, "--json")
    track = io.read_track(estimate_csv)
    # the truth's mark: none for a Parquet one beside a baseline (read with the mark)
    takes = _takes_decimal(truth, truth_format, truth_columns is not None) if decimal else None
    truth_mark = _marks(decimal, takes, baseline is not None)[0]
    ref = io.read(truth, truth_format, columns=truth_columns, decimal=truth_mark)
    if truth_channel is None and not ({"omega_true", "speed_true"} & set(ref.channels)) \
            and "gps_speed" in ref.channels:  # a phone drive: its GPS is the truth it has
        raise ParameterError(f"{truth}: no omega_true or speed_true to compare against; it has "
                             "GPS speed: --truth-channel gps_speed to score against that")
    m = ev(track, ref, min_omega=min_omega, warmup=warmup, truth_channel=truth_channel)
    if m.n == 0:  # a table of NaN with exit status 0 read as a result
        # the truth's moving threshold in its unit (evaluate compares speeds at 0.3 m/s)
        still = "0.3 m/s" if m.unit == "m/s" else f"--min-omega {min_omega:g} rad/s"
        after = f" {warmup:g} s after its start (--warmup)" if warmup > 0 else ""
        raise ParameterError(
            f"{estimate_csv}: nothing to compare: no sample of the estimate "
            f"({track.t[0]:g}-{track.t[-1]:g} s){after} has a finite value where the truth "
            f"{truth} ({ref.t[0]:g}-{ref.t[-1]:g} s) moves faster than {still}")
    mb = None
    if baseline is not None:  # the plain STFT on the same data, scored by the same call
        base, notes = _baseline_track(estimate_csv, track, baseline, ref, decimal,
                                      truth_took=truth_mark is not None and takes is True)
        for note in notes:
            err.print(f"note: {note}", markup=False, soft_wrap=True)
        mb = ev(base, ref, min_omega=min_omega, warmup=warmup, truth_channel=truth_channel)
        if mb.unit != m.unit:  # _baseline_track builds it to be scored as the estimate is
            raise ParameterError(f"{baseline}: the STFT baseline is scored in {mb.unit}, the "
                                 f"estimate {estimate_csv} in {m.unit}: no side-by-side table")
    tab = Table(title=Text(f"{estimate_csv.name} vs truth {truth.name}"), title_justify="left")
    tab.add_column("metric")
    tab.add_column("value" if mb is None else "estimate", justify="right")
    if mb is not None:
        tab.add_column("STFT 3 s", justify="right")
    tab.add_column("unit")
    rows = _metric_rows(m)
    base_values = {} if mb is None else {label: value for label, value, _ in _metric_rows(mb)}
    for label, value, unit in rows:
        tab.add_row(label, value, *(() if mb is None else (base_values.get(label, "n/a"),)),
                    unit)
    out.print(tab)
    if mb is not None:
        line = (f"share within max(2 {m.unit}, 10 %): estimate {m.ok_share:.1%} vs plain STFT "
                f"{mb.ok_share:.1%}")
        if m.ok_share < mb.ok_share:
            line += " (the estimate loses to the plain baseline here)"
        out.print(line, markup=False, soft_wrap=True)
    if json_out is not None:  # strict JSON, as the sidecars: a metric that is NaN is null
        doc = m.to_dict()
        if mb is not None:
            doc["baseline"] = mb.to_dict()
        atomic_write_text(json_out, json.dumps(jsonable(doc), indent=2, allow_nan=False) + "\n")


def _marks(decimal: str | None, *takes: bool | None) -> list[str | None]:
    """``--decimal`` for each input of a command (``evaluate``'s truth and baseline, the
    recording and truth of ``report`` and ``plot``), ``takes`` saying whether its reader takes
    a decimal mark (a CSV), None where its format cannot be told: the mark for each, left out
    for one that takes none where another does, so one flag serves a CSV beside a Parquet
    file or a phone export. Where none takes it, each keeps it: the first reader then refuses
    it in one line (a decimal mark for formats without one means nothing)."""
    if decimal is None or True not in takes:
        return [decimal] * len(takes)
    return [None if t is False else decimal for t in takes]


def _takes_decimal(path: Path, fmt: str, mapped: bool) -> bool | None:
    """Whether the reader of ``path`` (format ``fmt``, ``auto`` detected; ``mapped``: read
    through a column mapping) takes a decimal mark, i.e. it is a CSV; None where its format
    cannot be told (reading it then says why)."""
    from vibrospeed import io

    try:
        name = io.detect_format(path, mapping=mapped) if fmt == "auto" else fmt
    except (OSError, VibrospeedError):
        return None
    return io.format_takes(name, "decimal")


def _recording_marks(input: Path, fmt: str, columns: str | None, mapping: Path | None,
                     rate: float | None, truth: Path | None,
                     decimal: str | None) -> tuple[str | None, str | None]:
    """``--decimal`` of ``report`` and ``plot`` for their recording and their ``--truth``
    file (:func:`_marks`); the recording is a mapped CSV with --columns, --mapping or --rate,
    as a batch tells it (:func:`vibrospeed.batch.task._for_recording`)."""
    if decimal is None or truth is None:
        return decimal, None
    mapped = columns is not None or mapping is not None or rate is not None
    rec_mark, truth_mark = _marks(decimal, _takes_decimal(input, fmt, mapped),
                                  _takes_decimal(truth, "auto", False))
    return rec_mark, truth_mark


def _metric_rows(m) -> list[tuple[str, str, str]]:
    """The rows ``(metric, value, unit)`` of ``evaluate``'s table for the metrics ``m``; the
    rows that do not apply to them (harmonic shares of a speed comparison, the claimed share
    of a method that claims nothing, Vy without one) are left out."""
    rows = [
        ("samples evaluated (moving)", f"{m.n}", ""),
        ("moving share", f"{m.moving_share:.1%}", ""),
        ("RMSE", f"{m.rmse:.3f}", m.unit),
        ("MAE", f"{m.mae:.3f}", m.unit),
        ("bias", f"{m.bias:+.3f}", m.unit),
        ("relative error: median", f"{m.rel_error_median:.1%}", ""),
        ("relative error: mean", f"{m.rel_error:.1%}", ""),
        (f"coverage of the {m.level:.0%} band",
         f"{m.coverage:.1%}" if m.coverage == m.coverage else "n/a (no band)", ""),
    ]
    if m.unit != "m/s":
        rows += [("share within max(2 rad/s, 10 %)", f"{m.ok_share:.1%}", ""),
                 ("share at omega/2", f"{m.half_share:.1%}", ""),
                 ("share at 2 omega", f"{m.double_share:.1%}", "")]
    if m.claimed_share == m.claimed_share:
        rows.append(("share where it claims a signal", f"{m.claimed_share:.1%}", ""))
        if m.claimed_share > 0:  # no claim: nothing to score there (the metrics are NaN)
            rows += [("  RMSE there", f"{m.rmse_claimed:.3f}", m.unit),
                     ("  within max(2 rad/s, 10 %) there", f"{m.ok_claimed:.1%}", ""),
                     ("  band coverage there", f"{m.coverage_claimed:.1%}", "")]
    if m.rmse_speed == m.rmse_speed and m.unit != "m/s":
        rows.append(("RMSE speed", f"{m.rmse_speed:.3f}", "m/s"))
    if m.vy_n:  # the estimate has a lateral velocity and the truth vy_true
        rows += [("lateral velocity Vy: samples", f"{m.vy_n}", ""),
                 ("  Vy RMSE", f"{m.vy_rmse:.3f}", "m/s"),
                 ("  Vy MAE", f"{m.vy_mae:.3f}", "m/s"),
                 ("  Vy bias", f"{m.vy_bias:+.3f}", "m/s"),
                 ("  Vy correlation", f"{m.vy_corr:.3f}" if m.vy_corr == m.vy_corr
                  else "n/a (constant)", "")]
    return rows


def _baseline_track(estimate_csv: Path, track, recording: Path, ref, decimal: str | None = None,
                    truth_took: bool = False):
    """The plain 3 s STFT harmonic sum (:func:`vibrospeed.eval.baseline.stft_track`) on
    ``recording``, set up as the estimate ``track`` (read from ``estimate_csv``) was made: its
    axis (``y`` for ``gps-riss`` and ``algebraic``, whose axis is the longitudinal one), its
    search range (params ``omega_min`` / ``omega_max``; a method without one gets
    the grid's default range, said in a note), causal where the estimate is (``smooth`` =
    ``none``, ``online`` or ``causal`` true), with its delay where it has one (``smooth`` =
    ``lag``: the windows ended ``lag`` s after each sample) and its wheel radius, on the
    estimate's time stamps.
    A speed-only estimate (no radius) gets a speed-only baseline, through the recording's or
    the truth ``ref``'s radius, so both are scored in m/s. ``decimal``: ``evaluate
    --decimal``, refused where the sidecar's options (a batch's) say another; not given to a
    recording of a format without one where the CSV truth took it (``truth_took``). Returns
    the track and the notes."""
    import numpy as np

    from vibrospeed.config import parse_flag
    from vibrospeed.estimators.grid.config import Config as GridConfig
    from vibrospeed.eval.baseline import stft_track
    from vibrospeed.types import Track

    side = _sidecar(estimate_csv)
    _check_same_input(estimate_csv, side, recording,
                      hint="leave out --baseline")
    meta = side.get("meta") if isinstance(side.get("meta"), dict) else {}
    opts = meta.get("options") if isinstance(meta.get("options"), dict) else {}
    stored = opts.get("decimal")
    if decimal is not None and truth_took and _takes_decimal(
            recording, opts.get("fmt") or "auto",
            bool(opts.get("columns") or opts.get("mapping"))) is False:
        decimal = None  # the mark was the truth's: a Parquet recording has none
    if decimal is not None and stored is not None and decimal != stored:
        raise ParameterError(f"--decimal '{decimal}' but {estimate_csv}'s sidecar says the "
                             f"estimate read {recording} with decimal '{stored}': give one")
    rec = _load(recording, opts.get("fmt") or "auto", opts.get("columns"), opts.get("mapping"),
                opts.get("rate"), bool(opts.get("sort", False)), decimal=decimal or stored)
    if rec.t.size == 0 or rec.t[0] > track.t[-1] or rec.t[-1] < track.t[0]:
        span = f"{rec.t[0]:g}-{rec.t[-1]:g} s" if rec.t.size else "no samples"
        raise ParameterError(f"{recording}: its time span ({span}) does not overlap the "
                             f"estimate {estimate_csv} ({track.t[0]:g}-{track.t[-1]:g} s): "
                             "--baseline takes the recording the estimate was made from")
    par = track.params
    axis = par.get("axis") if isinstance(par.get("axis"), str) else meta.get("axis")
    axis = axis if isinstance(axis, str) and axis else "y"
    lo, hi = par.get("omega_min"), par.get("omega_max")
    notes = []
    if track.method in ("gps-riss", "algebraic"):  # their axis is the longitudinal one
        notes.append(f"{track.method} reads its axis ({axis}) for the longitudinal "
                     "acceleration: the STFT baseline reads the default vibration axis y")
        axis = "y"
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
               for x in (lo, hi)) or not 0 <= lo < hi:
        lo, hi = GridConfig.omega_min, GridConfig.omega_max
        notes.append(f"the estimate ({track.method or 'method unknown'}) has no search range "
                     f"(omega_min, omega_max): the STFT baseline searches the grid's default "
                     f"{lo:g}-{hi:g} rad/s")
    # a fixed-lag estimate: the grid's smooth=lag, fuse's lag (its tracker's fixed lag)
    lag = par.get("lag") if par.get("smooth") == "lag" or track.method == "fuse" else None
    lag = float(lag) if isinstance(lag, (int, float)) and not isinstance(lag, bool) \
        and np.isfinite(lag) and lag >= 0 else None
    causal = par.get("smooth") == "none" or lag is not None or any(
        parse_flag(par[k], k) for k in ("online", "causal") if par.get(k) is not None)
    speed_only = not np.isfinite(track.omega).any() and np.isfinite(track.speed).any()
    radius = (rec.wheel_radius or ref.wheel_radius) if speed_only else track.wheel_radius
    if speed_only and not radius:
        raise ParameterError(f"{estimate_csv}: a speed estimate without a wheel radius, and "
                             f"neither {recording} nor the truth has one: the STFT baseline's "
                             "omega has no speed to compare with it")
    base = stft_track(rec, axis=axis, omega_min=float(lo), omega_max=float(hi), causal=causal,
                      wheel_radius=radius, lag=lag or 0.0)
    if not np.isfinite(base.omega).any():  # every value NaN: a column of nan in the table
        raise ParameterError(f"{recording}: {rec.duration:g} s is shorter than the STFT "
                             f"baseline's {base.params['win_s']:g} s window: no baseline to "
                             "score (leave out --baseline)")
    omega = base.omega
    if not np.array_equal(base.t, track.t):  # scored on the estimate's own time stamps
        omega = np.interp(track.t, base.t, base.omega, left=np.nan, right=np.nan)
    nan = np.full(track.t.shape, np.nan)
    if speed_only:  # scored as speeds, as the estimate is
        base = Track.from_speed(track.t, radius * omega, lo=nan, hi=nan, method="stft",
                                params=base.params)
    else:
        base = Track.from_omega(track.t, omega, lo=nan, hi=nan, wheel_radius=radius,
                                method="stft", params=base.params)
    notes.insert(0, f"baseline: the plain {base.params['win_s']:g} s STFT harmonic sum "
                    f"(M = {base.params['M']}) on {base.params['axis']} high-passed "
                    f"({base.params['prefilter']}), {lo:g}-{hi:g} rad/s, "
                    + (f"with the estimate's {lag:g} s lag (each value from the windows "
                       "ended by then)" if lag else
                       "causal (each value from its window's end), as the estimate"
                       if causal else "offline (centred windows)"))
    return base, notes


@_friendly
def plot(
    input: InputArg,
    output: Annotated[Path, typer.Option("-o", "--output", help="PNG to write")],
    estimate_csv: Annotated[Path | None, typer.Option("--estimate", help="estimate CSV to "
                            "draw over the spectrogram")] = None,
    truth: Annotated[Path | None, typer.Option(help="truth recording (default: the input's "
                     "omega_true if any); a CSV one read with --decimal")] = None,
    axis: Annotated[str | None, typer.Option(help="channel or axis for the spectrogram "
                    "(default: the axis the estimate used, from its .json sidecar, else y)")]
    = None,
    harmonics: Annotated[int, typer.Option(help="harmonics of the estimate to draw (1 = the "
                         "wheel line alone)", callback=at_least("harmonics", lo=1,
                                                               strict=False))] = 3,
    window: Annotated[float, typer.Option(help="STFT window in s (e.g. 3; longer: finer "
                      "frequency, coarser time)", callback=at_least("window", "s"))] = 3.0,
    fmt: FormatOpt = "auto",
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    decimal: TruthDecimalOpt = None,
    sort: SortOpt = False,
) -> None:
    """Spectrogram of a vibration axis with the estimate, its band, harmonics and truth.

    Example:

      vibrospeed plot drive.csv --estimate est.csv -o drive.png
    """
    from vibrospeed import io
    from vibrospeed.estimators.common import axis_channel
    from vibrospeed.eval.plot import plot_track

    _check_output(output, figure=True)
    decimal, decimal_truth = _recording_marks(input, fmt, columns, mapping, rate, truth,
                                              decimal)
    rec = _load(input, fmt, columns, mapping, rate, sort, decimal=decimal)
    track = io.read_track(estimate_csv) if estimate_csv else None
    if estimate_csv is not None:
        side = _sidecar(estimate_csv)
        _check_same_input(estimate_csv, side, input, hint="an estimate of this one")
        if axis is None:  # the spectrogram the estimate was made from, as report draws it
            from vibrospeed.batch import vibration_channel

            used = (side.get("meta") or {}).get("axis")
            axis = vibration_channel(rec, used if isinstance(used, str) else None)
    ref = io.read(truth, decimal=decimal_truth) if truth else None
    plot_track(output, rec, track, axis=axis_channel(axis or "y"), truth=ref,
               harmonics=harmonics, window_s=window)
    err.print(f"wrote {output}", markup=False, soft_wrap=True)  # a path is text, not markup
