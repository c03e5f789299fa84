"""The harmonic EKF on the randomised family (issue 13): benchmarks/robustness/EKF.md.

    PYTHONPATH=src .venv/bin/python benchmarks/robustness/ekf_family.py [--seeds 100]
        [--seed0 0] [--duration 120] [--variants before,before+init,after,after+init]
        [--vehicles cart,forklift,car] [--out FILE]

Per seed of ``simulate("random", seed=N)``: ``ekf.estimate(rec, params=...)`` on the default
axis ``y`` as a user calls it (``vibrospeed estimate -m ekf -p omega_min=.. -p omega_max=..``)
with the vehicle class's search range ``meta["omega_range"]`` (car 10-120, forklift and cart
2-30 rad/s), and

* ``before``: ``comb=false`` (the EKF before issue 13: the thesis' filter from omega0 = 10.2);
* ``after``: the defaults (comb check: acquisition from the first steady candidate, re-lock);
* ``+init``: with ``omega0`` (``--init-omega``) = the median true omega over the moving time,
  rounded to 1 rad/s (a user who knows the vehicle's typical speed).

Scores: ``robustness.score`` (within ``max(10 %, omega_min / 5)`` over cruise / moving time),
``half`` / ``double``: share of the moving (cruise) time within the same tolerance of half /
twice the true speed. Baselines: the causal / offline 3 s STFT harmonic sum
(``robustness.stft_harmonic_sum``). ``comb``: where the comb check's candidates (moving time)
lie: on the truth, on half of it, on twice it, elsewhere (the decaying weights should put them
on the truth).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

VARIANTS = {
    "before": dict(comb="false"),
    "before+init": dict(comb="false", init=True),
    "after": dict(),
    "after+init": dict(init=True),
}


def scores(rec, om, om_lo):
    from robustness import score

    out = score(rec, om, {}, om_lo)
    truth = rec["omega_true"]
    acc = rec["accel_true"]
    moving = truth >= om_lo
    cruise = moving & (np.abs(acc) < 0.2)
    for name, f in (("half", 0.5), ("double", 2.0)):
        hit = np.abs(om - f * truth) <= np.maximum(0.1 * f * truth, om_lo / 5.0)
        hit &= ~(np.abs(om - truth) <= np.maximum(0.1 * truth, om_lo / 5.0))
        out[name] = float(hit[moving].mean()) if moving.any() else np.nan
        out[f"cruise_{name}"] = float(hit[cruise].mean()) if cruise.any() else np.nan
    return out


def one_seed(seed, variants, duration):
    from robustness import stft_harmonic_sum

    from vibrospeed import sim
    from vibrospeed.estimators import ekf
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.signal.comb import comb_candidates

    rec = sim.simulate("random", seed=seed, duration=duration)
    d = rec.meta["drawn"]
    om_lo, om_hi = rec.meta["omega_range"]
    truth = rec["omega_true"]
    moving = truth >= om_lo
    init = float(np.round(np.median(truth[moving]))) if moving.any() else 10.0
    row = {"seed": seed, "vehicle": d["vehicle"], "fs": d["fs"], "shape": d["comb_shape"],
           "level": d["level"], "init": init}
    for name in variants:
        v = dict(VARIANTS[name])
        p = {"omega_min": om_lo, "omega_max": om_hi}
        if v.pop("init", False):
            p["omega0"] = init
        p.update(v)
        t0 = time.process_time()
        try:
            tr = ekf.estimate(rec, params=p)
            row[name] = scores(rec, np.asarray(tr.omega, float), om_lo)
        except Exception as e:  # a crash is a result too
            row[name] = {"error": f"{type(e).__name__}: {e}"}
        row[name]["cpu_s"] = time.process_time() - t0
    y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
    for nm, causal in (("stft-causal", True), ("stft", False)):
        row[nm] = scores(rec, stft_harmonic_sum(y, 1.0 / rec.fs, om_lo, om_hi, causal=causal),
                         om_lo)
    # where the comb check's candidates lie (moving samples with a candidate)
    hi = min(om_hi, 0.98 * np.pi * rec.fs / 2)
    c, _ = comb_candidates(rec["ay"], 1.0 / rec.fs, om_lo, hi)
    sel = np.isfinite(c) & moving
    tol = lambda f: np.abs(c[sel] - f * truth[sel]) <= 0.1 * f * truth[sel]  # noqa: E731
    n = max(int(sel.sum()), 1)
    on = {k: float(tol(f).sum() / n) for k, f in (("truth", 1.0), ("half", 0.5),
                                                  ("double", 2.0))}
    on["other"] = 1.0 - sum(on.values())
    on["n"] = int(sel.sum())
    on["per_s"] = float(sel.sum() / max(moving.sum() / rec.fs, 1e-9))
    row["comb"] = on
    return row


def table(rows, methods):
    from robustness import pct

    out = ["| method | seeds | crashed | cruise median | cruise mean | moving median | "
           "moving mean | moving p10 | on half (moving) | on double (moving) | "
           "cruise on half | CPU s/seed |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in methods:
        rs = [r for r in rows if m in r and "error" not in r[m]]
        errs = sum(1 for r in rows if m in r and "error" in r[m])
        if not rs:
            out.append(f"| {m} | 0 | {errs} | | | | | | | | | |")
            continue
        def get(k, m=m, rs=rs):
            return np.array([r[m].get(k, np.nan) for r in rs], float)

        out.append(f"| {m} | {len(rs)} | {errs} | {pct(get('cruise'), 50):.3f} | "
                   f"{np.nanmean(get('cruise')):.3f} | {pct(get('moving'), 50):.3f} | "
                   f"{np.nanmean(get('moving')):.3f} | {pct(get('moving'), 10):.3f} | "
                   f"{np.nanmean(get('half')):.3f} | {np.nanmean(get('double')):.3f} | "
                   f"{np.nanmean(get('cruise_half')):.3f} | "
                   f"{np.nanmean(get('cpu_s')) if 'cpu_s' in rs[0][m] else np.nan:.2f} |")
    return "\n".join(out)


def comb_line(rows):
    c = [r["comb"] for r in rows if r["comb"]["n"] > 0]
    w = np.array([x["n"] for x in c], float)
    avg = {k: float(np.sum(w * np.array([x[k] for x in c])) / max(w.sum(), 1)) for k in
           ("truth", "half", "double", "other")}
    return (f"comb candidates while moving ({len(c)} seeds with any, "
            f"{np.median([x['per_s'] for x in c]) if c else 0:.2f}/s median): "
            f"on the truth {avg['truth']:.3f}, on half {avg['half']:.3f}, "
            f"on double {avg['double']:.3f}, elsewhere {avg['other']:.3f}")


def versus(rows, a, b, key="moving"):
    pairs = [(r[a].get(key, np.nan), r[b].get(key, np.nan)) for r in rows
             if "error" not in r[a] and "error" not in r[b]]
    pairs = np.array([p for p in pairs if np.isfinite(p[0]) and np.isfinite(p[1])])
    if not pairs.size:
        return "n/a"
    dd = pairs[:, 0] - pairs[:, 1]
    return (f"`{a}` vs `{b}` ({key}): better on {np.mean(dd > 0.02):.0%}, worse on "
            f"{np.mean(dd < -0.02):.0%} of seeds (by > 2 points), mean {dd.mean():+.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--vehicles", default="cart,forklift,car")
    ap.add_argument("--out", default="", help="write the rows (json) here")
    a = ap.parse_args(argv)
    variants = [v for v in a.variants.split(",") if v]
    vehicles = set(a.vehicles.split(","))
    t0 = time.time()
    from vibrospeed import sim

    rows = []
    for i, s in enumerate(range(a.seed0, a.seed0 + a.seeds)):
        kind = sim.simulate("random", seed=s, duration=10.0).meta["drawn"]["vehicle"]
        if kind in vehicles:
            rows.append(one_seed(s, variants, a.duration))
        print(f"\r{i + 1}/{a.seeds} seeds", end="", file=sys.stderr)
    print(file=sys.stderr)
    methods = variants + ["stft-causal", "stft"]
    text = [f"seeds {a.seed0}..{a.seed0 + a.seeds - 1} ({len(rows)} of {sorted(vehicles)}), "
            f"{a.duration:g} s each, {time.time() - t0:.0f} s wall", ""]
    for lab, sel in (("carts and forklifts", [r for r in rows if r["vehicle"] != "car"]),
                     ("cars", [r for r in rows if r["vehicle"] == "car"])):
        if not sel:
            continue
        text += [f"### {lab} ({len(sel)} seeds)", "", table(sel, methods), "",
                 f"- {comb_line(sel)}"]
        for x, y in (("after", "before"), ("after+init", "before+init"), ("after", "stft-causal"),
                     ("after+init", "after")):
            if x in methods and y in methods:
                text.append(f"- {versus(sel, x, y)}")
        text.append("")
    print("\n".join(text))
    if a.out:
        Path(a.out).write_text(json.dumps(rows))
    return rows


if __name__ == "__main__":
    main()
