"""Faults injected into simulated drives, estimated through the CLI: does anything crash, go NaN
or lose accuracy away from the fault?

Each drive (``simulate("car", seed=1)`` and ``simulate("random", seed=s)``, 600 s at 100 Hz) is
written as a canonical CSV with its IMU channels only (``ax ay az gx gy gz``), once clean and
once per fault below, and estimated by ``python -m vibrospeed estimate FILE -o OUT`` (the
default grid tracker, offline) in a subprocess. Per run: exit status, rows out, NaN share of
``omega``, accuracy = share of moving samples (truth omega > 1 rad/s) with
``|omega - truth| <= 0.10 truth``, outside and inside the fault window (the window's own rows
for a local fault; the whole drive for a global one), wall time and peak resident memory of
the CLI process (``os.wait4`` in a small launcher process, see ``_LAUNCH``).

Every row of a faulted file keeps the true time of its sample (the benchmark's record, not in
the file), so an output row's stamped time maps back to true time for the truth even where
the fault moved the stamps (clock drift, clock jump, rate change).

Faults (window ``W`` = 240-300 s true time unless noted):

* ``nan_bursts``: six 1 s bursts of empty cells in ax, ay, az inside W;
* ``time_gap``: the rows of 240-270 s removed (a 30 s hole in the time line); W = 240-300 s;
* ``clipping``: ay clipped at its 95th percentile of ``|ay|`` in W (occasional flat tops);
* ``stuck``: ax, ay, az hold their last value for 250-270 s (a frozen sensor);
* ``spikes``: 1 % of the samples in W get a spike of +-20 x the axis's RMS;
* ``quant8``: every axis quantised to 8 bits over +-2 g (0.153 m/s^2 steps), whole drive;
* ``rate_change``: from 300 s on every other row dropped (100 -> 50 Hz); W = 300-600 s;
* ``dup_stamps``: 100 rows in W written twice (same stamp, same values); also run ``--sort``;
* ``backward``: 20 adjacent row pairs in W swapped (time goes back); also run ``--sort``;
* ``axis_dropout``: ay empty in W (the tracked axis; ax, az still there);
* ``rate_drift``: the logger's clock gains linearly, stamps 2 % long by the end (whole drive);
* ``clock_jump``: every stamp from 300 s on is 5 s late (a jump forward, no data lost);
  W = 300-360 s;
* ``saturation``: a +-1 g sensor range: every axis clipped at +-9.81 m/s^2 over the whole
  drive (az, which carries +g, sits at the rail about half the time) and in W ay's range
  falls to its 40th percentile of ``|ay|`` (mostly at the rails); W = 240-300 s;
* ``flipped``: from 300 s the phone lies face down (y -> -y, z -> -z); W = 300-360 s.

The family's drives (``random``) are estimated with their search range
(``-p omega_min=.. -p omega_max=..`` from ``meta["omega_range"]``), as a user would give it.

Usage (``--write`` replaces ``benchmarks/faults/RESULTS.md``, ``--append`` adds to its rows;
~25 s CPU per run)::

    PYTHONPATH=src .venv/bin/python benchmarks/faults.py [--random-seeds 4,9] [--no-car]
        [--faults a,b] [--duration 600] [--write [--append]]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vibrospeed import io, sim
from vibrospeed.types import Recording

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
IMU = ("ax", "ay", "az", "gx", "gy", "gz")
ACC = ("ax", "ay", "az")
G0 = 9.80665
W0, W1 = 240.0, 300.0
_KEPT: list[str] = []  # table rows kept from an earlier part (--append)


@dataclass
class Faulted:
    """A faulted drive: the rows to write, each row's true time, the fault window (true s;
    None = the whole drive) and extra CLI arguments to try besides the default."""

    t: np.ndarray  # stamps written
    true_t: np.ndarray  # true time of each row
    ch: dict[str, np.ndarray]
    window: tuple[float, float] | None
    variants: tuple[tuple[str, ...], ...] = ((),)


def _rows(rec: Recording, keep: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    idx = np.arange(len(rec)) if keep is None else keep
    return idx, {k: rec.channels[k][idx].copy() for k in IMU}


def fault(name: str, rec: Recording, rng: np.random.Generator) -> Faulted:
    """``rec`` with fault ``name`` (module docstring)."""
    t = rec.t
    win = (t >= W0) & (t < W1)
    idx, ch = _rows(rec)
    stamps = t.copy()
    window: tuple[float, float] | None = (W0, W1)
    variants: tuple[tuple[str, ...], ...] = ((),)
    if name == "clean":
        window = None
    elif name == "nan_bursts":
        for s in np.linspace(W0 + 2, W1 - 8, 6):
            m = (t >= s) & (t < s + 1.0)
            for k in ACC:
                ch[k][m] = np.nan
    elif name == "time_gap":
        keep = np.flatnonzero(~((t >= W0) & (t < W0 + 30.0)))
        idx, ch = _rows(rec, keep)
        stamps = t[keep]
    elif name == "clipping":
        c = np.percentile(np.abs(ch["ay"][win]), 95)
        ch["ay"][win] = np.clip(ch["ay"][win], -c, c)
    elif name == "stuck":
        m = np.flatnonzero((t >= 250.0) & (t < 270.0))
        for k in ACC:
            ch[k][m] = ch[k][m[0] - 1]
    elif name == "spikes":
        w = np.flatnonzero(win)
        hit = rng.choice(w, size=max(1, w.size // 100), replace=False)
        for k in ACC:
            rms = np.sqrt(np.mean(np.square(ch[k][w] - np.mean(ch[k][w]))))
            ch[k][hit] += rng.choice([-20.0, 20.0], size=hit.size) * rms
    elif name == "quant8":
        step = 4 * G0 / 256
        for k in ACC:
            ch[k] = np.clip(np.round(ch[k] / step) * step, -2 * G0, 2 * G0 - step)
        window = None
    elif name == "rate_change":
        keep = np.flatnonzero((t < W1) | (np.arange(t.size) % 2 == 0))
        idx, ch = _rows(rec, keep)
        stamps = t[keep]
        window = (W1, float(t[-1]) + 1.0)
    elif name == "dup_stamps":
        w = np.flatnonzero(win)
        twice = np.sort(rng.choice(w, size=100, replace=False))
        idx = np.sort(np.concatenate((np.arange(t.size), twice)), kind="stable")
        ch = {k: rec.channels[k][idx].copy() for k in IMU}
        stamps = t[idx]
        variants = ((), ("--sort",))
    elif name == "backward":
        w = np.flatnonzero(win)[::2][:-1]
        pairs = np.sort(rng.choice(w, size=20, replace=False))
        idx = np.arange(t.size)
        idx[pairs], idx[pairs + 1] = pairs + 1, pairs
        ch = {k: rec.channels[k][idx].copy() for k in IMU}
        stamps = t[idx]
        variants = ((), ("--sort",))
    elif name == "axis_dropout":
        ch["ay"][win] = np.nan
    elif name == "rate_drift":
        span = t[-1] - t[0]
        stamps = t[0] + (t - t[0]) * (1.0 + 0.01 * (t - t[0]) / span)  # d stamp/dt: 1 -> 1.02
        window = None
    elif name == "clock_jump":
        stamps = np.where(t >= W1, t + 5.0, t)
        window = (W1, W1 + 60.0)
    elif name == "saturation":
        for k in ACC:
            ch[k] = np.clip(ch[k], -G0, G0)
        c = np.percentile(np.abs(ch["ay"][win]), 40)
        ch["ay"][win] = np.clip(ch["ay"][win], -c, c)
    elif name == "flipped":
        m = t >= W1
        ch["ay"][m] *= -1
        ch["az"][m] *= -1
        ch["gy"][m] *= -1
        ch["gz"][m] *= -1
        window = (W1, W1 + 60.0)
    else:
        raise SystemExit(f"unknown fault {name!r}")
    return Faulted(stamps, t[idx], ch, window, variants)


FAULTS = ("clean", "nan_bursts", "time_gap", "clipping", "stuck", "spikes", "quant8",
          "rate_change", "dup_stamps", "backward", "axis_dropout", "rate_drift", "clock_jump",
          "saturation", "flipped")


#: A small launcher: forks the command and prints its peak RSS (KiB). A child forked (or
#: vforked) straight from this big process would report this process's RSS as its own peak:
#: Linux records the old address space's high-water mark at exec.
_LAUNCH = ("import os, sys\n"
           "pid = os.fork()\n"
           "if pid == 0:\n"
           "    os.execv(sys.argv[1], sys.argv[1:])\n"
           "_, st, ru = os.wait4(pid, 0)\n"
           "sys.stderr.write(f'\\nMAXRSS_KIB {ru.ru_maxrss}\\n')\n"
           "sys.exit(os.waitstatus_to_exitcode(st))\n")


def run_cli(path: Path, out: Path, extra: tuple[str, ...]) -> tuple[int, float, float, str]:
    """(exit status, wall s, peak RSS MiB, last stderr line) of ``vibrospeed estimate``."""
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT / "src"))  # a snapshot's src/ when one is given
    cmd = [sys.executable, "-c", _LAUNCH, sys.executable, "-m", "vibrospeed", "estimate",
           str(path), "-o", str(out), *extra]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    wall = time.perf_counter() - t0
    lines = p.stderr.decode(errors="replace").strip().splitlines()
    mem = float("nan")
    if lines and lines[-1].startswith("MAXRSS_KIB "):
        mem = int(lines.pop().split()[1]) / 1024.0
    lines = [ln for ln in lines if ln.strip()]
    return p.returncode, wall, mem, (lines[-1] if lines else "")


def accuracy(track, f: Faulted, truth_t, truth_w) -> tuple[float, float, float]:
    """(NaN share of omega, accuracy outside the window, inside it)."""
    order = np.argsort(f.t, kind="stable")
    true_at = np.interp(track.t, f.t[order], f.true_t[order])
    w = np.interp(true_at, truth_t, truth_w)
    om = track.omega
    nan_share = float(np.mean(~np.isfinite(om))) if om.size else float("nan")
    moving = w > 1.0
    ok = np.abs(om - w) <= 0.10 * w

    def share(m):
        m = m & moving
        return float(np.mean(ok[m])) if m.any() else float("nan")

    if f.window is None:
        return nan_share, float("nan"), share(np.ones_like(moving))
    inside = (true_at >= f.window[0]) & (true_at < f.window[1])
    return nan_share, share(~inside), share(inside)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--random-seeds", default="4,9")
    ap.add_argument("--no-car", action="store_true")
    ap.add_argument("--faults", default=",".join(FAULTS))
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--append", action="store_true",
                    help="keep the rows already in RESULTS.md (a run split in parts)")
    a = ap.parse_args(argv)
    drives = [] if a.no_car else [("car", 1)]
    drives += [("random", int(s)) for s in a.random_seeds.split(",") if s]
    faults = [f for f in a.faults.split(",") if f]
    if "clean" not in faults:
        faults.insert(0, "clean")
    rows = []
    global _KEPT
    if a.append and (HERE / "faults" / "RESULTS.md").is_file():  # rows of an earlier run
        lines = (HERE / "faults" / "RESULTS.md").read_text().splitlines()
        _KEPT = [ln for ln in lines if ln.startswith("| ") and not ln.startswith("| drive")]
    with tempfile.TemporaryDirectory() as tmp:
        for scen, seed in drives:
            rec = sim.simulate(scen, seed=seed, duration=a.duration)
            # the family's vehicles need their search range, as a user would give it
            rng_args: tuple[str, ...] = ()
            if "omega_range" in rec.meta:
                lo, hi = rec.meta["omega_range"]
                rng_args = ("-p", f"omega_min={lo:g}", "-p", f"omega_max={hi:g}")
            truth_t, truth_w = rec.t, rec.channels["omega_true"]
            clean_ref: dict = {}
            clean = None
            for name in faults:
                f = fault(name, rec, np.random.default_rng(seed))
                src = Path(tmp) / f"{scen}{seed}_{name}.csv"
                io.write(Recording(f.t, f.ch, source=f"{scen}{seed}_{name}"), src)
                for extra in f.variants:
                    out = Path(tmp) / f"{scen}{seed}_{name}_est.csv"
                    out.unlink(missing_ok=True)
                    rc, wall, mem, last = run_cli(src, out, extra + rng_args)
                    row = dict(drive=f"{scen} {seed}", fault=name + (" " + " ".join(extra)
                                                                  if extra else ""),
                               rc=rc, rows=0, nan=float("nan"), acc_out=float("nan"),
                               acc_in=float("nan"), clean_in=float("nan"), wall=wall, mem=mem,
                               msg="" if rc == 0 else last)
                    if rc == 0:
                        tr = io.read_track(out)
                        nan, acc_out, acc_in = accuracy(tr, f, truth_t, truth_w)
                        row.update(rows=len(tr), nan=nan, acc_out=acc_out, acc_in=acc_in)
                    if name == "clean":
                        clean = io.read_track(out)
                        out.rename(Path(tmp) / f"{scen}{seed}_clean_track.csv")
                    elif f.window not in clean_ref:  # the clean drive on the same samples
                        cf = Faulted(rec.t, rec.t, {}, f.window)
                        clean_ref[f.window] = accuracy(clean, cf, truth_t, truth_w)[1:]
                    if name != "clean":
                        row["clean_out"], row["clean_in"] = clean_ref[f.window]
                    rows.append(row)
                    print(fmt_row(row), flush=True)
                    if a.write:  # after every run: a long benchmark keeps what it measured
                        _write(render(rows, a, done=False))
    table = render(rows, a)
    print(table)
    if a.write:
        print(f"wrote {_write(table)}")


def _write(text: str) -> Path:
    dest = HERE / "faults" / "RESULTS.md"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(text)
    return dest


def _p(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{100 * x:.1f}"


def fmt_row(r: dict) -> str:
    return (f"| {r['drive']} | {r['fault']} | {r['rc']} | {r['rows']} | {_p(r['nan'])} | "
            f"{_p(r['acc_out'])} | {_p(r.get('clean_out', float('nan')))} | {_p(r['acc_in'])} "
            f"| {_p(r['clean_in'])} | {r['wall']:.1f} | {r['mem']:.0f} | {r['msg']} |")


def render(rows: list[dict], a, done: bool = True) -> str:
    head = [
        "# Faults injected into simulated drives (`benchmarks/faults.py`)",
        "",
        f"`vibrospeed estimate` (default grid, offline) on simulated drives of "
        f"{a.duration:.0f} s at 100 Hz, IMU channels only. Accuracy: share of moving "
        "samples within 10 % of the true omega, outside / inside the fault window (global "
        "faults: the whole drive under 'in'), each beside the clean drive's share on the "
        "same samples. Wall time and peak RSS of the CLI process (start-up included) on the "
        "shared 2-core VM (heavily loaded while these ran: wall time is 2-5x the CPU time). "
        "The faults are defined in the script's docstring.",
        "",
        "| drive | fault | exit | rows out | NaN % | acc out % | clean out % | acc in % | "
        "clean in % | wall s | peak MiB | message |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    tail = [] if done else ["", "*(partial: the run is still going)*"]
    return "\n".join(head + _KEPT + [fmt_row(r) for r in rows] + tail) + "\n"


if __name__ == "__main__":
    main()
