"""``fuse`` and ``gps-riss`` on the built-in car scenario: RMSE and the 98 % band's coverage.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/car_band.py [--seeds 1-5]

``simulate("car", seed=s)`` (its default length; GPS throughout, a receiver lagging 0.4 s,
first order, against the filters' lag model of 0.08 s), each method through its ``estimate``
as ``vibrospeed estimate`` runs it, scored as speeds against ``speed_true`` by
:func:`vibrospeed.eval.metrics.compare` (RMSE in m/s and the share of the truth inside the
98 % band ``speed_lo``..``speed_hi``, moving samples: true speed above 0.3 m/s; ``vibrospeed
evaluate`` scores a track that has ``omega`` in rad/s against ``omega_true`` instead).
Figures are pooled over the seeds' moving samples. Two settings per method: "now" (the
defaults) and "before" (the receiver's lag taken as exact: ``gps_lag_std=0 q_gps_lag=0``,
for ``fuse`` also ``vib_lag=0``, for ``gps-riss`` also ``acc_psd=0``), the car rows of
docs/fuse.md's band table.
``--fuse-param NAME=VALUE`` is added to every ``fuse`` run (variants). Prints a markdown
table; nothing is written.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

LAG_EXACT = {"gps_lag_std": 0.0, "q_gps_lag": 0.0}
RUNS = {
    "fuse offline": ("fuse", {}, {"vib_lag": 0.0}),
    "fuse online": ("fuse", {"online": True}, {"vib_lag": 0.0}),
    "gps-riss": ("gps-riss", {}, {"acc_psd": 0.0}),
}


#: extra fuse parameters for every fuse run (--fuse-param NAME=VALUE)
EXTRA: dict = {}


def seed_counts(seed: int) -> dict:
    """Per method and setting: moving samples, squared error sum, samples inside the band,
    the receiver's lag at the end of the drive (the model's plus the learned extra, s)."""
    from vibrospeed.estimators import get
    from vibrospeed.eval.metrics import compare
    from vibrospeed.sim import simulate
    from vibrospeed.types import Track

    rec = simulate("car", seed=seed)
    out = {}
    for name, (method, base, before) in RUNS.items():
        for setting, extra in (("before", {**LAG_EXACT, **before}), ("now", {})):
            more = EXTRA if method == "fuse" else {}
            tr = get(method).estimate(rec, params={**base, **more, **extra})
            sp = Track(tr.t, tr.speed, tr.speed_std, tr.speed_lo, tr.speed_hi, tr.speed,
                       tr.speed_std, tr.speed_lo, tr.speed_hi, level=tr.level, wheel_radius=1.0)
            m = compare(sp, rec.t, rec.channel("speed_true"), min_omega=0.3)
            out[name, setting] = (m.n, m.n * m.rmse ** 2, m.n * m.coverage,
                                  tr.params.get("learned_gps_lag", np.nan))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="1-5", help="first-last (inclusive)")
    ap.add_argument("--fuse-param", action="append", default=[],
                    help="fuse parameter NAME=VALUE for every fuse run")
    a = ap.parse_args()
    EXTRA.update(dict(x.split("=", 1) for x in a.fuse_param))
    lo, hi = (int(x) for x in a.seeds.split("-"))
    t0 = time.time()
    per_seed = [seed_counts(s) for s in range(lo, hi + 1)]
    print(f"`simulate(\"car\", seed)`, seeds {lo}-{hi}, moving samples pooled "
          f"({time.time() - t0:.0f} s){'; fuse with ' + str(EXTRA) if EXTRA else ''}\n")
    print("| method | inside the band, before -> now | RMSE (m/s), before -> now |")
    print("|---|---|---|")
    for name in RUNS:
        cov, rmse = {}, {}
        for setting in ("before", "now"):
            n, sse, c = (sum(x) for x in list(zip(*(d[name, setting] for d in per_seed),
                                                  strict=True))[:3])
            cov[setting], rmse[setting] = 100 * c / n, np.sqrt(sse / n)
        print(f"| {name} | {cov['before']:.1f} % -> {cov['now']:.1f} % | "
              f"{rmse['before']:.3f} -> {rmse['now']:.3f} |")
    print("\nPer seed, now (RMSE m/s / inside the band / the receiver's lag at the end, s):")
    for s, d in zip(range(lo, hi + 1), per_seed, strict=True):
        print(f"  {s}: " + ", ".join(
            f"{name} {np.sqrt(d[name, 'now'][1] / d[name, 'now'][0]):.3f} / "
            f"{100 * d[name, 'now'][2] / d[name, 'now'][0]:.1f} % / {d[name, 'now'][3]:.3f}"
            for name in RUNS))


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
