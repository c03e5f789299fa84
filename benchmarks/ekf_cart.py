"""EKF accuracy on the simulated shelf cart, 15 seeds (issue 2; thesis table 3.1 for reference).

The thesis' EKF needs a good initial omega and cannot follow starts and stops (thesis ch. 2-3);
this benchmark measures it where it applies: a cart that keeps rolling (no stops), evaluated from
t = 5 s, initialised at the true omega. Also the whole default drive with stops, from a 10 rad/s
guess, to show why the aided tracker exists, and without a guess (the comb check's acquisition,
issue 13). ``--comb false`` runs everything without the comb check (the EKF before issue 13).
Writes a Markdown table to stdout.

Run: ``.venv/bin/python benchmarks/ekf_cart.py [--comb false]``
"""

from __future__ import annotations

import sys

import numpy as np

from vibrospeed import sim
from vibrospeed.estimators import ekf
from vibrospeed.eval.metrics import evaluate

SEEDS = range(15)
COMB = {"comb": sys.argv[sys.argv.index("--comb") + 1]} if "--comb" in sys.argv else {}


def rolling(params: dict) -> list:
    out = []
    for seed in SEEDS:
        rec = sim.simulate("cart", seed=seed, initial_stop=0, p_stop=0).slice_time(5.0)
        w0 = float(rec.channel("omega_true")[0])
        tr = ekf.estimate(rec, params={"omega0": w0, **COMB, **params})
        out.append(evaluate(tr, rec))
    return out


def with_stops(params: dict) -> list:
    out = []
    for seed in SEEDS:
        rec = sim.simulate("cart", seed=seed)
        tr = ekf.estimate(rec, params={"omega0": 10.0, **COMB, **params})
        out.append(evaluate(tr, rec))
    return out


def no_guess(params: dict) -> list:
    out = []
    for seed in SEEDS:
        rec = sim.simulate("cart", seed=seed)
        tr = ekf.estimate(rec, params={**COMB, **params})
        out.append(evaluate(tr, rec))
    return out


def main() -> None:
    print("| case | M | RMSE mean [rad/s] | RMSE median | RMSE worst | coverage 98 % band |")
    print("|---|---|---|---|---|---|")
    for name, fn in (("rolling cart, init at truth", rolling), ("cart with stops", with_stops),
                     ("cart with stops, no --init-omega", no_guess)):
        for M, extra in ((2, {}), (3, {"omega_max": 100.0})):
            ms = fn({"M": M, **extra})
            r = np.array([m.rmse for m in ms])
            c = np.array([m.coverage for m in ms])
            print(f"| {name} | {M} | {r.mean():.2f} | {np.median(r):.2f} | {r.max():.2f} | "
                  f"{np.mean(c):.1%} |")


if __name__ == "__main__":
    main()
