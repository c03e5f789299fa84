"""The standstill detector alone on the randomised family and the real Hungary phone drives.

``PYTHONPATH=src .venv/bin/python benchmarks/robustness/standstill.py --seeds 60 --seed0 0 [--set
NAME=VALUE ...] [--write]`` (a few minutes on the shared 2-core VM). ``--set`` overrides a module
constant of :mod:`vibrospeed.signal.standstill` (e.g. ``MOTION_FRAME_S=1.5``) to compare variants;
``--lag S`` adds the causal detector with an S s delay (the fixed-lag smoother's, ``-p smooth=lag
-p lag=S``). Scores as :mod:`robustness`: "stop detected" is the share of the time standing at
least 1 s away from motion that is declared standing, "false" the share of moving time (true wheel
speed > 0) declared standing; on the real drives, the share of the time with GPS speed above 1 m/s
declared standing. Axes: ``ay`` (the tracked one) plus ``ax`` and ``az``; band: the vehicle class's
search range (omega_min .. 3 omega_max), as :func:`grid.with_standstill`.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))


#: (name, causal, lag s) of the detectors compared; main() appends the --lag ones
DETECTORS = [("offline", False, 0.0), ("causal", True, 0.0)]


def family(seeds) -> dict:
    from vibrospeed.signal import standstill as ss
    from vibrospeed.sim import simulate

    tot: dict = {}
    for s in seeds:
        rec = simulate("random", seed=s, duration=120)
        lo, hi = rec.meta["omega_range"]
        fs = rec.fs
        band = (lo, min(3 * hi, np.pi * fs))
        X = np.column_stack([rec[c] for c in ("ay", "ax", "az")])
        truth = rec["omega_true"]
        k = int(round(fs))
        stop = np.convolve((truth <= 0).astype(float), np.ones(2 * k + 1), "same") >= 2 * k + 1
        for name, causal, lag in DETECTORS:
            f = ss.standstill(X, 1.0 / fs, band, causal=causal, lag=lag)
            for v in (rec.meta["drawn"]["vehicle"], "all"):
                a = tot.setdefault((v, name), np.zeros(4))
                a += [f[stop].sum(), stop.sum(), f[truth > 0].sum(), (truth > 0).sum()]
    return tot


def hungary() -> dict:
    import real_recordings as R

    from vibrospeed import io
    from vibrospeed.signal import standstill as ss

    recs = [io.read(p, "phyphox") for p in sorted(x for x in R.HUNGARY.iterdir() if x.is_dir())]
    out = {}
    for name, causal, lag in DETECTORS:
        st = nm = 0
        for rec in recs:
            g = rec["gps_speed"]
            ok = np.isfinite(g)
            moving = np.interp(rec.t, rec.t[ok], g[ok]) > 1.0
            dt = float(np.median(np.diff(rec.t)))
            X = np.column_stack([rec.channel(c) for c in ("ay", "ax", "az")])
            f = ss.standstill(X, dt, (10.0, min(360.0, np.pi / dt)), causal=causal, lag=lag)
            st += f[moving].sum()
            nm += moving.sum()
        out[name] = st / nm
    return out


def kart() -> dict:
    import pandas as pd
    import real_recordings as R

    from vibrospeed import io
    from vibrospeed.signal import standstill as ss

    rec = io.read(R.KART / "GX030410_accl_raw.csv", columns="ax=c1,ay=c2,az=c3", rate=198.4)
    gps = pd.read_csv(R.KART / "GX030410_gps_speed.csv")
    moving = np.interp(rec.t, gps["t_video_s"].to_numpy(float),
                       gps["gps_speed2d_mps"].to_numpy(float)) > 3.0
    dt = 1.0 / 198.4
    X = np.column_stack([rec.channel(c) for c in ("az", "ax", "ay")])
    return {name: float(ss.standstill(X, dt, (20.0, min(900.0, np.pi / dt)),
                                      causal=causal, lag=lag)[moving].mean())
            for name, causal, lag in DETECTORS}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=60)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--set", action="append", default=[], help="CONSTANT=VALUE of the module")
    ap.add_argument("--no-real", action="store_true", help="skip the Hungary drives")
    ap.add_argument("--write", action="store_true", help="append the table to STANDSTILL.md")
    ap.add_argument("--label", default="")
    ap.add_argument("--lag", type=float, action="append", default=[],
                    help="also the causal detector with this delay (s; repeatable)")
    a = ap.parse_args(argv)
    DETECTORS.extend((f"causal, {lag:g} s lag", True, lag) for lag in a.lag)
    order = [d[0] for d in DETECTORS]
    from vibrospeed.signal import standstill as ss

    for kv in a.set:
        k, v = kv.split("=", 1)
        if not hasattr(ss, k):
            ap.error(f"vibrospeed.signal.standstill has no constant {k}")
        setattr(ss, k, type(getattr(ss, k))(float(v)))
    t0 = time.time()
    tot = family(range(a.seed0, a.seed0 + a.seeds))
    lines = [f"seeds {a.seed0}..{a.seed0 + a.seeds - 1} (120 s each)"
             f"{', ' + ', '.join(a.set) if a.set else ''}", "",
             "| vehicle | detector | stop detected | standstill while moving |",
             "|---|---|---|---|"]
    for (v, name), x in sorted(tot.items(),
                               key=lambda kv: (kv[0][0] == "all", kv[0][0], order.index(kv[0][1]))):
        lines.append(f"| {v} | {name} | {x[0] / max(x[1], 1):.3f} | "
                     f"{100 * x[2] / max(x[3], 1):.2f} % |")
    if not a.no_real:
        h = hungary()
        k = kart()
        lines += ["", "Hungary phone drives, standstill while GPS speed > 1 m/s: "
                  + ", ".join(f"{n} {100 * h[n]:.2f} %" for n in order),
                  "GoPro kart, standstill while GPS speed > 3 m/s: "
                  + ", ".join(f"{n} {100 * k[n]:.2f} %" for n in order)]
    lines.append(f"\n({time.time() - t0:.0f} s wall)")
    text = "\n".join(lines)
    print(text)
    if a.write:
        with open(HERE / "STANDSTILL.md", "a") as f:
            f.write(f"\n## {a.label or 'run'}\n\n{text}\n")


if __name__ == "__main__":
    main()
