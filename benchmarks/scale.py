"""Time and memory against log length, the online tracker's cost per sample, the CLI's start-up.

Parts (all in fresh child processes so that peak memory is the run's own):

* ``lengths``: ``simulate("car", seed=1)`` of 1 min, 10 min, 1 h (``--lengths``) written as
  Parquet; a child reads it and runs one method's ``estimate`` (as the CLI does, no output
  written); wall time of the estimate, peak RSS of the child (``ru_maxrss``, the recording
  included) and RSS before the estimate. Methods: ``grid`` (the default, offline smoothed),
  ``grid-causal`` (``smooth=none``), ``rbpmf``, ``ekf`` and the 3 s STFT harmonic sum
  (:func:`vibrospeed.eval.baseline.stft_harmonic_sum` on the same pre-filtered axis as the grid
  sees); on request (``--methods``) also ``aided`` (offline, ``accel_axis=ax``: the aided
  grid smoother, the drive's wheel radius). Beyond the longest length the time and
  memory are extrapolated with the log-log slope of the last two lengths (printed as such).
* ``online``: microseconds per sample of :class:`~vibrospeed.estimators.online.OnlineTracker`
  (grid causal, rbpmf, ekf; 3000 samples after 300 warm-up, best of 3), of the causal grid's
  comb evidence alone (:func:`vibrospeed.estimators.grid.frame_evidence` on 100 successive
  frames, one call each as its ``step`` makes them, best of 3) and of
  :func:`vibrospeed.signal.whiten.step` (12 000 samples of noise, best of 3), beside the same
  whitener at ``--whiten-ref`` (a git revision, read with ``git show``), and the causal
  grid's other parts alone: its filter's ``step`` without the comb evidence, the pre-filter's
  and the normaliser's ``step`` (3000 samples, best of 3).
* ``startup``: ``python -m vibrospeed estimate`` on a 10 s canonical CSV with an empty numba
  cache directory (``NUMBA_CACHE_DIR``: every ``cache=True`` kernel compiles) and again with the
  cache it left; ``python -c "import vibrospeed.cli.app"`` for reference.
* ``grid``: ``lengths`` for the default grid tracker alone (its own section, so that a
  change to it is measured without running every method again).
* ``read``: peak RSS of reading a 1 h CSV / Parquet whole (``io.read``) and chunk by chunk
  (:class:`vibrospeed.io.chunks.ChunkedRecording`, 65 536 rows) over the child's baseline.
* ``stream``: ``vibrospeed estimate`` (default grid) on Parquet files of ``--stream-lengths``
  (the 1 h drive repeated end to end, time running on: the per-sample work does not depend on
  the content), in a child that runs the CLI in-process after a 10 s run (compilation apart):
  above :data:`vibrospeed.estimators.grid.stream.STREAM_ROWS` rows it reads in chunks,
  estimates in blocks and appends to its output; CPU, wall and peak RSS of the command.
* ``options``: the same measurement for what else streams, each through the streaming path and
  (its threshold raised) the whole-log path, on the 1 h drive (``--options-lengths``): a
  logger CSV read through ``--columns`` (time in ms, the axes in g, a text column,
  semicolons), ``--lag 3`` and ``--plot`` on the Parquet file (``--options-modes stream``:
  the streaming path alone).

Usage (``--write``: ``benchmarks/scale/RESULTS.md`` and ``docs/img/scale.png``)::

    PYTHONPATH=src .venv/bin/python benchmarks/scale.py [lengths] [grid] [online] [startup] [read]
        [stream] [options] [--lengths 60,600,3600] [--methods grid,grid-causal,rbpmf,ekf,stft]
        [--stream-lengths 3600,21600] [--options-lengths 3600] [--options-modes stream,whole]
        [--write]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
METHODS = ("grid", "grid-causal", "rbpmf", "ekf", "stft")
DAY = 86400.0


def _rss_mib() -> float:
    return _status_mib("VmRSS:")


def _status_mib(key: str) -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key):
                return float(line.split()[1]) / 1024.0
    return float("nan")


def _peak_mib() -> float:
    """This process's peak RSS since the last :func:`_reset_peak` (VmHWM). Not ``ru_maxrss``:
    a child's counts its parent's RSS at exec time."""
    return _status_mib("VmHWM:")


def _reset_peak() -> None:
    with open("/proc/self/clear_refs", "w") as fh:  # "5": reset the peak RSS (Linux >= 4.0)
        fh.write("5")


# ---- children ---------------------------------------------------------------------------
def child_estimate(method: str, path: str) -> dict:
    from vibrospeed import io

    rec = io.read(path)
    # compile (or load the numba cache) on a 10 s piece first: start-up is measured apart
    short = type(rec)(rec.t[:1000], {k: v[:1000] for k, v in rec.channels.items()})
    _run(method, short)
    before = _rss_mib()
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    n = _run(method, rec)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall": wall, "cpu": cpu, "peak": _peak_mib(), "before": before, "n": n}


def _run(method: str, rec) -> int:
    from vibrospeed import estimators

    name, params = {"grid": ("grid", {}), "grid-causal": ("grid", {"smooth": "none"}),
                    "rbpmf": ("rbpmf", {}), "ekf": ("ekf", {}),
                    "aided": ("aided", {"accel_axis": "ax"})}.get(method, (None, None))
    if name is None:
        return _stft(rec)
    if name == "aided":  # the Parquet file does not keep the drive's wheel radius
        from vibrospeed import sim

        r = sim.simulate("car", seed=1, duration=1.0).wheel_radius
        return len(estimators.get(name).estimate(rec, axis="y", params=params, wheel_radius=r))
    return len(estimators.get(name).estimate(rec, axis="y", params=params))


def _stft(rec) -> int:
    """The STFT baseline as the robustness benchmark runs it: ay through the thesis high-pass,
    3 s windows, the grid's default range 10-120 rad/s."""
    from vibrospeed.eval.baseline import stft_harmonic_sum
    from vibrospeed.signal import prefilter as pf

    y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
    return int(stft_harmonic_sum(y, rec.dt, 10.0, 120.0).size)


def child_read(path: str, chunked: bool) -> dict:
    import vibrospeed.io.canonical
    import vibrospeed.io.parquet  # noqa: F401 - imported before the baseline is taken
    from vibrospeed import io
    from vibrospeed.io.chunks import ChunkedRecording

    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        pass
    base = _rss_mib()
    _reset_peak()
    t0 = time.perf_counter()
    if chunked:
        n, acc = 0, 0.0
        for c in ChunkedRecording(path):
            n += len(c)
            acc += float(np.nansum(c.channels["ay"]))
    else:
        rec = io.read(path)
        n = len(rec)
    return {"wall": time.perf_counter() - t0, "peak": _peak_mib(), "before": base, "n": n}


def child_stream(path: str, short: str) -> dict:
    """``vibrospeed estimate path`` in this process, after one on ``short`` (compilation),
    on the streaming path whatever the length (its threshold set to 0 rows)."""
    from vibrospeed.cli.app import app
    from vibrospeed.estimators.grid import stream

    stream.STREAM_ROWS = 0

    out = Path(tempfile.mkdtemp())
    app(["estimate", short, "-o", str(out / "short.csv")], standalone_mode=False)
    before = _rss_mib()
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    app(["estimate", path, "-o", str(out / "est.csv")], standalone_mode=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    with open(out / "est.csv") as fh:
        rows = sum(1 for _ in fh) - 1
    return {"wall": wall, "cpu": cpu, "peak": _peak_mib(), "before": before, "n": rows}


def child_cli(mode: str, path: str, short: str, args_json: str) -> dict:
    """``vibrospeed estimate path *args`` in this process after the same on ``short``, on the
    streaming path (``mode`` "stream": threshold 0 rows) or the whole-log one ("whole")."""
    from vibrospeed.cli.app import app
    from vibrospeed.estimators.grid import stream

    stream.STREAM_ROWS = 0 if mode == "stream" else 10**15
    out = Path(tempfile.mkdtemp())
    args = [a.replace("{out}", str(out)) for a in json.loads(args_json)]
    app(["estimate", short, *args, "-o", str(out / "short.csv")], standalone_mode=False)
    before = _rss_mib()
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    app(["estimate", path, *args, "-o", str(out / "est.csv")], standalone_mode=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    with open(out / "est.csv") as fh:
        rows = sum(1 for _ in fh) - 1
    return {"wall": wall, "cpu": cpu, "peak": _peak_mib(), "before": before, "n": rows}


def _write_logger_csv(rec, dest: Path) -> None:
    """``rec``'s accelerometer as a data logger might write it: ``date;time_ms;acc_x;acc_y;
    acc_z`` (ms, g, shortest round-trip floats), a chunk of rows at a time."""
    g = 9.80665
    with open(dest, "w") as fh:
        fh.write("date;time_ms;acc_x;acc_y;acc_z\n")
        for a in range(0, len(rec), 50_000):
            b = min(a + 50_000, len(rec))
            cols = [rec.t[a:b] * 1e3, *(rec.channel(c)[a:b] / g for c in ("ax", "ay", "az"))]
            fh.write("".join(f"2026-01-01;{t!r};{x!r};{y!r};{z!r}\n"
                             for t, x, y, z in zip(*(c.tolist() for c in cols), strict=True)))


OPTIONS = (
    ("mapped CSV (`--columns t=time_ms:ms,ax=acc_x:g,...`)", "csv",
     ["-m", "grid", "--columns", "t=time_ms:ms,ax=acc_x:g,ay=acc_y:g,az=acc_z:g"]),
    ("`--lag 3`", "parquet", ["-m", "grid", "--lag", "3"]),
    ("`--plot`", "parquet", ["-m", "grid", "--plot", "{out}/p.png"]),
)


def part_options(lengths, tmp: Path, modes=("stream", "whole")) -> list[str]:
    from vibrospeed import io, sim

    out = ["## What else streams: mapped CSVs, `--lag`, `--plot`", "",
           "`vibrospeed estimate` on the 1 h `simulate(\"car\", seed=1)` drive (repeated end "
           "to end for longer logs), each option through the streaming path (the CLI takes it "
           "above 500 000 rows; here at every length) and through the whole-log path (the "
           "threshold raised), in fresh processes after a 10 s run of the same command; CPU "
           "time and peak RSS of the command, the output written. The mapped CSV is a logger's "
           "file (`date;time_ms;acc_x;acc_y;acc_z`, ms and g, 3 axes only); the others the "
           "Parquet file of 6 IMU channels.", "",
           "| what | length | path | CPU s | wall s | peak MiB | before MiB |",
           "|---|---|---|---|---|---|---|"]
    short = _imu(sim.simulate("car", seed=1, duration=10.0))
    io.write(short, tmp / "opt_short.parquet")
    _write_logger_csv(short, tmp / "opt_short.txt")
    for L in lengths:
        k = max(1, int(round(L / 3600.0)))
        base = tmp / "opt_1h.parquet"
        rec = _imu(sim.simulate("car", seed=1, duration=min(L, 3600.0)))
        io.write(rec, base)
        files = {"parquet": base}
        if k > 1:
            files["parquet"] = tmp / f"opt_{k}h.parquet"
            _write_repeated(base, files["parquet"], k)
            import pyarrow.parquet as pq

            from vibrospeed.types import Recording

            tab = pq.read_table(files["parquet"], columns=["t", "ax", "ay", "az"])
            rec = Recording(tab.column("t").to_numpy(),
                            {c: tab.column(c).to_numpy() for c in ("ax", "ay", "az")})
            del tab
        files["csv"] = tmp / f"opt_{k}h.txt"
        _write_logger_csv(rec, files["csv"])
        del rec
        for what, kind, args in OPTIONS:
            short_p = tmp / ("opt_short.txt" if kind == "csv" else "opt_short.parquet")
            for mode in modes:
                r = _child(["cli", mode, str(files[kind]), str(short_p), json.dumps(args)])
                path = "streamed" if mode == "stream" else "whole log"
                if "error" in r:
                    out.append(f"| {what} | {_len(L)} | {path} | - | - | - | {r['error']} |")
                else:
                    out.append(f"| {what} | {_len(L)} | {path} | {r['cpu']:.0f} | "
                               f"{r['wall']:.0f} | {r['peak']:.0f} | {r['before']:.0f} |")
                print(out[-1], flush=True)
        for f in files.values():
            if f != base:
                f.unlink()
    return out


def _write_repeated(src: Path, dest: Path, times: int) -> None:
    """``src`` (Parquet) ``times`` times end to end (time shifted), written a copy at a time."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tab = pq.read_table(src)
    t = tab.column("t").to_numpy()
    period = float(t[-1] - t[0]) + float(t[1] - t[0])
    with pq.ParquetWriter(dest, tab.schema) as w:
        for k in range(times):
            part = tab.set_column(0, "t", pa.array(t + k * period))
            w.write_table(part, row_group_size=65536)


def part_stream(lengths, tmp: Path) -> list[str]:
    from vibrospeed import io, sim

    base = tmp / "stream_1h.parquet"
    io.write(_imu(sim.simulate("car", seed=1, duration=3600.0)), base)
    short = tmp / "stream_short.csv"
    io.write(_imu(sim.simulate("car", seed=1, duration=10.0)), short)
    out = ["## Streaming: `vibrospeed estimate` on long logs", "",
           "The default grid estimate through the CLI (`vibrospeed estimate day.parquet -o "
           "est.csv`) on the 1 h `simulate(\"car\", seed=1)` drive (6 IMU channels, Parquet) "
           "repeated end to end, on the streaming path (the CLI takes it above 500 000 rows; "
           "here at every length): it reads in chunks, estimates in 600 s blocks (120 s "
           "look-ahead) and appends each block to its output. CPU and wall time "
           "and peak RSS of the command in a fresh process (after a 10 s run that compiles or "
           "loads the kernels), the output CSV written.", "",
           "| length | rows | CPU s | x real time (CPU) | wall s | peak MiB | before MiB |",
           "|---|---|---|---|---|---|---|"]
    done = []
    for L in lengths:
        k = max(1, int(round(L / 3600.0)))
        p = tmp / f"stream_{k}h.parquet"
        if k > 1:
            _write_repeated(base, p, k)
        else:
            p = base
        r = _child(["stream", str(p), str(short)])
        if "error" in r:
            out.append(f"| {_len(k * 3600.0)} | - | - | - | - | - | {r['error']} |")
        else:
            out.append(f"| {_len(k * 3600.0)} | {r['n']} | {r['cpu']:.0f} | "
                       f"{k * 3600.0 / r['cpu']:.0f} | {r['wall']:.0f} | {r['peak']:.0f} | "
                       f"{r['before']:.0f} |")
        print(out[-1], flush=True)
        if k > 1:
            p.unlink()
        if "error" not in r:
            done.append((k * 3600.0, r))
    if len(done) >= 2 and done[-1][0] < DAY:  # the straight line through the last two
        (L0, r0), (L1, r1) = done[-2], done[-1]
        k = (r1["peak"] - r0["peak"]) / (L1 - L0)
        cpu = r1["cpu"] * DAY / L1
        out.append(f"| 24 h | {int(DAY * r1['n'] / (L1 / 3600.0) / 3600.0)} | {cpu:.0f} | "
                   f"{DAY / cpu:.0f} | - | {r1['peak'] + k * (DAY - L1):.0f} | - |")
        out += ["", f"24 h *extrapolated*: CPU time in proportion to length, peak memory along "
                f"the straight line through the two longest measured lengths "
                f"({1000 * k:.1f} MiB per 1000 s of log)."]
    return out


def _child(args: list[str]) -> dict:
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT / "src"))
    out = subprocess.run([sys.executable, __file__, "_child", *args], capture_output=True,
                         text=True, env=env)
    if out.returncode:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


# ---- parts ------------------------------------------------------------------------------
def part_lengths(lengths, methods, tmp: Path) -> list[dict]:
    from vibrospeed import io, sim

    rows = []
    for L in lengths:
        p = tmp / f"car_{int(L)}.parquet"
        rec = _imu(sim.simulate("car", seed=1, duration=L))
        io.write(rec, p)
        del rec
        for m in methods:
            r = _child(["estimate", m, str(p)])
            r.update(method=m, length=L)
            rows.append(r)
            print(f"  {m:12s} {L:7.0f} s: {r}", flush=True)
    return rows


def _imu(rec):
    """The phone-like part of a simulated drive: ax, ay, az, gx, gy, gz."""
    keep = ("ax", "ay", "az", "gx", "gy", "gz")
    return type(rec)(rec.t, {k: rec.channels[k] for k in keep}, source=rec.source,
                     wheel_radius=rec.wheel_radius)


def _slope(x0, y0, x1, y1) -> float:
    return float(np.log(y1 / y0) / np.log(x1 / x0))


def render_lengths(rows: list[dict], lengths) -> list[str]:
    out = ["## Time and peak memory against log length", "",
           "`simulate(\"car\", seed=1)` at 100 Hz (its 6 IMU channels), read from Parquet "
           "in a fresh process; CPU time (the process's user + system) and wall time of "
           "`estimate` (or the STFT baseline; after a 10 s run that compiles the kernels), "
           "real-time factor (log length / CPU time: the machine is shared, so wall time is "
           "longer than CPU time when other jobs run), "
           "peak RSS of the process during the estimate (recording included) and its RSS "
           "before it. "
           "Rows marked *extrapolated*: CPU time in proportion to length from the longest "
           "measured one (the measured log-log slope is printed), peak memory by the straight "
           "line (MiB per s of log) through the two longest measured lengths.", "",
           "| method | length | CPU s | x real time (CPU) | wall s | peak MiB | before MiB | "
           "note |",
           "|---|---|---|---|---|---|---|---|"]
    by = {}
    for r in rows:
        by.setdefault(r["method"], []).append(r)
    for m, rs in by.items():
        ok = [r for r in rs if "error" not in r]
        for r in rs:
            if "error" in r:
                out.append(f"| {m} | {_len(r['length'])} | - | - | - | - | - | {r['error']} |")
                continue
            out.append(f"| {m} | {_len(r['length'])} | {r['cpu']:.2f} | "
                       f"{r['length'] / r['cpu']:.0f} | {r['wall']:.2f} | {r['peak']:.0f} | "
                       f"{r['before']:.0f} | |")
        if len(ok) >= 2:
            a, b = ok[-2], ok[-1]
            st = _slope(a["length"], a["cpu"], b["length"], b["cpu"])
            k = (b["peak"] - a["peak"]) / (b["length"] - a["length"])  # MiB per s of log
            for L in (3 * 3600.0, DAY):
                if L <= b["length"]:
                    continue
                w = b["cpu"] * L / b["length"]  # linear: the per-sample work is constant
                pk = b["peak"] + k * (L - b["length"])
                out.append(f"| {m} | {_len(L)} | {w:.0f} | {L / w:.0f} | - | {pk:.0f} | - | "
                           f"*extrapolated* linearly (measured time ~ length^{st:.2f}; memory "
                           f"{1000 * k:.0f} MiB per 1000 s) |")
    return out


def _len(L: float) -> str:
    return f"{L / 3600:.0f} h" if L >= 3600 else f"{L / 60:.0f} min"


def part_online(ref: str | None) -> list[str]:
    from vibrospeed import sim
    from vibrospeed.estimators import ekf, grid, rbpmf
    from vibrospeed.estimators.common import start_level
    from vibrospeed.estimators.online import OnlineTracker
    from vibrospeed.signal import whiten

    rec = sim.simulate("car", seed=1, duration=60)
    ay = rec["ay"]
    out = ["## Online: microseconds per sample", "",
           "`OnlineTracker` fed `simulate(\"car\", seed=1)`'s ay sample by sample (3000 samples "
           "after 300, best of 3, CPU time) and `whiten.step` alone (12 000 samples of white "
           "noise, best of 3; the predictor runs once per second in both).", "",
           "| what | us / sample |", "|---|---|"]
    for label, mod, params in (("OnlineTracker grid (causal)", grid, {"smooth": "none"}),
                               ("OnlineTracker rbpmf", rbpmf, {}),
                               ("OnlineTracker ekf", ekf, {})):
        if mod is ekf:  # the EKF's estimate() defaults: unit-RMS model at the log's rate
            from vibrospeed.models.harmonic import HarmonicModel

            cfg = ekf.Config(model=HarmonicModel(**{**ekf.UNIT_RMS_MODEL, "dt": rec.dt}))
        else:
            cfg = mod.config_for(rec, axis="y", params=params)
        best = np.inf
        for _ in range(3):
            trk = OnlineTracker(mod, cfg, level=start_level(ay, rec.dt))
            for v in ay[:300]:
                trk.update(v)
            t0 = time.process_time()
            for v in ay[300:3300]:
                trk.update(v)
            best = min(best, (time.process_time() - t0) / 3000 * 1e6)
        out.append(f"| {label} | {best:.1f} |")
        print(out[-1], flush=True)
    out += _online_lagged(rec)
    # the causal grid's comb evidence alone: one frame at a time, as its step asks for it
    cfg = grid.config_for(rec, axis="y", params={"smooth": "none"})
    y = (ay - np.mean(ay)) / np.std(ay)
    L, H = cfg.frame_len, cfg.hop_len
    frames = [y[e - L + 1 : e + 1][None, :] for e in range(L - 1 + 300, L - 1 + 300 + 100 * H, H)]
    grid.frame_evidence(cfg, frames[0])
    best = np.inf
    for _ in range(3):
        t0 = time.process_time()
        for fr in frames:
            grid.frame_evidence(cfg, fr)
        best = min(best, (time.process_time() - t0) / len(frames) * 1e6)
    out.append(f"| comb evidence of one {L}-sample frame ({cfg.rates_in_frame(L).size} rates; "
               f"every {H} samples) | {best:.0f} per frame, {best / H:.1f} per sample |")
    print(out[-1], flush=True)
    x = np.random.default_rng(0).normal(size=12000)
    mods = [("whiten.step (this tree)", whiten)]
    if ref:
        import importlib.util

        src = subprocess.run(["git", "show", f"{ref}:src/vibrospeed/signal/whiten.py"],
                             capture_output=True, text=True, cwd=ROOT, check=True).stdout
        d = Path(tempfile.mkdtemp())
        # since 044fd30 the compiled kernels live beside the whitener: take REF's too, so the
        # row is the whitener at REF and not REF's model level on this tree's kernels
        kernels = subprocess.run(
            ["git", "show", f"{ref}:src/vibrospeed/signal/_whiten_kernels.py"],
            capture_output=True, text=True, cwd=ROOT)
        if kernels.returncode == 0:
            (d / "_whiten_kernels_ref.py").write_text(kernels.stdout)
            src = src.replace("from vibrospeed.signal._whiten_kernels import",
                              "from _whiten_kernels_ref import")
            sys.path.insert(0, str(d))
        (d / "whiten_ref.py").write_text(src)
        spec = importlib.util.spec_from_file_location("whiten_ref", d / "whiten_ref.py")
        old = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(old)
        mods.append((f"whiten.step at {ref}", old))
    for label, mod in mods:
        for no_pred in (False, True):
            saved = mod.predictor
            if no_pred:
                a = np.zeros(mod.ORDER + 1)
                a[0] = 1.0
                mod.predictor = lambda h, fs, a=a: (a, 1.0)
            best = np.inf
            for _ in range(3):
                st = mod.init()
                t0 = time.process_time()
                for v in x:
                    st, _ = mod.step(st, v, 100.0)
                best = min(best, (time.process_time() - t0) / x.size * 1e6)
            mod.predictor = saved
            out.append(f"| {label}{' without the predictor' if no_pred else ''} | {best:.2f} |")
            print(out[-1], flush=True)
    out += _online_parts(rec, ay)
    return out


def _online_lagged(rec) -> list[str]:
    """Rows of the fixed-lag grid on a device (:class:`~vibrospeed.estimators.grid.
    LaggedTracker`, lag 2 s) against the causal one, without and with the stops on the three
    accelerometer axes (3000 samples after 300, best of 3, CPU time)."""
    from vibrospeed.estimators import grid
    from vibrospeed.estimators.common import start_level
    from vibrospeed.estimators.online import OnlineTracker

    ay, ax, az = rec["ay"], rec["ax"], rec["az"]
    lv = start_level(ay, rec.dt)
    causal = grid.config_for(rec, axis="y", params={"smooth": "none"})
    lagged = grid.config_for(rec, axis="y", params={"smooth": "lag", "lag": 2.0})
    rows = []
    for label, make, still in (
            ("OnlineTracker grid (causal), standstill=3",
             lambda: OnlineTracker(grid, causal, level=lv, standstill=3), True),
            ("LaggedTracker grid (smooth=lag, lag 2 s)",
             lambda: grid.LaggedTracker(lagged, level=lv), False),
            ("LaggedTracker grid (smooth=lag, lag 2 s), standstill=3",
             lambda: grid.LaggedTracker(lagged, level=lv, standstill=3), True)):
        best = np.inf
        for _ in range(3):
            trk = make()
            for k in range(3300):
                if k == 300:
                    t0 = time.process_time()
                if still:
                    trk.update(ay[k], (ax[k], az[k]))
                else:
                    trk.update(ay[k])
            best = min(best, (time.process_time() - t0) / 3000 * 1e6)
        rows.append(f"| {label} | {best:.1f} |")
        print(rows[-1], flush=True)
    rows += _online_fuse()
    return rows


def _online_fuse() -> list[str]:
    """The rows of ``fuse`` on a device (:class:`~vibrospeed.estimators.fuse.device.
    FuseTracker`, causal and with a 2 s lag, default grid, the stops on three axes) on a
    simulated car with 10 Hz GPS and a tunnel (``simulate("random", seed=3, vehicle="car",
    gps_model=outage_gps())``, 40 s at 100 Hz), every sample and ``finish()``, best of 2, CPU
    time."""
    from vibrospeed import sim
    from vibrospeed.estimators.common import start_level
    from vibrospeed.estimators.fuse.device import FuseTracker, config_for
    from vibrospeed.sim.gps import outage_gps

    rec = sim.simulate("random", seed=3, duration=40, vehicle="car", gps_model=outage_gps())
    cols = [rec[c] for c in ("ax", "ay", "gps_speed", "gps_sats", "az")]
    rows = []
    for params, what in (({}, "fuse online"), ({"lag": 2.0}, "fuse -p lag=2")):
        cfg, tc = config_for(rec, params=params)
        lv = start_level(rec["ay"], tc.tracker.model.dt)
        best = np.inf
        for _ in range(2):
            dev = FuseTracker(cfg, tc, level=lv)
            t0 = time.process_time()
            for i, (x, y, g, s, z) in enumerate(zip(*cols, strict=True)):
                dev.update(rec.t[i], x, y, g, s, others=(x, z))
            dev.finish()
            best = min(best, (time.process_time() - t0) / len(rec) * 1e6)
        rows.append(f"| FuseTracker ({what}, grid N = {tc.tracker.n_grid}, standstill=3) | "
                    f"{best:.1f} |")
        print(rows[-1], flush=True)
    return rows


def _online_parts(rec, ay) -> list[str]:
    """Rows of the causal grid's per-sample cost by part: its filter's step without the comb
    evidence, the pre-filter's and the normaliser's steps (best of 3, CPU time)."""
    from vibrospeed.estimators import grid
    from vibrospeed.estimators.grid import filter as gf
    from vibrospeed.signal import normalize as nz
    from vibrospeed.signal import prefilter as pf

    cfg = grid.config_for(rec, axis="y", params={"smooth": "none"}).tracker
    y = (ay - np.mean(ay)) / np.std(ay)
    st0 = gf.init(cfg)
    for v in y[:300]:
        st0, _ = gf.step(cfg, st0, v)
    sos = pf.design("whiten", 1.0 / float(rec.dt))

    def filt():
        st = st0
        for v in y[300:3300]:
            st, _ = gf.step(cfg, st, v)

    def pre():
        st = pf.init(sos, float(ay[0]))
        for v in ay[300:3300]:
            st, _ = pf.step(sos, st, v)

    dt = float(rec.dt)

    def norm():
        st = nz.init()
        for v in y[300:3300]:
            st, _ = nz.step(st, v, dt, 5.0)

    rows = []
    for label, fn in (("grid filter step alone (the causal grid's, no comb evidence)", filt),
                      ("prefilter.step (2nd-order high-pass)", pre),
                      ("normalize.step", norm)):
        best = np.inf
        for _ in range(3):
            t0 = time.process_time()
            fn()
            best = min(best, (time.process_time() - t0) / 3000 * 1e6)
        rows.append(f"| {label} | {best:.2f} |")
        print(rows[-1], flush=True)
    return rows


def part_startup(tmp: Path) -> list[str]:
    from vibrospeed import io, sim

    p = tmp / "short.csv"
    io.write(sim.simulate("car", seed=1, duration=10), p)
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT / "src"))
    cache = Path(tempfile.mkdtemp())
    env["NUMBA_CACHE_DIR"] = str(cache)
    out = ["## Start-up: `vibrospeed estimate` on a 10 s file", "",
           "CPU and wall time of the whole command (`python -m vibrospeed estimate short.csv -o "
           "est.csv`, default grid) with an empty numba cache directory, then again with the "
           "cache that run left; the import of the CLI alone for reference.", "",
           "| run | CPU s (user + system) | wall s |", "|---|---|---|"]
    runs = [("import vibrospeed.cli.app", [sys.executable, "-c", "import vibrospeed.cli.app"]),
            ("estimate, empty numba cache", None), ("estimate, numba cache warm", None),
            ("estimate, numba cache warm (again)", None)]
    for label, cmd in runs:
        cmd = cmd or [sys.executable, "-m", "vibrospeed", "estimate", str(p), "-o",
                      str(tmp / "est.csv")]
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                env=env)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        ok = os.waitstatus_to_exitcode(status) == 0
        out.append(f"| {label} | {ru.ru_utime + ru.ru_stime:.2f} | {wall:.2f}"
                   f"{'' if ok else ' (failed)'} |")
        print(out[-1], flush=True)
    return out


def part_read(tmp: Path, L: float) -> list[str]:
    from vibrospeed import io, sim

    rec = _imu(sim.simulate("car", seed=1, duration=L))
    out = [f"## Reading a {_len(L)} log whole or in chunks", "",
           "Peak RSS of a fresh process over its RSS after the imports: `io.read` (the whole "
           "recording) against `ChunkedRecording` (65 536 rows per chunk, summing ay).", "",
           "| file | size MiB | whole: wall s | whole: MiB | chunks: wall s | chunks: MiB |",
           "|---|---|---|---|---|---|"]
    for suffix in (".csv", ".parquet"):
        p = tmp / f"read{suffix}"
        io.write(rec, p)
        w = _child(["read", "0", str(p)])
        c = _child(["read", "1", str(p)])
        out.append(f"| {suffix[1:]} ({len(rec)} rows, {len(rec.channels)} channels) | "
                   f"{p.stat().st_size / 2**20:.0f} | {w['wall']:.1f} | "
                   f"{w['peak'] - w['before']:.0f} | {c['wall']:.1f} | "
                   f"{c['peak'] - c['before']:.0f} |")
        print(out[-1], flush=True)
    return out


def plot(rows: list[dict], dest: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    by = {}
    for r in rows:
        if "error" not in r:
            by.setdefault(r["method"], []).append(r)
    for m, rs in by.items():
        L = np.array([r["length"] for r in rs])
        w = np.array([r["cpu"] for r in rs])
        pk = np.array([r["peak"] for r in rs])
        (line,) = a1.loglog(L, w, "o-", label=m)
        a2.loglog(L, pk, "o-", color=line.get_color(), label=m)
        if L.size >= 2:
            Lx = np.array([L[-1], DAY])
            a1.loglog(Lx, w[-1] * Lx / L[-1], ":", color=line.get_color())
            k = (pk[-1] - pk[-2]) / (L[-1] - L[-2])
            Lm = np.geomspace(L[-1], DAY, 20)
            a2.loglog(Lm, pk[-1] + k * (Lm - L[-1]), ":", color=line.get_color())
    Ls = np.array([60.0, DAY])
    a1.loglog(Ls, Ls / 1000, "k--", lw=1, label="1000x real time")
    a2.axhline(2048, color="k", ls="--", lw=1, label="2 GiB")
    a1.set(xlabel="log length (s)", ylabel="CPU time (s)", title="time (dotted: extrapolated)")
    a2.set(xlabel="log length (s)", ylabel="peak RSS (MiB)", title="peak memory")
    a1.legend(fontsize=7)
    a2.legend(fontsize=7)
    fig.tight_layout()
    dest.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(dest, dpi=110)


def _sections(text: str) -> list[tuple[str, str]]:
    """(heading, text) of each ``## `` section ("" for what comes before the first)."""
    out, head, buf = [], "", []
    for line in text.splitlines(keepends=True):
        if line.startswith("## "):
            out.append((head, "".join(buf)))
            head, buf = line.strip(), []
        buf.append(line)
    out.append((head, "".join(buf)))
    return out


def _merge(dest: Path, body: str) -> str:
    """``dest``'s sections with the ones in ``body`` replaced (a part run alone keeps the
    others)."""
    if not dest.is_file():
        return body
    new = dict(_sections(body))
    old = _sections(dest.read_text())
    heads = [h for h, _ in old]
    merged = [(h, new.get(h, t)) for h, t in old]
    merged += [(h, t) for h, t in _sections(body) if h not in heads]
    return "".join(t if t.endswith("\n\n") or not t else t + "\n" for _, t in merged)


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "_child":
        if argv[1] == "estimate":
            res = child_estimate(argv[2], argv[3])
        elif argv[1] == "stream":
            res = child_stream(argv[2], argv[3])
        elif argv[1] == "cli":
            res = child_cli(argv[2], argv[3], argv[4], argv[5])
        else:
            res = child_read(argv[3], argv[2] == "1")
        print(json.dumps(res))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("parts", nargs="*", default=["lengths", "online", "startup", "read"])
    ap.add_argument("--lengths", default="60,600,3600")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--whiten-ref", default=None)
    ap.add_argument("--read-length", type=float, default=3600.0)
    ap.add_argument("--stream-lengths", default="3600,21600")
    ap.add_argument("--options-lengths", default="3600")
    ap.add_argument("--options-modes", default="stream,whole")
    ap.add_argument("--write", action="store_true")
    a = ap.parse_args(argv)
    lengths = [float(x) for x in a.lengths.split(",")]
    methods = [m for m in a.methods.split(",") if m]
    text = ["# Scale: time and memory against log length (`benchmarks/scale.py`)", "",
            "Shared 2-core VM (other jobs running: wall times are upper bounds), one process, "
            "float64.", ""]
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if "lengths" in a.parts:
            rows = part_lengths(lengths, methods, tmp)
            text += render_lengths(rows, lengths) + [""]
        if "grid" in a.parts:  # the default alone, e.g. after a change to it
            grows = part_lengths(lengths, ["grid"], tmp)
            text += ["## The default grid tracker alone (this tree)", ""]
            text += render_lengths(grows, lengths)[3:] + [""]
        if "online" in a.parts:
            text += part_online(a.whiten_ref) + [""]
        if "startup" in a.parts:
            text += part_startup(tmp) + [""]
        if "read" in a.parts:
            text += part_read(tmp, a.read_length) + [""]
        if "stream" in a.parts:
            text += part_stream([float(x) for x in a.stream_lengths.split(",")], tmp) + [""]
        if "options" in a.parts:
            text += part_options([float(x) for x in a.options_lengths.split(",")], tmp,
                                 a.options_modes.split(",")) + [""]
    body = "\n".join(text) + "\n"
    print(body)
    if a.write:
        dest = HERE / "scale" / "RESULTS.md"
        dest.parent.mkdir(exist_ok=True)
        dest.write_text(_merge(dest, body))
        if rows:
            plot(rows, ROOT / "docs" / "img" / "scale.png")
            (HERE / "scale" / "lengths.json").write_text(json.dumps(rows, indent=1))
        print(f"wrote {dest}")


if __name__ == "__main__":
    main()
