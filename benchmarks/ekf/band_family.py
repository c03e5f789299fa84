"""How often the EKF's 98 % band holds the true omega on the randomised family of drives.

    PYTHONPATH=src .venv/bin/python benchmarks/ekf/band_family.py [--seeds 60] [--duration 120]

Each seed of ``simulate("random")`` estimated with ``ekf``'s defaults and the drive's own search
range (``meta["omega_range"]``); per vehicle class, pooled over the moving samples (true omega in
the range): the share whose true omega lies inside ``[omega_lo, omega_hi]`` and the share within
the family's tolerance max(omega_min / 5, 10 %). Prints markdown; nothing is written.
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    from vibrospeed import sim
    from vibrospeed.errors import VibrospeedError
    from vibrospeed.estimators import get

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=60)
    ap.add_argument("--duration", type=float, default=120.0)
    a = ap.parse_args()
    counts: dict[str, np.ndarray] = {}
    skipped = []
    for seed in range(a.seeds):
        rec = sim.simulate("random", seed=seed, duration=a.duration)
        lo, hi = rec.meta["omega_range"]
        try:
            tr = get("ekf").estimate(rec, params={"omega_min": lo, "omega_max": hi})
        except VibrospeedError:  # e.g. M omega_max above Nyquist at 50 Hz
            skipped.append(seed)
            continue
        ot = rec["omega_true"]
        mov = (ot >= lo) & (ot <= hi)
        inside = (ot >= tr.omega_lo) & (ot <= tr.omega_hi)
        ok = np.abs(tr.omega - ot) <= np.maximum(0.1 * ot, lo / 5)
        c = counts.setdefault(rec.meta["drawn"]["vehicle"], np.zeros(3))
        c += [mov.sum(), (inside & mov).sum(), (ok & mov).sum()]
    print(f"{a.seeds} seeds of {a.duration:g} s ({len(skipped)} refused: {skipped})\n")
    print("| vehicle | moving samples | band holds the truth | within tolerance |")
    print("|---|---|---|---|")
    for veh, (n, inside, ok) in sorted(counts.items()):
        print(f"| {veh} | {int(n)} | {100 * inside / n:.1f} % | {100 * ok / n:.1f} % |")


if __name__ == "__main__":
    main()
