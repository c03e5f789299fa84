"""``fuse`` and ``gps-riss`` on the built-in car scenario: RMSE and the 98 % band's coverage.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/car_band.py [--seeds 1-5]

``simulate("car", seed=s)`` (its default length; GPS throughout, a receiver lagging 0.4 s,
first order, against the filters' lag model of 0.08 s), each method through its ``estimate``
as ``vibrospeed estimate`` runs it, scored as speeds against ``speed_true`` by
:func:`vibrospeed.eval.metrics.compare` (RMSE in m/s and the share of the truth inside the
98 % band ``speed_lo``..``speed_hi``, moving samples: true speed above 0.3 m/s; ``vibrospeed
evaluate`` scores a track that has ``omega`` in rad/s against ``omega_true`` instead).
Figures are pooled over the seeds' moving samples: the car rows of docs/fuse.md's band
table. The grid tracker runs once per seed and mode (smoothed, causal: with its posterior)
with fuse's settings (``fuse.TRACKER_DEFAULTS``), as ``fuse.estimate`` would run it.
``--fuse-param NAME=VALUE`` is added to every ``fuse`` run (variants; e.g. the receiver's lag
taken as exact: ``gps_lag_std=0 q_gps_lag=0 vib_lag=0``), ``--gps-riss-param`` to every
``gps-riss`` run. Prints a markdown table; nothing is written.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

RUNS = {"fuse offline": ("fuse", {}), "fuse online": ("fuse", {"online": True}),
        "gps-riss": ("gps-riss", {})}

#: extra parameters for every run of a method (--fuse-param / --gps-riss-param NAME=VALUE)
EXTRA: dict = {"fuse": {}, "gps-riss": {}}


def seed_counts(seed: int) -> dict:
    """Per method: moving samples, squared error sum, samples inside the band, the receiver's
    lag at the end of the drive (the model's plus the learned extra, s)."""
    from vibrospeed.estimators import fuse, get
    from vibrospeed.eval.metrics import compare
    from vibrospeed.sim import simulate
    from vibrospeed.types import Track

    rec = simulate("car", seed=seed)
    # the causal track with its posterior, which fuse online reads (vib_measure)
    tracks = {online: get("grid").estimate(rec, axis="y", params={
        **fuse.TRACKER_DEFAULTS, **({"smooth": "none"} if online else {})},
        return_posterior=online) for online in (False, True)}
    out = {}
    for name, (method, base) in RUNS.items():
        kw = {"vibration": tracks[bool(base.get("online"))]} if method == "fuse" else {}
        tr = get(method).estimate(rec, params={**base, **EXTRA[method]}, **kw)
        sp = Track(tr.t, tr.speed, tr.speed_std, tr.speed_lo, tr.speed_hi, tr.speed,
                   tr.speed_std, tr.speed_lo, tr.speed_hi, level=tr.level, wheel_radius=1.0)
        m = compare(sp, rec.t, rec.channel("speed_true"), min_omega=0.3)
        out[name] = (m.n, m.n * m.rmse ** 2, m.n * m.coverage,
                     tr.params.get("learned_gps_lag", np.nan))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="1-5", help="first-last (inclusive)")
    ap.add_argument("--fuse-param", action="append", default=[],
                    help="fuse parameter NAME=VALUE for every fuse run")
    ap.add_argument("--gps-riss-param", action="append", default=[],
                    help="gps-riss parameter NAME=VALUE for every gps-riss run")
    a = ap.parse_args()
    EXTRA["fuse"].update(dict(x.split("=", 1) for x in a.fuse_param))
    EXTRA["gps-riss"].update(dict(x.split("=", 1) for x in a.gps_riss_param))
    lo, hi = (int(x) for x in a.seeds.split("-"))
    t0 = time.time()
    per_seed = [seed_counts(s) for s in range(lo, hi + 1)]
    print(f"`simulate(\"car\", seed)`, seeds {lo}-{hi}, moving samples pooled "
          f"({time.time() - t0:.0f} s){'; with ' + str(EXTRA) if any(EXTRA.values()) else ''}"
          "\n")
    print("| method | inside the band | RMSE (m/s) |")
    print("|---|---|---|")
    for name in RUNS:
        n, sse, c = (sum(x) for x in list(zip(*(d[name] for d in per_seed), strict=True))[:3])
        print(f"| {name} | {100 * c / n:.1f} % | {np.sqrt(sse / n):.3f} |")
    print("\nPer seed (RMSE m/s / inside the band / the receiver's lag at the end, s):")
    for s, d in zip(range(lo, hi + 1), per_seed, strict=True):
        print(f"  {s}: " + ", ".join(
            f"{name} {np.sqrt(d[name][1] / d[name][0]):.3f} / "
            f"{100 * d[name][2] / d[name][0]:.1f} % / {d[name][3]:.3f}" for name in RUNS))


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
