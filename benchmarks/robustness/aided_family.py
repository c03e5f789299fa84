"""The aided tracker on the randomised family (issue 13, part 3/5): benchmarks/robustness/AIDED.md.

    PYTHONPATH=src .venv/bin/python benchmarks/robustness/aided_family.py [--seeds 60]
        [--seed0 0] [--duration 120] [--variants after,before] [--baselines]
        [--cache DIR] [--out FILE]

Per seed of ``simulate("random", seed=N)``: the aided EKF (``aided.estimate``) with the true
wheel radius, vibration axis ``y`` like every other method, and two choices of the
longitudinal acceleration input ``u``:

* ``raw``: the sensor's ``ax`` as recorded (what ``benchmarks/robustness`` gives it); with the
  family's random mount ``ax`` is any mix of the vehicle's axes plus gravity;
* ``aligned``: the sensor's three axes rotated back into the vehicle frame with the drawn mount
  (``mount_matrix(mount).T``): what a user who knows (or has calibrated) the mount would feed;
  noise, bias, quantisation and body motion stay, and nothing else from the truth.

Both are scored with ``benchmarks/robustness/robustness.py``'s ``score`` (search range of the
vehicle class, ``meta["omega_range"]``, passed as ``omega_min`` / ``omega_max``), and split
into mount "near the vehicle frame" (the family's N(0, 0.1) rad draw) and "anywhere".
Baselines (``--baselines``): ``grid`` (offline), ``grid-causal`` and the causal / offline STFT
harmonic sum,
cached per seed in ``--cache`` (they do not depend on the aided tracker).
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

#: aided variants: name -> params (``range`` True: omega_min / omega_max of the vehicle class)
VARIANTS = {
    # the defaults before this work (window test, no offset removal, no comb, no range)
    "before": dict(tracker="ekf", standstill="window", accel_offset="none", comb=False),
    "after": dict(tracker="ekf", range=True),
    "after-norange": dict(tracker="ekf"),
    "after-causal": dict(tracker="ekf", range=True, causal=True),
    # the aiding around the grid product's tracker (accel_axis: the mount estimate)
    "grid": dict(range=True, tracker="grid"),
    "grid-online": dict(range=True, tracker="grid", causal=True),
    "grid-noaid": dict(range=True, tracker="grid", aiding="none"),
    "grid-mode": dict(range=True, tracker="grid", aiding="mode"),
    "grid-ax": dict(range=True, tracker="grid", accel_axis="ax"),
}
#: variants whose own a_x input is the mount estimate (run once, not per raw / aligned)
MOUNT = ("grid", "grid-online", "grid-noaid", "grid-mode")


def _aided(rec, u, om_lo, om_hi, params):
    from vibrospeed.estimators import aided

    p = dict(params)
    if p.pop("range", False):
        p["omega_min"], p["omega_max"] = om_lo, om_hi
    r2 = rec if u is None else rec.with_channels(ax=u)
    tr = aided.estimate(r2, params=p)
    return np.asarray(tr.omega, float), {"standstill": np.asarray(tr.extras["standstill"]),
                                         "mount": bool(tr.params.get("mount_confident", False))}


def one_seed(seed, variants, duration, baselines, cache):
    from robustness import _run_method, score, stft_harmonic_sum

    from vibrospeed import sim
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.sim.sensors import mount_matrix

    rec = sim.simulate("random", seed=seed, duration=duration)
    d = rec.meta["drawn"]
    om_lo, om_hi = rec.meta["omega_range"]
    near = bool(np.max(np.abs(d["mount"])) < 0.5)
    row = {"seed": seed, "vehicle": d["vehicle"], "fs": d["fs"], "shape": d["comb_shape"],
           "level": d["level"], "near": near}
    veh = mount_matrix(d["mount"]).T @ np.vstack([rec["ax"], rec["ay"], rec["az"]])
    for name in variants:
        inputs = ((("mount", None),) if name in MOUNT
                  else (("raw", rec["ax"]), ("aligned", veh[0])))
        for inp, u in inputs:
            t0 = time.process_time()
            try:
                om, ex = _aided(rec, u, om_lo, om_hi, VARIANTS[name])
                row[f"{name}/{inp}"] = score(rec, om, ex, om_lo)
                row[f"{name}/{inp}"]["mount"] = ex["mount"]
            except Exception as e:  # a crash is a result too
                row[f"{name}/{inp}"] = {"error": f"{type(e).__name__}: {e}"}
            row[f"{name}/{inp}"]["cpu_s"] = time.process_time() - t0
    if baselines:
        f = Path(cache) / f"{seed}_{duration:g}.json" if cache else None
        b = json.loads(f.read_text()) if f is not None and f.exists() else {}
        y = None
        for nm in ("stft", "stft-causal", "grid-causal", "grid"):
            if nm in b:
                continue
            t0 = time.process_time()
            if nm.startswith("stft"):
                if y is None:
                    y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
                om = stft_harmonic_sum(y, 1.0 / rec.fs, om_lo, om_hi, causal=nm == "stft-causal")
                ex = {}
            else:
                om, ex = _run_method(nm, rec, om_lo, om_hi)
            b[nm] = score(rec, om, ex, om_lo)
            b[nm]["cpu_s"] = time.process_time() - t0
        if f is not None:
            f.parent.mkdir(parents=True, exist_ok=True)
            f.write_text(json.dumps(b))
        row.update(b)
    return row


def table(rows, methods):
    from robustness import pct

    out = ["| method | seeds | cruise median | cruise p10 | moving median | moving mean | "
           "moving p10 | stop detected | standstill while moving | CPU s/seed |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for m in methods:
        rs = [r for r in rows if m in r and "error" not in r[m]]
        if not rs:
            continue
        def get(k, m=m, rs=rs):
            return np.array([r[m].get(k, np.nan) for r in rs], float)

        stop_s, mov_s = get("stop_s"), get("moving_s")
        sd, sf = get("stop_det"), get("stop_false")
        det = np.nansum(sd * stop_s) / max(np.sum(stop_s[np.isfinite(sd)]), 1e-9)
        false = np.nansum(sf * mov_s) / max(np.sum(mov_s[np.isfinite(sf)]), 1e-9)
        errs = sum(1 for r in rows if m in r and "error" in r[m])
        out.append(f"| {m}{f' ({errs} crashed)' if errs else ''} | {len(rs)} | "
                   f"{pct(get('cruise'), 50):.3f} | {pct(get('cruise'), 10):.3f} | "
                   f"{pct(get('moving'), 50):.3f} | {np.nanmean(get('moving')):.3f} | "
                   f"{pct(get('moving'), 10):.3f} | {det:.3f} | {false:.4f} | "
                   f"{np.nanmean(get('cpu_s')):.2f} |")
    return "\n".join(out)


def versus(rows, a, b, key="moving"):
    """(share of seeds with a >= b, mean of a - b) on ``key``."""
    pairs = [(r[a].get(key, np.nan), r[b].get(key, np.nan)) for r in rows if a in r and b in r]
    pairs = np.array([p for p in pairs if np.isfinite(p[0]) and np.isfinite(p[1])])
    if not pairs.size:
        return np.nan, np.nan
    return float(np.mean(pairs[:, 0] >= pairs[:, 1])), float(np.mean(pairs[:, 0] - pairs[:, 1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=60)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--variants", default="after,before")
    ap.add_argument("--baselines", action="store_true")
    ap.add_argument("--cache", default="/tmp/aided_family_cache",
                    help="baseline scores per seed (delete it when the grid tracker changes)")
    ap.add_argument("--out", default="", help="write the rows (json) here")
    a = ap.parse_args(argv)
    variants = [v for v in a.variants.split(",") if v]
    t0 = time.time()
    rows = []
    for i, s in enumerate(range(a.seed0, a.seed0 + a.seeds)):
        rows.append(one_seed(s, variants, a.duration, a.baselines, a.cache))
        print(f"\r{i + 1}/{a.seeds} seeds", end="", file=sys.stderr)
    print(file=sys.stderr)
    methods = [f"{v}/{i}" for v in variants
               for i in (("mount",) if v in MOUNT else ("raw", "aligned"))]
    if a.baselines:
        methods += ["grid", "grid-causal", "stft-causal", "stft"]
    text = [f"{len(rows)} seeds ({a.seed0}..{a.seed0 + a.seeds - 1}), {a.duration:g} s each, "
            f"{time.time() - t0:.0f} s wall", ""]
    for lab, sel in (("all seeds", rows), ("mount near the vehicle frame",
                                           [r for r in rows if r["near"]]),
                     ("mount anywhere", [r for r in rows if not r["near"]])):
        text += [f"### {lab} ({len(sel)} seeds)", "", table(sel, methods), ""]
        if a.baselines:
            for m in methods[:-4]:
                for b in ("grid", "grid-causal", "stft-causal"):
                    sh, dm = versus(sel, m, b)
                    text.append(f"- `{m}` moving-within >= `{b}` on {100 * sh:.0f} % of seeds "
                                f"(mean difference {dm:+.3f})")
            text.append("")
        for m in methods:
            if m.endswith("/mount"):
                k = sum(1 for r in sel if m in r and r[m].get("mount"))
                text.append(f"- `{m}`: mount confident (aided) on {k} of {len(sel)} seeds")
        text.append("")
    by = {}
    for r in rows:
        by.setdefault(r["vehicle"], []).append(r)
    for v, rs in sorted(by.items()):
        text += [f"### {v} ({len(rs)} seeds)", "", table(rs, methods), ""]
    print("\n".join(text))
    if a.out:
        Path(a.out).write_text(json.dumps(rows))
    return rows


if __name__ == "__main__":
    main()
