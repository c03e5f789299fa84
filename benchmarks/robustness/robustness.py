"""Every wheel-speed method on the randomised family of drives (issue 13).

    PYTHONPATH=src .venv/bin/python benchmarks/robustness/robustness.py [--seeds 200] [--seed0 0]
        [--methods grid,grid-causal,rbpmf,stft,stft-causal,aided] [--jobs 2] [--duration 240]
        [--write]

Each seed of ``simulate("random", seed=N)`` is estimated with every method on the default axis
``y`` (the family's mount is random, so ``y`` is any mix of the vehicle's axes), with the
search range a user would give for the vehicle class (``meta["omega_range"]``: car 10-120
rad/s, forklift and cart 2-30 rad/s) and nothing else. Scores per seed:

* ``cruise`` / ``moving``: share of the cruise time (``|a| < 0.2 m/s^2``) / of all moving time
  with the truth inside the search range, where ``|omega - omega_true| <= tol``,
  ``tol = max(10 %, omega_min / 5)`` (car: max(2 rad/s, 10 %), the issue's tolerance);
* ``stop_det``: share of stop time (truth 0, 1 s away from any motion) declared standstill
  (``extras["standstill"]``, or ``omega`` < omega_min / 2 for methods without that column);
  ``stop_false``: share of moving time declared standstill;
* ``claim_prec`` / ``claim_rec`` (grid): within tolerance where it claims a line
  (``has_signal``), and share of the samples where a 3 s STFT peak is right that are claimed
  (pooled over the seeds' moving time, as are ``claimed`` and the stop scores).

Baselines: the paper's ``rbpmf`` and a plain 3 s STFT harmonic sum (offline: window centres,
causal: window ends), :func:`stft_harmonic_sum`.
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from vibrospeed.eval.baseline import stft_harmonic_sum  # noqa: F401 (used by the others)

HERE = Path(__file__).resolve().parent
METHODS = ("grid", "grid-causal", "rbpmf", "stft", "stft-causal", "aided")


def _run_method(name, rec, om_lo, om_hi, extra=None):
    from vibrospeed.estimators import aided, grid, rbpmf

    rng = {"omega_min": om_lo, "omega_max": om_hi, **(extra or {})}
    if name == "grid":
        tr = grid.estimate(rec, params=rng)
    elif name == "grid-causal":
        tr = grid.estimate(rec, params={**rng, "smooth": "none"})
    elif name == "rbpmf":
        tr = rbpmf.estimate(rec, params=rng)
    elif name == "aided":
        tr = aided.estimate(rec, params={"omega_min": om_lo, "omega_max": om_hi})
    elif name.startswith("stft"):
        from vibrospeed.signal import prefilter as pf

        y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
        om = stft_harmonic_sum(y, 1.0 / rec.fs, om_lo, om_hi, causal=name.endswith("causal"))
        return om, {}
    else:
        raise ValueError(name)
    return np.asarray(tr.omega, float), {k: np.asarray(v) for k, v in tr.extras.items()
                                         if k in ("has_signal", "standstill")}


def score(rec, om, extras, om_lo, stft_ok=None):
    truth = rec["omega_true"]
    acc = rec["accel_true"]
    fs = rec.fs
    tol = np.maximum(0.1 * truth, om_lo / 5.0)
    ok = np.abs(om - truth) <= tol
    moving = truth >= om_lo
    cruise = moving & (np.abs(acc) < 0.2)
    still = truth <= 0
    k = int(round(fs))  # 1 s away from motion
    stop = np.convolve(still.astype(float), np.ones(2 * k + 1), "same") >= 2 * k + 1
    standing = extras.get("standstill")
    if standing is None:
        standing = ~(om >= om_lo / 2)  # NaN (no estimate) counts as standing
    standing = np.asarray(standing, bool)
    out = {
        "cruise": float(ok[cruise].mean()) if cruise.any() else np.nan,
        "moving": float(ok[moving].mean()) if moving.any() else np.nan,
        "stop_det": float(standing[stop].mean()) if stop.any() else np.nan,
        "stop_false": float(standing[truth > 0].mean()) if (truth > 0).any() else np.nan,
        "stop_s": float(stop.sum() / fs), "moving_s": float(moving.sum() / fs),
    }
    hs = extras.get("has_signal")
    if hs is not None:
        hs = hs > 0.5
        c = moving & hs
        out["claim_prec"] = float(ok[c].mean()) if c.any() else np.nan
        out["claimed"] = float(hs[moving].mean()) if moving.any() else np.nan
        if stft_ok is not None:
            r = moving & stft_ok
            out["claim_rec"] = float(hs[r].mean()) if r.any() else np.nan
            out["stft_ok_s"] = float(r.sum() / fs)
    return out


def one_seed(seed, methods, duration, extra=None):
    from vibrospeed import sim

    if extra and str(extra.get("standstill", "on")) == "off":  # the stage switched off
        from vibrospeed.estimators import grid

        extra = {k: v for k, v in extra.items() if k != "standstill"}
        grid.with_standstill = lambda tr, *a, **k: tr

    rec = sim.simulate("random", seed=seed, duration=duration)
    d = rec.meta["drawn"]
    om_lo, om_hi = rec.meta["omega_range"]
    truth = rec["omega_true"]
    row = {"seed": seed, "vehicle": d["vehicle"], "fs": d["fs"], "shape": d["comb_shape"],
           "level": d["level"]}
    stft_om, _ = _run_method("stft", rec, om_lo, om_hi)
    stft_ok = np.abs(stft_om - truth) <= np.maximum(0.1 * truth, om_lo / 5.0)
    for m in methods:
        t0 = time.process_time()
        try:
            om, ex = (stft_om, {}) if m == "stft" else _run_method(
                m, rec, om_lo, om_hi, extra if m.startswith("grid") else None)
            row[m] = score(rec, om, ex, om_lo, stft_ok)
        except Exception as e:  # a crash is a result too
            row[m] = {"error": f"{type(e).__name__}: {e}"}
        row[m]["cpu_s"] = time.process_time() - t0
    return row


def pct(x, q):
    x = np.asarray([v for v in x if np.isfinite(v)])
    return float(np.percentile(x, q)) if x.size else np.nan


def summarise(rows, methods):
    lines = ["| method | cruise median | cruise p10 | moving median | moving p10 | stop detected"
             " | standstill while moving | claim precision | claim recall | claimed | CPU s/seed |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in methods:
        def get(k, m=m):
            return [r[m].get(k, np.nan) for r in rows if "error" not in r[m]]

        stop_s = np.array([r[m]["stop_s"] for r in rows if "error" not in r[m]])
        mov_s = np.array([r[m]["moving_s"] for r in rows if "error" not in r[m]])
        sd = np.array(get("stop_det"), float)
        sf = np.array(get("stop_false"), float)
        det = np.nansum(sd * stop_s) / max(np.sum(stop_s[np.isfinite(sd)]), 1e-9)
        false = np.nansum(sf * mov_s) / max(np.sum(mov_s[np.isfinite(sf)]), 1e-9)
        errs = sum("error" in r[m] for r in rows)
        # claims pooled over the seeds' moving time (a median over seeds that mostly claim
        # nothing would hide where they do)
        cl = np.array(get("claimed"), float) * mov_s
        prec = np.nansum(np.array(get("claim_prec"), float) * cl) / max(np.nansum(cl), 1e-9)
        ok_s = np.array(get("stft_ok_s"), float)
        rec_ = np.nansum(np.array(get("claim_rec"), float) * ok_s) / max(np.nansum(ok_s), 1e-9)
        claimed = np.nansum(cl) / max(np.sum(mov_s), 1e-9)
        if not np.isfinite(cl).any():
            prec = rec_ = claimed = np.nan
        elif not np.isfinite(ok_s).any():
            rec_ = np.nan
        lines.append(
            f"| {m}{f' ({errs} crashed)' if errs else ''} | {pct(get('cruise'), 50):.3f} | "
            f"{pct(get('cruise'), 10):.3f} | {pct(get('moving'), 50):.3f} | "
            f"{pct(get('moving'), 10):.3f} | {det:.3f} | {false:.3f} | "
            f"{prec:.3f} | {rec_:.3f} | {claimed:.3f} | "
            f"{np.mean(get('cpu_s')):.2f} |")
    return "\n".join(lines)


def versus(rows, a, b, key="moving", margin=0.0):
    """Share of seeds where method ``a`` is at or above ``b`` (within ``margin``), and the
    seeds where it is not."""
    pairs = [(r["seed"], r[a].get(key, np.nan), r[b].get(key, np.nan)) for r in rows
             if a in r and b in r]
    pairs = [(s, x, y) for s, x, y in pairs if np.isfinite(x) and np.isfinite(y)]
    lose = [(s, x, y) for s, x, y in pairs if x < y - margin]
    return 1.0 - len(lose) / max(len(pairs), 1), lose


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--duration", type=float, default=240.0)
    ap.add_argument("--grid-params", default="", help="NAME=VALUE,... for the grid methods "
                    "(standstill=off: without the standstill stage)")
    ap.add_argument("--write", action="store_true", help="append the tables to RESULTS.md")
    ap.add_argument("--label", default="", help="heading of the written section")
    ap.add_argument("--from-rows", default="", help="summarise a saved rows .npy, run nothing")
    a = ap.parse_args(argv)
    methods = [m for m in a.methods.split(",") if m]
    extra = dict(kv.split("=", 1) for kv in a.grid_params.split(",") if kv)
    seeds = range(a.seed0, a.seed0 + a.seeds)
    t0 = time.time()
    rows = []
    if a.from_rows:
        rows = list(np.load(a.from_rows, allow_pickle=True))
        methods = [m for m in methods if m in rows[0]]
        seeds = [r["seed"] for r in rows]
        a.seeds, a.seed0 = len(rows), seeds[0]
    elif a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            for i, r in enumerate(ex.map(one_seed, seeds, [methods] * len(seeds),
                                         [a.duration] * len(seeds),
                                         [extra] * len(seeds))):
                rows.append(r)
                print(f"\r{i + 1}/{len(seeds)} seeds", end="", file=sys.stderr)
    else:
        for i, s in enumerate(seeds):
            rows.append(one_seed(s, methods, a.duration, extra))
            print(f"\r{i + 1}/{len(seeds)} seeds", end="", file=sys.stderr)
    print(file=sys.stderr)
    out = [f"{len(rows)} seeds ({a.seed0}..{a.seed0 + a.seeds - 1}), {a.duration:g} s each, "
           f"{time.time() - t0:.0f} s wall", "", summarise(rows, methods), ""]
    for g in ("grid", "grid-causal"):
        for b, margin in (("stft", 0.0), ("stft-causal", 0.0), ("rbpmf", 0.0)):
            if g in methods and b in methods:
                share, lose = versus(rows, g, b, margin=margin)
                lose_txt = ", ".join(f"{s} ({x:.2f} vs {y:.2f})" for s, x, y in lose[:25])
                out.append(f"- `{g}` at or above `{b}` (moving within) on {100 * share:.1f} % "
                           f"of seeds; below on: {lose_txt or 'none'}")
    by = {}
    for r in rows:
        by.setdefault(r["vehicle"], []).append(r)
    for v, rs in sorted(by.items()):
        out += ["", f"{v} ({len(rs)} seeds):", "", summarise(rs, methods)]
    text = "\n".join(out)
    print(text)
    if a.write:
        with open(HERE / "RESULTS.md", "a") as f:
            f.write(f"\n## {a.label or 'run'}\n\n{text}\n")
    if not a.from_rows:
        np.save(HERE / "last_rows.npy", np.array(rows, dtype=object), allow_pickle=True)
    return rows


if __name__ == "__main__":
    main()
