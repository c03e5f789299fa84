"""Where ``fuse`` online loses the line-visible tunnel time of ``fuse.py sim``, by what the
causal tracker does there.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/online_loss.py [--seeds 30] [--cache DIR]

Same drives, tracks and scoring as ``fuse.py sim`` (``--cache`` shares its grid tracks).
Line-visible tunnel time = tunnel samples where the offline tracker claims a line. Each such
sample falls in one class: the causal tracker claims a line (``has_signal``) or not; its mode
(``omega_mode``) times the true radius is the wheel's (within 3 % of the true speed) or not;
``fuse`` online used a wheel-frequency update there (``source`` 2: taken) or not. Per class:
its share of the line-visible time, and the share of the line-visible time lost in it (the
online speed not within 3 %). Prints a markdown table; nothing is written.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from fuse import _grid, near_axes, sim_recording

CLASSES = ("claims the wheel's line, taken", "claims the wheel's line, not taken",
           "claims another line, taken", "claims another line, not taken",
           "claims none, its mode on the wheel's line", "claims none, its mode elsewhere")


def seed_classes(seed: int, cache: str | None):
    """Per line-visible tunnel sample: its class (index into CLASSES) and whether the online
    speed is within 3 % of the truth; None for a seed whose mount is not near the axes."""
    from vibrospeed.estimators import fuse

    rec = sim_recording(seed)
    if not near_axes(rec):
        return None
    lo, hi = rec.meta["omega_range"]
    p = {"omega_min": lo, "omega_max": hi}
    g_off = _grid(rec, p, cache, f"sim{seed}_off")
    g_on = _grid(rec, {**p, "smooth": "none"}, cache, f"sim{seed}_on")
    f_on = fuse.estimate(rec, vibration=g_on, params={"online": True})
    r = rec.meta["drawn"]["wheel_radius"]
    v = rec["speed_true"]
    vis = (rec["gps_sats"] == 0) & (g_off.extras["has_signal"] > 0.5)
    claim = g_on.extras["has_signal"][vis] > 0.5
    vv = v[vis]
    right = (vv > 1.0) & (np.abs(g_on.extras["omega_mode"][vis] * r / np.maximum(vv, 1e-9)
                                 - 1.0) <= 0.03)
    taken = f_on.extras["source"][vis] == 2
    cls = np.where(claim, np.where(right, np.where(taken, 0, 1), np.where(taken, 2, 3)),
                   np.where(right, 4, 5))
    ok = np.abs(f_on.speed[vis] - vv) <= 0.03 * vv
    return seed, cls, ok


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--cache", default=None, help="folder of fuse.py's grid tracks")
    a = ap.parse_args()
    t0 = time.time()
    res, seed = [], 0
    while len(res) < a.seeds:
        x = seed_classes(seed, a.cache)
        if x is not None:
            res.append(x)
        seed += 1
    cls = np.concatenate([x[1] for x in res])
    ok = np.concatenate([x[2] for x in res])
    n = max(cls.size, 1)
    print(f"{len(res)} drives, line-visible tunnel time {cls.size} samples, online within 3 % "
          f"{100 * ok.mean():.1f} % ({time.time() - t0:.0f} s)\n")
    print("| causal tracker | share of the line-visible time | lost (not within 3 %) | "
          "within 3 % in the class | seeds losing most |")
    print("|---|---|---|---|---|")
    for k, name in enumerate(CLASSES):
        m = cls == k
        lost = [(int(np.sum(x[1] == k) - np.sum((x[1] == k) & x[2])), x[0]) for x in res]
        worst = ", ".join(str(s) for n_lost, s in sorted(lost, reverse=True)[:4] if n_lost)
        print(f"| {name} | {100 * m.sum() / n:.1f} % | {100 * np.sum(m & ~ok) / n:.1f} % | "
              f"{100 * ok[m].mean() if m.any() else 0.0:.0f} % | {worst or '-'} |")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
