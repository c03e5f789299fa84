"""One axis or all three in the grid's comb evidence (``-p comb_axes=all``;
benchmarks/trackers/RESULTS.md follow-up 5). The lock from an unknown start and the 15-seed
accuracy are in ``trackers.py`` (rows "comb_axes xyz"); this script gives the rest of that
section.

Usage (by hand, from the repository root; ~10 min on one core)::

    PYTHONPATH=src .venv/bin/python benchmarks/axes.py [sim] [tracked] [kart] [noline] [--seeds 3]

* sim: simulated ``car`` and ``cart`` (range [2, 30]), grid smoother and causal filter with
  axis y alone and with ``comb_axes=xyz``: share of the moving time within max(2 rad/s, 10 %)
  and has_signal while standing (omega_true <= 5 rad/s).
* tracked: the same with the time-domain (tracked) axis x or z instead of y: what a wrong
  axis choice (a phone of unknown orientation) costs with one axis and with all three.
* kart: GoPro kart, tracked axis z, range [60, 300], paper-hp, M = 2
  (benchmarks/beyond/RESULTS.md): k fitted to the GPS speed, share within 5 % / 10 % of k v
  (and 5 % two-fold).
* noline: Hungary drives (az tracked) and the comma2k19 phone (each axis tracked), where no
  wheel line is visible: band coverage, confident misses and claimed share (real_recordings.py
  definitions).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from vibrospeed import io, sim
from vibrospeed.estimators import get

sys.path.insert(0, str(Path(__file__).resolve().parent))
import real_recordings as R  # noqa: E402
from beyond import SCEN, metrics  # noqa: E402

VARIANTS = (("y only", {}), ("comb_axes xyz", {"comb_axes": "xyz"}))


def simulated(seeds: int) -> None:
    print("| scenario | comb axes | smoothed % | causal % | has_signal standing: smoothed / "
          "causal % |")
    print("|---|---|---|---|---|")
    for scen in ("car", "cart"):
        for label, extra in VARIANTS:
            ok = {"fb": [], "none": []}
            still = {"fb": [], "none": []}
            for seed in range(seeds):
                rec = sim.simulate(scen, seed=seed)
                truth = rec["omega_true"]
                for sm in ok:
                    tr = get("grid").estimate(rec, axis="y",
                                              params={**SCEN[scen], **extra, "smooth": sm})
                    ok[sm].append(metrics(rec.t, tr.omega, truth)["ok_moving"])
                    hs = np.asarray(tr.extras["has_signal"], bool)
                    still[sm].append(hs[truth <= 5.0].mean())
            print(f"| {scen} | {label} | {100 * np.mean(ok['fb']):.1f} | "
                  f"{100 * np.mean(ok['none']):.1f} | {100 * np.mean(still['fb']):.1f} / "
                  f"{100 * np.mean(still['none']):.1f} |", flush=True)


def tracked_axis(seeds: int) -> None:
    """The tracked (time-domain) axis x or z instead of y, one axis vs all three in the comb
    evidence: how much a wrong axis choice (a phone of unknown orientation) costs."""
    print("| scenario | tracked axis | comb axes | smoothed % | causal % |")
    print("|---|---|---|---|---|")
    for scen in ("car", "cart"):
        for ax in "xz":
            for label, extra in (("that axis only", {}), ("all", {"comb_axes": "all"})):
                ok = {"fb": [], "none": []}
                for seed in range(seeds):
                    rec = sim.simulate(scen, seed=seed)
                    for sm in ok:
                        tr = get("grid").estimate(rec, axis=ax,
                                                  params={**SCEN[scen], **extra, "smooth": sm})
                        ok[sm].append(metrics(rec.t, tr.omega, rec["omega_true"])["ok_moving"])
                print(f"| {scen} | {ax} | {label} | {100 * np.mean(ok['fb']):.1f} | "
                      f"{100 * np.mean(ok['none']):.1f} |", flush=True)


def kart() -> None:
    rec = io.read(R.KART / "GX030410_accl_raw.csv", columns="ax=c1,ay=c2,az=c3", rate=198.4)
    gps = pd.read_csv(R.KART / "GX030410_gps_speed.csv")
    tg, v = gps["t_video_s"].to_numpy(float), gps["gps_speed2d_mps"].to_numpy(float)
    base = {"prefilter": "paper-hp", "omega_min": 60.0, "omega_max": 300.0, "M": 2}
    print("| kart, axis z | comb axes | k | within 5 % | within 10 % | within 5 % two-fold |")
    print("|---|---|---|---|---|---|")
    for sm, name in (("fb", "smoother"), ("none", "filter")):
        for label, extra in (("z only", {}), ("comb_axes all", {"comb_axes": "all"})):
            tr = get("grid").estimate(rec, axis="z", params={**base, **extra, "smooth": sm})
            w = np.interp(tg, tr.t, tr.omega, left=np.nan, right=np.nan)
            k, s5, s2 = R._kfit(w, v)
            ok = np.isfinite(w) & (v > 3.0)
            s10 = (np.sum(np.abs(w[ok] - k * v[ok]) < 0.1 * k * v[ok]) / max((v > 3.0).sum(), 1))
            print(f"| {name} | {label} | {k:.2f} | {100 * s5:.1f} | {100 * s10:.1f} | "
                  f"{100 * s2:.1f} |", flush=True)


def noline() -> None:
    R.NOLINE_METHODS = [
        (f"grid ({name}, {label})", "grid", {**extra, **({"smooth": "none"} if sm else {})})
        for sm, name in ((False, "smoother"), (True, "filter")) for label, extra in
        (("one axis", {}), ("comb_axes all", {"comb_axes": "all"}))]
    drives = sorted(p for p in R.HUNGARY.iterdir() if p.is_dir())
    recs = [io.read(p, "phyphox") for p in drives]
    rows = R._noline_recordings(
        recs, lambda r: (r["gps_speed"] / R.R_HUNGARY, np.isfinite(r["gps_speed"])), "z", "z",
        False, False)
    print("Hungary drives (truth GPS / r)\n\n" + R._noline_table(rows))
    can = io.read(R.COMMA, "comma2k19")
    phone = R._comma_phone(R.COMMA, can)
    rows = R._noline_recordings([phone], lambda r: (r["wheel_omega"], np.ones(len(r), bool)),
                                "xyz", "z", False, False)
    print("comma2k19 phone IMU (truth CAN wheel speeds)\n\n" + R._noline_table(rows))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("parts", nargs="*", default=["sim", "tracked", "kart", "noline"])
    ap.add_argument("--seeds", type=int, default=3)
    a = ap.parse_args()
    if "sim" in a.parts:
        simulated(a.seeds)
    if "tracked" in a.parts:
        tracked_axis(a.seeds)
    if "kart" in a.parts:
        kart()
    if "noline" in a.parts:
        noline()


if __name__ == "__main__":
    main()
