"""The same defaults at any sample rate (results -> benchmarks/beyond/RESULTS.md update 4,
benchmarks/aided/RESULTS.md).

Usage (by hand, from the repository root; ~15 min on one core)::

    PYTHONPATH=src .venv/bin/python benchmarks/rates.py [grid] [aided] [aided_grid] [--seeds 3]

* grid: the simulator's ``car`` and ``cart`` (range [2, 30]) drawn at 50 / 100 / 200 / 400 Hz
  (``sim.simulate(..., fs=)``), the grid smoother and causal filter with the defaults
  (tempering 0.2 per 0.01 s of data, ``temper_fs`` 100 Hz) and with the per-sample power
  (``temper_fs=None``): share of the moving time within max(2 rad/s, 10 %).
* aided: ``stop_and_go`` (cart, 120 s, seed 1) at the same rates, aided EKF with the window
  test and with the CUSUM: RMSE (rad/s) with the defaults (windows of 0.2 s, CUSUM threshold
  per 100 Hz) and with the thesis' per-sample values (20-sample windows, threshold 10).
* aided_grid: ``stop_and_go`` seeds 1..seeds at 100-400 Hz, the aided grid trackers
  (``tracker=grid`` / ``rbpmf``) with the sampled random-walk kernel and the earlier q values
  vs the variance-matched kernel (the defaults): mean RMSE (benchmarks/aided/RESULTS.md;
  ``--seeds 8``).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from vibrospeed import sim
from vibrospeed.estimators import get
from vibrospeed.sim.aided import SCENARIOS as AIDED

sys.path.insert(0, str(Path(__file__).resolve().parent))
from beyond import metrics  # noqa: E402

RATES = (50.0, 100.0, 200.0, 400.0)
SCEN = {"car": {}, "cart": {"omega_min": 2.0, "omega_max": 30.0}}


def grid_rates(seeds: int) -> None:
    print("| scenario | fs Hz | per sample: smoothed / causal % | per second (default): "
          "smoothed / causal % |")
    print("|---|---|---|---|")
    for scen, base in SCEN.items():
        for fs in RATES:
            cells = []
            for extra in ({"temper_fs": None}, {}):
                ok = np.zeros(2)
                for seed in range(seeds):
                    rec = sim.simulate(scen, seed=seed, fs=fs)
                    for i, smooth in enumerate(("fb", "none")):
                        tr = get("grid").estimate(rec, axis="y",
                                                  params={**base, **extra, "smooth": smooth})
                        ok[i] += metrics(rec.t, tr.omega, rec["omega_true"])["ok_moving"]
                ok *= 100.0 / seeds
                cells.append(f"{ok[0]:.1f} / {ok[1]:.1f}")
            print(f"| {scen} | {fs:g} | {cells[0]} | {cells[1]} |", flush=True)


def aided_rates() -> None:
    print("| fs Hz | window test: per sample / default | CUSUM: per sample / default |")
    print("|---|---|---|")
    for fs in RATES:
        rec = AIDED["stop_and_go"](seed=1, duration=120, fs=fs)
        cells = []
        for kind in ("window", "cusum"):
            rmse = []
            for extra in ({"ss_n": 20, "mode_n": 20, "cusum_fs": None}, {}):
                tr = get("aided").estimate(rec, axis="y", params={"standstill": kind, **extra})
                rmse.append(float(np.sqrt(np.mean((tr.omega - rec["omega_true"]) ** 2))))
            cells.append(f"{rmse[0]:.3f} / {rmse[1]:.3f}")
        print(f"| {fs:g} | {cells[0]} | {cells[1]} |", flush=True)


def aided_grid_rates(seeds: int) -> None:
    """Aided grid trackers, the paper's sampled kernel with the earlier q values (0.5, accel
    1) vs the variance-matched kernel with their effective values (the defaults)."""
    print("| fs Hz | tracker | sampled, q 0.5 / accel 1 | matched, q 0.025 / accel 0.5 "
          "(default) |")
    print("|---|---|---|---|")
    old = {"kernel_var": "sampled", "q_omega": 0.5, "q_omega_accel": 1.0}
    for fs in (100.0, 200.0, 300.0, 400.0):
        for kind in ("grid", "rbpmf"):
            cells = []
            for extra in (old, {}):
                rmse = []
                for seed in range(1, 1 + seeds):
                    rec = AIDED["stop_and_go"](seed=seed, duration=120, fs=fs)
                    tr = get("aided").estimate(rec, axis="y",
                                               params={"tracker": kind, **extra})
                    rmse.append(np.sqrt(np.mean((tr.omega - rec["omega_true"]) ** 2)))
                cells.append(f"{np.mean(rmse):.3f}")
            print(f"| {fs:g} | {kind} | {cells[0]} | {cells[1]} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", default=["grid", "aided"],
                    choices=["grid", "aided", "aided_grid"])
    ap.add_argument("--seeds", type=int, default=3)
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    if "grid" in a.parts:
        grid_rates(a.seeds)
    if "aided" in a.parts:
        aided_rates()
    if "aided_grid" in a.parts:
        aided_grid_rates(a.seeds)


if __name__ == "__main__":
    main()
