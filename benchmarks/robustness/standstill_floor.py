"""The stop detector against the search range's floor ``omega_min`` on the simple cart
scenarios (``stop_and_go``, ``cart``; 8 seeds each, the three accelerometer axes, band
``(omega_min, 90)`` rad/s): the share of the true stop time found and of the moving time
declared standing, offline and causal.

    PYTHONPATH=src .venv/bin/python benchmarks/robustness/standstill_floor.py [--causal]

Why: the body-motion test (``signal.standstill``) is used only where its band, 0.2 Hz up to
0.7 omega_min / 2 pi, reaches 1 Hz; below that it held little but a braking's tail and lost a
cart's 3-5 s stops. Prints markdown (STANDSTILL.md, "The range floor").
"""

from __future__ import annotations

import argparse

import numpy as np

from vibrospeed import sim
from vibrospeed.signal import standstill as ss


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--causal", action="store_true", help="the causal detector")
    ap.add_argument("--seeds", type=int, default=8)
    args = ap.parse_args()
    print(f"{'causal' if args.causal else 'offline'}, {args.seeds} seeds per scenario\n")
    print("| scenario | omega_min (rad/s) | stop time found | moving declared standing |")
    print("|---|---|---|---|")
    for scen in ("stop_and_go", "cart"):
        recs = [sim.simulate(scen, seed=s) for s in range(args.seeds)]
        for om in (2.0, 3.0, 5.0, 8.0, 10.0):
            found = stops = false = moving = 0
            for rec in recs:
                X = np.column_stack([rec[c] for c in ("ay", "ax", "az")])
                still = ss.standstill(X, rec.dt, (om, min(90.0, np.pi * rec.fs)),
                                      causal=args.causal)
                truth = rec["omega_true"] < 0.05
                found += int(np.sum(still & truth))
                stops += int(truth.sum())
                false += int(np.sum(still & ~truth))
                moving += int((~truth).sum())
            print(f"| {scen} | {om:g} | {100 * found / max(stops, 1):.1f} % | "
                  f"{100 * false / max(moving, 1):.2f} % |")


if __name__ == "__main__":
    main()
