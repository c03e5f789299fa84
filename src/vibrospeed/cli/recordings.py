"""The commands that make or describe a recording: ``simulate`` (a drive with ground truth),
``truth`` (omega / speed truth from cog-wheel ticks or a recording's wheel channels) and
``info`` (channels, rates, ranges and which estimators the recording can feed)."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table
from rich.text import Text

from vibrospeed.cli.base import _check_output, _friendly, _load, err, out
from vibrospeed.cli.options import (
    ColumnsOpt,
    DecimalOpt,
    FormatOpt,
    InputArg,
    MappingOpt,
    RateOpt,
    SortOpt,
    at_least,
)
from vibrospeed.errors import ParameterError


@_friendly
def simulate(
    output: Annotated[Path | None, typer.Option("-o", "--output",
                                                help="output file (.csv or .parquet)")] = None,
    scenario: Annotated[str, typer.Option(help="scenario name (see --list)")] = "cart",
    seed: Annotated[int, typer.Option(help="random seed, >= 0 (same seed, same drive)",
                                      callback=at_least("seed", strict=False))] = 0,
    duration: Annotated[float | None, typer.Option(help="length in s (scenario default)",
                                                   callback=at_least("duration", "s"))] = None,
    fs: Annotated[float | None, typer.Option(help="accelerometer sample rate in Hz (scenario "
                  "default: 100, GPS scenarios 400)", callback=at_least("sample rate", "Hz"))]
    = None,
    set_: Annotated[list[str] | None, typer.Option("--set", help="override a scenario knob, "
                    "NAME=VALUE (repeatable; dotted for nested knobs, lists by comma: "
                    "--set vibration.harmonic_amps=0.1,0.05)")] = None,
    list_: Annotated[bool, typer.Option("--list", help="list scenarios and exit")] = False,
) -> None:
    """Simulate a drive with ground truth (omega_true, speed_true) and write it.

    Where the scenario simulates a cog-wheel sensor (cart, car and most others; not random,
    validation or the gps_* ones), a CSV output gets its ticks beside it, in
    <name>.wss_ticks.csv (for `vibrospeed truth`); a Parquet output holds them inside. The
    number of wheel harmonics is the length of vibration.harmonic_amps (each in m/s^2), as in
    the third example.

    Examples:

      vibrospeed simulate --scenario cart -o cart.csv   (and cart.wss_ticks.csv)

      vibrospeed simulate --scenario car --seed 3 --duration 120 -o car.parquet

      vibrospeed simulate --set vibration.harmonic_amps=0.25,0.2,0.1,0.05 -o cart4.csv

      vibrospeed simulate --scenario random --seed 7 -o drive7.csv   (the randomised family)

      vibrospeed simulate --list
    """
    from vibrospeed import io, sim
    from vibrospeed.config import parse_params

    if list_:
        # scenario descriptions are doc text ([t_front, ...] is not markup), wrapped under their
        # column at the terminal's width
        names = sim.describe()
        col = max(map(len, names)) + 2
        for name, desc in names.items():
            lines = textwrap.wrap(desc, max(40, out.width - col)) or [""]
            text = f"{name:{col}s}" + ("\n" + " " * col).join(lines)
            out.print(text, markup=False, highlight=False, soft_wrap=True)
        return
    if output is None:
        raise ParameterError("simulate: missing -o / --output (the file to write)")
    _check_output(output)
    kw = {} if fs is None else {"fs": fs}
    knobs = parse_params(set_)
    for name in ("seed", "duration", *kw):  # simulate's own arguments: one way to give each
        if name in knobs:
            raise ParameterError(f"--set {name}={knobs[name]}: give it as --{name}")
    rec = sim.simulate(scenario, seed=seed, duration=duration, **kw, **knobs)
    io.write(rec, output)
    err.print(f"wrote {output}: {len(rec)} samples, {rec.duration:.1f} s at {rec.fs:.4g} Hz, "
              f"channels {', '.join(rec.channels)}", markup=False, soft_wrap=True)


@_friendly
def truth(
    ticks: Annotated[Path, typer.Argument(help="cog-wheel tick times: a one-column CSV (s), or "
                     "a recording with a wss_ticks event stream (--from-recording)")],
    output: Annotated[Path, typer.Option("-o", "--output", help="truth recording to write "
                      "(t, omega_true, speed_true)")],
    cogs: Annotated[int, typer.Option(help="cogs per revolution of the sensor wheel",
                                      callback=at_least("cogs", lo=1, strict=False))] = 12,
    r_sensor: Annotated[float, typer.Option(help="radius of the cog wheel in m",
                                            callback=at_least("cog wheel radius", "m"))]
    = 0.0625,
    r_wheel: Annotated[float, typer.Option(help="radius of the vehicle wheel in m",
                                           callback=at_least("wheel radius", "m"))] = 0.08,
    scale: Annotated[float, typer.Option(help="multiply tick values (1e-3 for ms)",
                                         callback=at_least("tick scale"))] = 1.0,
    spike_rel: Annotated[float, typer.Option(help="relative size of a single-sample spike "
                         "replaced by its neighbours' mean (0 = off)",
                         callback=at_least("spike size", strict=False))] = 0.3,
    max_gap: Annotated[float, typer.Option(help="a longer tick interval (s) means standstill",
                                           callback=at_least("gap", "s"))] = 0.5,
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

    _check_output(output)
    kw = dict(n_cogs=cogs, r_sensor=r_sensor, r_wheel=r_wheel, spike_rel=spike_rel,
              max_gap=max_gap)
    if from_recording:
        rec = tr.truth_from_recording(io.read(ticks), **kw)
    else:
        rec = tr.ticks_to_truth(tr.read_ticks(ticks, scale=scale), source=str(ticks), **kw)
    io.write(rec, output)
    for note in rec.notes:
        err.print(f"note: {note}", markup=False)
    err.print(f"wrote {output}: {len(rec)} truth samples over {rec.duration:.1f} s",
              markup=False, soft_wrap=True)


@_friendly
def info(
    input: InputArg,
    fmt: FormatOpt = "auto",
    columns: ColumnsOpt = None,
    mapping: MappingOpt = None,
    rate: RateOpt = None,
    decimal: DecimalOpt = None,
    sort: SortOpt = False,
) -> None:
    """Describe a recording: format, time line, channels with units and ranges, what the reader
    did, and which methods it can feed.

    Example:

      vibrospeed info ../shared/datasets/hungary_car_phyphox/rsq_q2_00
    """
    from vibrospeed import estimators
    from vibrospeed.estimators import fuse
    from vibrospeed.io.timebase import describe_timebase

    rec = _load(input, fmt, columns, mapping, rate, sort, uniform=False, decimal=decimal)
    out.print(f"{rec.source or input}: {len(rec)} samples, {rec.duration:.2f} s, "
              f"median rate {rec.fs:.4g} Hz" + (f", wheel radius {rec.wheel_radius} m"
                                                 if rec.wheel_radius else ""),
              markup=False, soft_wrap=True)
    tab = Table(title_justify="left")
    for col in ("channel", "unit", "finite", "min", "median", "max"):
        tab.add_column(col, justify="left" if col in ("channel", "unit") else "right")
    for name, x in rec.channels.items():
        ok = np.isfinite(x)
        if ok.any():
            lo, med, hi = np.percentile(x[ok], [0, 50, 100])
            tab.add_row(Text(name), Text(rec.units.get(name, "")), f"{ok.mean():.1%}",
                        f"{lo:.4g}", f"{med:.4g}", f"{hi:.4g}")
        else:  # names and units as text, not markup (a unit such as [m/s])
            tab.add_row(Text(name), Text(rec.units.get(name, "")), "0%", "", "", "")
    out.print(tab)
    for name, ev in rec.events.items():
        out.print(f"event stream {name}: {ev.size} events", markup=False)
    notes = list(rec.notes)
    notes += [n for n in describe_timebase(rec) if n not in notes]
    for note in notes:
        out.print(f"note: {note}", markup=False)
    ch = set(rec.channels)
    uses = []
    # the grid tracker (grid's default, fuse's vibration) needs omega_max below pi fs (its
    # refusal in estimators.grid.app); at a phone's 16 Hz its default 120 rad/s is refused,
    # and fuse then runs without its vibration part
    grid_max = float(estimators.get("grid").Config().tracker.omega_max)
    fund = np.pi * rec.fs
    grid_need = (f"; grid needs -p omega_max below {fund:.0f} rad/s at this rate "
                 f"(default {grid_max:.0f})" if fund <= grid_max else "")
    if ch & {"ax", "ay", "az"}:
        top = np.pi * rec.fs / 2  # highest omega with M = 2 harmonics below Nyquist
        limit = "" if top >= 120 else f"; only up to omega = {top:.0f} rad/s at this rate, M = 2"
        limit += grid_need
        axes = sorted(ch & {"ax", "ay", "az"})
        both = f"; grid -p comb_axes=all reads {', '.join(axes)} together" if len(axes) > 1 else ""
        uses.append(f"ekf, rbpmf, grid, rbpf, shs (vibrations{limit}{both})")
    if "ax" in ch or "ay" in ch:
        uses.append("aided (with a longitudinal axis and the wheel radius)")
    if "gps_speed" in ch:
        uses.append("gps-riss")
    if fuse.suits(rec):  # the estimator's own test, as `estimate` uses to choose its method
        uses.append("fuse (vibration + acceleration + GPS speed; estimate's default for such "
                    "a log" + (f"; at this rate without its vibration part unless -p omega_max "
                               f"is below {fund:.0f} rad/s" if grid_need else "") + ")")
    elif "ax" in ch:
        uses.append("fuse (with --wheel-radius or --radius-from: no GPS speed fix)")
    if {"gz", "ax", "ay"} <= ch and all(f"wheel_omega_{w}" in ch for w in ("fl", "fr", "rl", "rr")):
        uses.append("algebraic")
    out.print("can feed: " + ("; ".join(uses) if uses else "no estimator (no known channel)"),
              markup=False)
