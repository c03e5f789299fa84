"""The grid tracker in blocks (:mod:`vibrospeed.estimators.grid.blocks`) against the whole-log
estimate: what the look-ahead costs in accuracy.

Drives: the demo drives of ``benchmarks/architecture/bitwise.py`` (``cart`` seed 1 with wheel
ticks, ``car`` seed 1, ``random`` seed 3; default parameters, as there) and seeds 0.. of the
randomised family (``simulate("random", seed=N, duration=D)``, each with its vehicle class's
search range ``meta["omega_range"]``, as ``benchmarks/robustness/robustness.py`` runs them).
Each is estimated
whole and in blocks of ``--block`` s (far shorter than the default 600 s, so that most samples
are near a block's end, the worst case) with each look-ahead of ``--lookahead``. Per drive and
look-ahead: the largest ``|omega_blocks - omega_whole|`` (rad/s, NaN where both are NaN), the
share of samples whose omega differs at all, and the change of the share within tolerance on
the moving time (truth >= omega_min; ``|omega - omega_true| <= max(10 %, omega_min / 5)``, the
robustness benchmark's score), in points.

    PYTHONPATH=src .venv/bin/python benchmarks/scale_blocks.py [--seeds 6] [--duration 240]
        [--block 30] [--lookahead 10,30,120]
"""

from __future__ import annotations

import argparse

import numpy as np

from vibrospeed import sim
from vibrospeed.config import parse_params
from vibrospeed.estimators.grid import blocks
from vibrospeed.estimators.grid import method as gm

DEMO = {"cart": ("cart", 1, ["ticks=on"]), "car": ("car", 1, []), "random": ("random", 3, [])}


def _within(rec, omega, om_lo: float) -> float:
    truth = rec["omega_true"]
    moving = truth >= om_lo
    ok = np.abs(omega - truth) <= np.maximum(0.1 * truth, om_lo / 5.0)
    return 100.0 * float(np.mean(ok[moving])) if moving.any() else float("nan")


def compare(name: str, rec, params: dict, block_s: float, lookaheads) -> list[str]:
    om_lo = float(params.get("omega_min", 10.0))
    whole = gm.estimate(rec, axis="y", params=dict(params))
    w_in = _within(rec, whole.omega, om_lo)
    rows = []
    for la in lookaheads:
        b = blocks.Blocks(rec, axis="y", params=dict(params), block_s=block_s,
                          lookahead_s=la).track()
        d = np.abs(b.omega - whole.omega)
        both_nan = np.isnan(b.omega) & np.isnan(whole.omega)
        d = np.where(both_nan, 0.0, d)
        dmax = float(np.max(d)) if d.size else 0.0
        share = 100.0 * float(np.mean(d > 0))
        rows.append(f"| {name} | {rec.duration:.0f} | {la:g} | {dmax:.3g} | {share:.2f} | "
                    f"{w_in:.2f} | {_within(rec, b.omega, om_lo) - w_in:+.2f} |")
        print(rows[-1], flush=True)
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--duration", type=float, default=240.0)
    ap.add_argument("--block", type=float, default=30.0)
    ap.add_argument("--lookahead", default="10,30,120")
    a = ap.parse_args(argv)
    las = [float(x) for x in a.lookahead.split(",")]
    print(f"blocks of {a.block:g} s\n")
    print("| drive | s | look-ahead s | max abs d omega (rad/s) | samples differing % | "
          "within, whole-log % | within, blocks - whole (points) |")
    print("|---|---|---|---|---|---|---|")
    for name, (scen, seed, sets) in DEMO.items():
        rec = sim.simulate(scen, seed=seed, **parse_params(sets))
        compare(f"demo {name}", rec, {}, a.block, las)
    for seed in range(a.seeds):
        rec = sim.simulate("random", seed=seed, duration=a.duration)
        lo, hi = rec.meta["omega_range"]
        compare(f"random {seed}", rec, {"omega_min": lo, "omega_max": hi}, a.block, las)


if __name__ == "__main__":
    main()
