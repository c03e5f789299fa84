"""Robustness of the algebraic Vx estimator on the randomised vehicle family (issue 13, part 5).

Run by hand (single process; a few minutes)::

    PYTHONPATH=src .venv/bin/python benchmarks/algebraic_robustness.py [--seeds 0:300]
        [--param k=v ...] [--compare detect=seed] [--no-write]

Every seed is one drive of :func:`vibrospeed.sim.vehicle.simulate_random` (tyre, ABS, events,
speeds, noise, biases and sample rate drawn from the seed). Per seed: Vx RMSE of ``algebraic``
(default parameters, or ``--param``) and of the baseline ``r * mean(wheel omega)`` over the
whole drive and inside the slip windows (some wheel's |slip| > 3 %); the ratio is
RMSE(algebraic) / RMSE(baseline), < 1 where the estimator wins. Seeds 0-99 are the tuning
set, 100-299 the held-out set. ``--compare`` adds a second parameter set (e.g. the seed's
detection) to the summary. Writes ``benchmarks/algebraic_robustness/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from vibrospeed.estimators import algebraic as A
from vibrospeed.sim import vehicle as sim
from vibrospeed.types import WHEEL_CHANNELS

OUT = Path(__file__).resolve().parent / "algebraic_robustness" / "RESULTS.md"
SLIP = 0.03


def _rmse(e, m=None):
    e = np.asarray(e)
    if m is not None:
        e = e[m]
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def evaluate(rec, params: dict | None = None) -> dict:
    """Per-drive figures of one recording with ``speed_true`` and ``meta['slip']``."""
    vx = rec["speed_true"]
    slip = np.abs(rec.meta["slip"]).max(axis=1) > SLIP
    base = np.mean([rec[c] for c in WHEEL_CHANNELS], axis=0) * rec.wheel_radius
    tr = A.estimate(rec, params=params)
    return {
        "alg": _rmse(tr.speed - vx), "base": _rmse(base - vx),
        "alg_slip": _rmse(tr.speed - vx, slip), "base_slip": _rmse(base - vx, slip),
        "slip_frac": float(slip.mean()), "int_frac": float(np.nanmean(tr.extras["slip_mode"])),
    }


def run_family(seeds, params: dict | None = None, recs: dict | None = None) -> dict[int, dict]:
    res = {}
    for seed in seeds:
        rec = recs[seed] if recs is not None and seed in recs else sim.simulate_random(seed)
        if recs is not None:
            recs[seed] = rec
        c = rec.meta["config"]
        res[seed] = {**evaluate(rec, params), "mu": c["mu"], "tyre": c["tyre"],
                     "abs": c["abs_slip"] > 0, "fs": 1.0 / c["dt"]}
    return res


def summary(res: dict[int, dict], seeds) -> dict:
    rows = [res[s] for s in seeds if s in res]
    r_all = np.array([r["alg"] / r["base"] for r in rows])
    r_slip = np.array([r["alg_slip"] / r["base_slip"] for r in rows if r["slip_frac"] > 0])
    q = lambda x, p: float(np.percentile(x, p)) if x.size else float("nan")  # noqa: E731
    return {"n": len(rows), "n_slip": int(r_slip.size),
            "all": (q(r_all, 50), q(r_all, 10), q(r_all, 90)),
            "slip": (q(r_slip, 50), q(r_slip, 10), q(r_slip, 90)),
            "lose_all": int(np.sum(r_all >= 1.0)), "lose_slip": int(np.sum(r_slip >= 1.0)),
            "alg_mean": float(np.mean([r["alg"] for r in rows])),
            "base_mean": float(np.mean([r["base"] for r in rows]))}


def gradual_case(params: dict | None = None, seeds=range(3)) -> tuple[float, float]:
    """The fixed 'gradual' scenario at mu = 0.5: mean slip-window RMSE (alg, baseline)."""
    a, b = [], []
    for seed in seeds:
        rec = sim.simulate(sim.Config(mu=0.5, sd_gz=0.005, sd_acc=0.1, sd_omega=0.1),
                           np.random.default_rng(seed), name="gradual")
        e = evaluate(rec, params)
        a.append(e["alg_slip"])
        b.append(e["base_slip"])
    return float(np.mean(a)), float(np.mean(b))


def _parse_seeds(s: str) -> range:
    a, b = s.split(":")
    return range(int(a), int(b))


def _parse_params(items) -> dict:
    out = {}
    for it in items or []:
        k, v = it.split("=", 1)
        try:
            out[k] = float(v) if "." in v or "e" in v.lower() or v == "inf" else int(v)
        except ValueError:
            out[k] = v
    return out


def _fmt(t):
    return f"{t[0]:.3f} / {t[1]:.3f} / {t[2]:.3f}"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="0:300")
    ap.add_argument("--param", action="append", help="estimator parameter k=v")
    ap.add_argument("--compare", action="append", help="second parameter set k=v")
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args(argv)
    seeds = _parse_seeds(a.seeds)
    params = _parse_params(a.param)
    t0 = time.perf_counter()
    recs: dict = {}
    sets = [("default" if not params else " ".join(f"{k}={v}" for k, v in params.items()),
             params)]
    if a.compare:
        cp = _parse_params(a.compare)
        sets.append((" ".join(f"{k}={v}" for k, v in cp.items()), cp))
    results = {label: run_family(seeds, p, recs) for label, p in sets}
    grad = {label: gradual_case(p) for label, p in sets}
    runtime = time.perf_counter() - t0
    tune = [s for s in seeds if s < 100]
    held = [s for s in seeds if 100 <= s < 300]
    lines = [
        "# `algebraic` on the randomised vehicle family",
        "",
        f"Command: `PYTHONPATH=src .venv/bin/python {' '.join(shlex.quote(x) for x in sys.argv)}`"
        f" (runtime {runtime:.0f} s, one process).",
        "",
        "Family: `vibrospeed.sim.vehicle.simulate_random(seed)` (ranges in "
        "`vehicle.RANDOM_RANGES`): magic-formula or brush tyres, peak mu 0.3-1.0, ABS / "
        "traction control on 60 % of the cars, torque ramps 0.1-1 s, demands 0.2-1.6 mu g, "
        "turns, 5-35 m/s, 50-200 Hz, production-size sensor noise and biases, 20 s per drive. "
        f"Slip windows: some wheel's |slip| > {SLIP:.0%}. Ratio = Vx RMSE of `algebraic` / "
        "Vx RMSE of `r * mean(wheel omega)` (< 1: the estimator wins); median / 10th / 90th "
        "percentile over the seeds.",
        "",
        "| parameters | seeds | n | ratio, whole drive (median / p10 / p90) | ratio, slip "
        "windows (median / p10 / p90) | seeds lost (whole / slip) | mean RMSE alg / base m/s |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, _ in sets:
        for name, ss in (("0-99 (tuning)", tune), ("100-299 (held out)", held),
                         ("all", list(seeds))):
            if not ss:
                continue
            sm = summary(results[label], ss)
            lines.append(f"| {label} | {name} | {sm['n']} | {_fmt(sm['all'])} | "
                         f"{_fmt(sm['slip'])} | {sm['lose_all']} / {sm['lose_slip']} | "
                         f"{sm['alg_mean']:.3f} / {sm['base_mean']:.3f} |")
    lines += ["", "Fixed `gradual` scenario (brake torque ramped over 0.3 s to 0.8 mu g at "
              "mu = 0.5, steady slip 3-8 %; noise sd 0.005 rad/s, 0.1 m/s^2, 0.1 rad/s; seeds "
              "0-2): Vx RMSE in the slip windows", "",
              "| parameters | algebraic m/s | r * mean(omega) m/s | ratio |", "|---|---|---|---|"]
    for label, _ in sets:
        g = grad[label]
        lines.append(f"| {label} | {g[0]:.3f} | {g[1]:.3f} | {g[0] / g[1]:.3f} |")
    for label, _ in sets:
        res = results[label]
        lost = [s for s in seeds if res[s]["alg"] >= res[s]["base"]
                or (res[s]["slip_frac"] > 0 and res[s]["alg_slip"] >= res[s]["base_slip"])]
        lines += ["", f"Seeds where `algebraic` ({label}) loses to the baseline (whole drive or "
                  f"slip windows): {len(lost)}", ""]
        if lost:
            lines += ["| seed | mu | tyre | ABS | Hz | alg | base | alg (slip) | base (slip) | "
                      "slip fraction | integration fraction |",
                      "|---|---|---|---|---|---|---|---|---|---|---|"]
            for s in lost:
                r = res[s]
                lines.append(f"| {s} | {r['mu']:.2f} | {r['tyre']} | {'yes' if r['abs'] else 'no'}"
                             f" | {r['fs']:.0f} | {r['alg']:.3f} | {r['base']:.3f} | "
                             f"{r['alg_slip']:.3f} | {r['base_slip']:.3f} | "
                             f"{r['slip_frac']:.2f} | {r['int_frac']:.2f} |")
    label0 = sets[0][0]
    lines += ["", f"Per seed ({label0}): Vx RMSE m/s", "",
              "| seed | mu | tyre | ABS | Hz | alg | base | ratio | alg (slip) | base (slip) | "
              "ratio (slip) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in seeds:
        r = results[label0][s]
        lines.append(f"| {s} | {r['mu']:.2f} | {r['tyre']} | {'yes' if r['abs'] else 'no'} | "
                     f"{r['fs']:.0f} | {r['alg']:.3f} | {r['base']:.3f} | "
                     f"{r['alg'] / r['base']:.3f} | {r['alg_slip']:.3f} | {r['base_slip']:.3f} | "
                     f"{r['alg_slip'] / r['base_slip']:.3f} |")
    text = "\n".join(lines) + "\n"
    print("\n".join(lines[:40]))
    if not a.no_write:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(text)
        print(f"written {OUT}", file=sys.stderr)


if __name__ == "__main__":
    main()
