"""Where ``fuse`` online loses the line-visible tunnel time of ``fuse.py sim``, by what the
causal tracker does there; and the online summary of variants of ``fuse``'s parameters.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/online_loss.py [--seeds 30] [--cache DIR]
        [--variant NAME:PARAM=VALUE,PARAM=VALUE ...]

Same drives, tracks and scoring as ``fuse.py sim`` (``--cache`` shares its grid tracks).
Line-visible tunnel time = tunnel samples where the offline tracker claims a line. Each such
sample falls in one class: the causal tracker claims a line (``has_signal``) or not; its mode
(``omega_mode``) times the true radius is the wheel's (within 3 % of the true speed) or not;
``fuse`` online used a wheel-frequency update there (``source`` 2: taken) or not. Per class:
its share of the line-visible time, and the share of the line-visible time lost in it (the
online speed not within 3 %). Each ``--variant`` (``fuse`` online with those parameters; the
first is the defaults, ``default:``) gets its summary line (tunnel RMSE, line-visible within 3
%, seeds with a tunnel RMSE at most ``gps-riss``'s) and its class table. Prints markdown;
nothing is written.
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


def _value(text: str):
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def parse_variant(spec: str) -> tuple[str, dict]:
    """``NAME:P=V,P=V`` -> ``(NAME, {P: V})`` (numbers and true/false converted)."""
    name, _, rest = spec.partition(":")
    kv = dict(item.split("=", 1) for item in rest.split(",") if item.strip())
    return name, {k.strip(): _value(v.strip()) for k, v in kv.items()}


def seed_classes(seed: int, cache: str | None, variants: list[tuple[str, dict]]):
    """Per variant and line-visible tunnel sample: its class (index into CLASSES) and whether
    the online speed is within 3 % of the truth, and the tunnel's squared error and samples of
    the variant and of ``gps-riss``; None for a seed whose mount is not near the axes."""
    from vibrospeed.estimators import fuse, gps_riss

    rec = sim_recording(seed)
    if not near_axes(rec):
        return None
    lo, hi = rec.meta["omega_range"]
    p = {"omega_min": lo, "omega_max": hi}
    g_off = _grid(rec, p, cache, f"sim{seed}_off")
    g_on = _grid(rec, {**p, "smooth": "none"}, cache, f"sim{seed}_on", posterior=True)
    r = rec.meta["drawn"]["wheel_radius"]
    v = rec["speed_true"]
    tun = rec["gps_sats"] == 0
    vis = tun & (g_off.extras["has_signal"] > 0.5)
    claim = g_on.extras["has_signal"][vis] > 0.5
    vv = v[vis]
    right = (vv > 1.0) & (np.abs(g_on.extras["omega_mode"][vis] * r / np.maximum(vv, 1e-9)
                                 - 1.0) <= 0.03)
    gr = gps_riss.estimate(rec)
    sse_gr = float(np.sum((gr.speed[tun] - v[tun]) ** 2))
    out = []
    for _, params in variants:
        f_on = fuse.estimate(rec, vibration=g_on, params={**params, "online": True})
        taken = f_on.extras["source"][vis] == 2
        cls = np.where(claim, np.where(right, np.where(taken, 0, 1), np.where(taken, 2, 3)),
                       np.where(right, 4, 5))
        ok = np.abs(f_on.speed[vis] - vv) <= 0.03 * vv
        sse = float(np.sum((f_on.speed[tun] - v[tun]) ** 2))
        out.append((cls, ok, sse, sse_gr, int(tun.sum())))
    return seed, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--cache", default=None, help="folder of fuse.py's grid tracks")
    ap.add_argument("--variant", action="append", default=[],
                    help="NAME:PARAM=VALUE,... (fuse parameters; repeatable)")
    a = ap.parse_args()
    variants = [("default", {})] + [parse_variant(s) for s in a.variant]
    t0 = time.time()
    res, seed = [], 0
    while len(res) < a.seeds:
        x = seed_classes(seed, a.cache, variants)
        if x is not None:
            res.append(x)
        seed += 1
    print(f"{len(res)} drives ({time.time() - t0:.0f} s)\n")
    print("| variant | tunnel RMSE (m/s) | line visible: within 3 % | seeds <= gps-riss |")
    print("|---|---|---|---|")
    for j, (name, params) in enumerate(variants):
        ok = np.concatenate([x[1][j][1] for x in res])
        sse = sum(x[1][j][2] for x in res)
        n = sum(x[1][j][4] for x in res)
        better = sum(x[1][j][2] <= x[1][j][3] * 1.0001 for x in res)
        print(f"| {name} {params or ''} | {np.sqrt(sse / max(n, 1)):.2f} | "
              f"{100 * ok.mean():.1f} % | {better} / {len(res)} |")
    for j, (name, _) in enumerate(variants):
        cls = np.concatenate([x[1][j][0] for x in res])
        ok = np.concatenate([x[1][j][1] for x in res])
        n = max(cls.size, 1)
        print(f"\n{name}: line-visible tunnel time {cls.size} samples, online within 3 % "
              f"{100 * ok.mean():.1f} %\n")
        print("| causal tracker | share of the line-visible time | lost (not within 3 %) | "
              "within 3 % in the class | seeds losing most |")
        print("|---|---|---|---|---|")
        for k, cname in enumerate(CLASSES):
            m = cls == k
            lost = [(int(np.sum(x[1][j][0] == k) - np.sum((x[1][j][0] == k) & x[1][j][1])),
                     x[0]) for x in res]
            worst = ", ".join(str(s) for n_lost, s in sorted(lost, reverse=True)[:4] if n_lost)
            print(f"| {cname} | {100 * m.sum() / n:.1f} % | {100 * np.sum(m & ~ok) / n:.1f} % | "
                  f"{100 * ok[m].mean() if m.any() else 0.0:.0f} % | {worst or '-'} |")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
