"""Issue 7, part 3: the grid tracker's noise parameters fitted by marginal likelihood (results ->
benchmarks/fits/RESULTS.md).

Usage (by hand, from the repository root; one at a time on the shared VM)::

    # 1. fit q_omega, q_amp, r per recording (sim car/cart seeds 0-4, Hungary drives, kart z);
    #    rows on stdout, values also to a JSON-lines file for step 2
    PYTHONPATH=src .venv/bin/python benchmarks/fits.py fit --seeds 0-4 \
        --sets car,cart,hungary,kart --max-seconds 90 --out /tmp/fits90.jsonl
    #    the simulator fits again on whole recordings (--max-seconds 0)
    PYTHONPATH=src .venv/bin/python benchmarks/fits.py fit --seeds 0-4 --sets car,cart \
        --max-seconds 0 --out /tmp/fitsfull.jsonl
    # 2. held-out seeds: grid smoother and causal filter with the current defaults vs the
    #    median fitted values (per scenario, and over all simulator fits)
    PYTHONPATH=src .venv/bin/python benchmarks/fits.py eval --seeds 5-9 --sets car,cart \
        --fits "90 s=/tmp/fits90.jsonl" --fits "whole=/tmp/fitsfull.jsonl"
    # 3. real recordings: current defaults vs the recording's own fit (GPS speed / fitted radius)
    PYTHONPATH=src .venv/bin/python benchmarks/fits.py real --sets hungary,kart \
        --fits /tmp/fits90.jsonl

The fit is the product's (:func:`vibrospeed.estimators.fit.fit`, coordinate search on a log
scale, start = :data:`vibrospeed.estimators.grid.GRID_DEFAULTS`) on exactly what the causal grid
filter sees: ``grid._prepare`` (pre-filter, running-RMS scaling, tracker config with
``temper`` and the "no line" state) and the comb evidence referred to each frame's *end*
(``grid.evidence(cfg, y)``), kept fixed. ``--max-seconds``: only the first that many seconds of
each recording enter the likelihood (the fit's own option; cost ~ evaluations x length).

Score (``beyond.metrics``): share of moving samples (omega_true > 5 rad/s) with
|omega_hat - omega_true| <= max(2 rad/s, 10 %), also at cruise, band coverage where has_signal.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import beyond as B  # noqa: E402

from vibrospeed import sim  # noqa: E402
from vibrospeed.estimators import fit as _fit  # noqa: E402
from vibrospeed.estimators import grid  # noqa: E402

NAMES = ("q_omega", "q_amp", "r")
SIM_PARAMS = {"car": {}, "cart": {"omega_min": 2.0, "omega_max": 30.0}}
HUNGARY_PARAMS = {"prefilter": "thesis-hp", "omega_min": 5.0, "omega_max": 60.0}
KART_PARAMS = {"prefilter": "paper-hp", "omega_min": 60.0, "omega_max": 300.0, "M": 2}


def _seeds(spec: str) -> list[int]:
    """``"0-4"`` or ``"0,2,5"`` -> list of seeds."""
    out: list[int] = []
    for part in spec.split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part.strip():
            out.append(int(part))
    return out


def recordings(sets: list[str], seeds: list[int]):
    """Yield ``(set, label, recording, axis, params)``."""
    for name in sets:
        if name in SIM_PARAMS:
            for s in seeds:
                yield name, f"{name} seed {s}", sim.simulate(name, seed=s), "y", SIM_PARAMS[name]
        elif name == "hungary":
            for label, rec in B._hungary():
                yield name, f"Hungary {label}", rec, "z", HUNGARY_PARAMS
        elif name == "kart":
            rec, _ = B._kart()
            yield name, "GoPro kart (z)", rec, "z", KART_PARAMS
        else:
            raise SystemExit(f"unknown set {name!r} (car, cart, hungary, kart)")


def fit_one(rec, axis: str, params: dict, max_seconds: float | None):
    """Fit ``NAMES`` on the causal grid filter's signal and end-referred comb evidence."""
    cfg, y, _, _ = grid._prepare(rec, axis, params)
    t0 = time.process_time()
    idx, vals = grid.evidence(cfg, y)
    fr = _fit.fit(cfg.tracker, y, names=NAMES, extra=(idx, vals), max_seconds=max_seconds)
    cpu = time.process_time() - t0
    used = min(y.size, int(round(max_seconds / cfg.tracker.model.dt))) if max_seconds else y.size
    return fr, cpu, used * cfg.tracker.model.dt, y.size * cfg.tracker.model.dt


def cmd_fit(a) -> None:
    out = open(a.out, "a") if a.out else None
    print(f"start: {', '.join(f'{k} {grid.GRID_DEFAULTS[k]:g}' for k in NAMES)}; "
          f"max_seconds {a.max_seconds}\n")
    print("| recording | q_omega | q_amp | r | log p start -> fitted (nats) | per s | evals | "
          "s used / total | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|", flush=True)
    for set_, label, rec, axis, params in recordings(a.sets.split(","), _seeds(a.seeds)):
        fr, cpu, used, total = fit_one(rec, axis, params, a.max_seconds)
        v = fr.values
        print(f"| {label} | {v['q_omega']:.4g} | {v['q_amp']:.4g} | {v['r']:.4g} | "
              f"{fr.start_loglik:.0f} -> {fr.loglik:.0f} | "
              f"{(fr.loglik - fr.start_loglik) / used:+.2f} | {fr.evals} | "
              f"{used:.0f} / {total:.0f} | {cpu:.0f} |", flush=True)
        if out:
            out.write(json.dumps({"set": set_, "label": label, "values": v,
                                  "loglik": fr.loglik, "start": fr.start_loglik,
                                  "evals": fr.evals, "cpu": cpu, "used_s": used,
                                  "total_s": total}) + "\n")
            out.flush()


def _logmedian(xs) -> float:
    """Median on a log scale (geometric mean of the middle two for an even count)."""
    return float(np.exp(np.median(np.log(np.asarray(xs, float)))))


def candidates(fits: dict[str, list[dict]], sets: list[str]) -> dict:
    """name -> {set: params}: the current defaults, then per fits file (label -> rows) the
    per-scenario median fit and the median over all of its simulator fits."""
    cur = {k: float(grid.GRID_DEFAULTS[k]) for k in NAMES}
    out = {"current defaults": {s: cur for s in sets}}
    for label, rows in fits.items():
        per = {}
        for s in sets:
            vals = [f["values"] for f in rows if f["set"] == s]
            per[s] = {k: _logmedian([r[k] for r in vals]) for k in NAMES} if vals else cur
        sim_rows = [f["values"] for f in rows if f["set"] in SIM_PARAMS]
        out[f"per-scenario median ({label})"] = per
        if sim_rows:
            pooled = {k: _logmedian([r[k] for r in sim_rows]) for k in NAMES}
            out[f"median of all sim fits ({label})"] = {s: pooled for s in sets}
    return out


def cmd_eval(a) -> None:
    fits = {}
    for spec in a.fits or []:
        label, _, path = spec.rpartition("=")
        fits[label or Path(path).stem] = [json.loads(x) for x in open(path) if x.strip()]
    sets = a.sets.split(",")
    cands = candidates(fits, sets)
    if a.extra:
        cands["extra"] = {s: json.loads(a.extra) for s in sets}
    for name, per in cands.items():
        print(f"- {name}: " + "; ".join(
            f"{s}: " + ", ".join(f"{k} {v:.4g}" for k, v in p.items()) for s, p in per.items()))
    seeds = _seeds(a.seeds)
    res: dict = {}
    for s_ in sets:
        for seed in seeds:
            rec = sim.simulate(s_, seed=seed)
            truth = rec["omega_true"]
            for name, per in cands.items():
                for smooth in ("fb", "none"):
                    t0 = time.process_time()
                    tr = grid.estimate(rec, axis="y", params={**SIM_PARAMS[s_], **per[s_],
                                                              "smooth": smooth})
                    m = B.metrics(rec.t, tr.omega, truth, tr.omega_lo, tr.omega_hi,
                                  tr.extras["has_signal"] > 0.5)
                    m["cpu"] = time.process_time() - t0
                    res.setdefault((s_, name, smooth), []).append(m)
                    print(f"  {s_} seed {seed} {name} {smooth}: ok moving "
                          f"{100 * m['ok_moving']:.1f} %", file=sys.stderr, flush=True)
        print(f"\n### {s_}: held-out seeds {a.seeds}\n")
        print("| noise | q_omega | q_amp | r | smoother ok moving % | ok cruise % | cover % | "
              "filter ok moving % | ok cruise % | cover % | per-seed smoother / filter ok % |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for name, per in cands.items():
            fb, fi = res[(s_, name, "fb")], res[(s_, name, "none")]

            def mean(rows, key):
                return 100 * np.nanmean([r[key] for r in rows])

            seeds_txt = " ".join(f"{100 * x['ok_moving']:.0f}/{100 * y['ok_moving']:.0f}"
                                 for x, y in zip(fb, fi, strict=True))
            p = per[s_]
            print(f"| {name} | {p['q_omega']:.4g} | {p['q_amp']:.4g} | {p['r']:.4g} | "
                  f"{mean(fb, 'ok_moving'):.1f} | {mean(fb, 'ok_cruise'):.1f} | "
                  f"{mean(fb, 'cover'):.1f} | {mean(fi, 'ok_moving'):.1f} | "
                  f"{mean(fi, 'ok_cruise'):.1f} | {mean(fi, 'cover'):.1f} | {seeds_txt} |",
                  flush=True)


def cmd_real(a) -> None:
    """Real recordings: the grid with the current defaults vs the recording's own fit (and
    ``--extra``), truth = GPS speed / r_fit, r_fit = median(v / omega_hat) over v > 2 m/s
    (as ``beyond.real_bench``); a fitted constant makes any speed-correlated line look "ok"."""
    fits = {}
    for spec in a.fits or []:
        for x in open(spec.rpartition("=")[2]):
            if x.strip():
                f = json.loads(x)
                fits[f["label"]] = f["values"]
    cur = {k: float(grid.GRID_DEFAULTS[k]) for k in NAMES}
    print("| recording | noise | q_omega | q_amp | r | smooth | ok moving % (r fitted) | "
          "within 5 % | r fit m | has_signal moving % | cover % (where has_signal) | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for set_, label, rec, axis, params in recordings(a.sets.split(","), []):
        v = rec["gps_speed"] if set_ == "hungary" else B._kart()[1]
        cands = {"current defaults": cur}
        if label in fits:
            cands["own fit"] = fits[label]
        if a.extra:
            cands["extra"] = json.loads(a.extra)
        mov = np.isfinite(v) & (v > 2.0)
        for name, p in cands.items():
            for smooth in ("fb", "none"):
                t0 = time.process_time()
                tr = grid.estimate(rec, axis=axis, params={**params, **p, "smooth": smooth})
                cpu = time.process_time() - t0
                om, has = tr.omega, tr.extras["has_signal"] > 0.5
                sel = mov & np.isfinite(om)
                r_fit = float(np.median(v[sel] / om[sel]))
                w = v / r_fit
                ok = np.abs(om - w) <= np.maximum(2.0, 0.1 * w)
                w5 = np.abs(om - w) <= 0.05 * w
                cov = ((w >= tr.omega_lo) & (w <= tr.omega_hi))[mov & has]
                print(f"| {label} | {name} | {p['q_omega']:.4g} | {p['q_amp']:.4g} | "
                      f"{p['r']:.4g} | {smooth} | {100 * ok[mov].mean():.1f} | "
                      f"{100 * w5[mov].mean():.1f} | {r_fit:.3f} | {100 * has[mov].mean():.0f} | "
                      f"{100 * cov.mean() if cov.size else float('nan'):.0f} | {cpu:.0f} |",
                      flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["fit", "eval", "real"])
    ap.add_argument("--seeds", default=None, help="e.g. 0-4 (fit) / 5-9 (eval)")
    ap.add_argument("--sets", default=None, help="car,cart,hungary,kart (eval: car,cart)")
    ap.add_argument("--max-seconds", type=float, default=90.0,
                    help="fit: seconds of each recording in the likelihood (0: all)")
    ap.add_argument("--out", default=None, help="fit: append JSON lines here")
    ap.add_argument("--fits", action="append", default=None,
                    help="eval: [label=]path of JSON lines from `fit --out` (repeatable)")
    ap.add_argument("--extra", default=None,
                    help='eval: one more candidate, JSON {"q_omega":..,"q_amp":..,"r":..}')
    a = ap.parse_args()
    if a.max_seconds is not None and a.max_seconds <= 0:
        a.max_seconds = None
    if a.what == "fit":
        a.seeds = a.seeds or "0-4"
        a.sets = a.sets or "car,cart,hungary,kart"
        cmd_fit(a)
    elif a.what == "real":
        a.sets = a.sets or "hungary,kart"
        cmd_real(a)
    else:
        a.seeds = a.seeds or "5-9"
        a.sets = a.sets or "car,cart"
        cmd_eval(a)


if __name__ == "__main__":
    main()
