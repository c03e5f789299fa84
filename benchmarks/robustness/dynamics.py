"""How fast speed changes on the randomised family against the real drives (issue 13, part 1).

    PYTHONPATH=src .venv/bin/python benchmarks/robustness/dynamics.py [--seeds 100]

The speed of each drive resampled at 1 Hz (family: ``omega_true`` times the wheel radius; the
GoPro kart and the Hungary phone drives: GPS speed), its 1 s differences while moving
(v > 0.5 m/s): the percentiles of ``|a|`` (m/s^2) and of ``|a| / v`` (1/s, the relative rate
that decides how far a wheel line moves against its harmonic spacing). The omega walk of the
trackers is chosen on the family, so a family whose speed changes less than real drives
favours a slower walk than the real recordings accept (RESULTS.md, stops 24 and 25).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import real_recordings as R  # noqa: E402

from vibrospeed import io, sim  # noqa: E402


def rates(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(|a|, |a| / v)`` of a 1 Hz speed series while moving (v > 0.5 m/s)."""
    a = np.diff(v)
    vm = 0.5 * (v[1:] + v[:-1])
    m = vm > 0.5
    return np.abs(a[m]), np.abs(a[m]) / vm[m]


def row(name: str, parts: list[tuple[np.ndarray, np.ndarray]]) -> str:
    a = np.concatenate([p[0] for p in parts])
    rel = np.concatenate([p[1] for p in parts])
    q = (50, 90, 99)
    return (f"| {name} | {a.size} | " + " / ".join(f"{np.percentile(a, x):.2f}" for x in q)
            + " | " + " / ".join(f"{np.percentile(rel, x):.3f}" for x in q) + " |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=100)
    a = ap.parse_args(argv)
    fam: dict[str, list] = {}
    for s in range(a.seeds):
        rec = sim.simulate("random", seed=s, duration=120)
        step = int(round(rec.fs))
        v = rec["omega_true"][::step] * rec.wheel_radius
        fam.setdefault(rec.meta["drawn"]["vehicle"], []).append(rates(v))
    lines = ["| drives | seconds moving | \\|a\\| m/s^2, p50 / p90 / p99 | \\|a\\| / v 1/s, "
             "p50 / p90 / p99 |", "|---|---|---|---|"]
    lines += [row(f"family {k} (seeds 0-{a.seeds - 1})", p) for k, p in sorted(fam.items())]
    gps = pd.read_csv(R.KART / "GX030410_gps_speed.csv")
    tg, vg = gps["t_video_s"].to_numpy(float), gps["gps_speed2d_mps"].to_numpy(float)
    t1 = np.arange(tg[0], tg[-1], 1.0)
    lines.append(row("GoPro kart (GPS)", [rates(np.interp(t1, tg, vg))]))
    parts = []
    for p in sorted(x for x in R.HUNGARY.iterdir() if x.is_dir()):
        rec = io.read(p, "phyphox")
        g = rec["gps_speed"]
        ok = np.isfinite(g)
        t1 = np.arange(rec.t[ok][0], rec.t[ok][-1], 1.0)
        parts.append(rates(np.interp(t1, rec.t[ok], g[ok])))
    lines.append(row("Hungary phone drives (GPS)", parts))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
