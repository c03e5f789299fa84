"""How much of the line-visible tunnel time of ``fuse.py sim`` the causal grid tracker's
*posterior* could give ``fuse`` online, before building on it.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/posterior_bound.py [--seeds 30] [--cache DIR]

Same drives and scoring as ``fuse.py sim`` (line-visible = tunnel samples where the offline
tracker claims a line); evaluated at ``fuse``'s fusion samples. The causal tracker runs with
``return_posterior`` (its rows at the fusion samples are kept, cached under ``DIR`` as
``sim{seed}_on_post.pkl``). At each sample, with the current online ``fuse``'s prediction
(speed ``v +- sqrt(P_vv)``, radius ``r +- sqrt(P_rr)``: a Gaussian on the wheel frequency
``v / r``, on the tracker's line ``v / (r k)`` for k in 1/2, 1, 2), per octave the product of
that Gaussian with the tracker's line-conditional posterior (``posterior / (1 - p_null)``) on
the grid points within 4 sigma, its mass against a flat posterior's (the Bayes factor of the
line at that octave) and its moment-matched mean. Reported shares of the line-visible time:

* peak: the posterior's mass within 3 % of the true line at some octave is more than twice a
  flat posterior's (a line the posterior holds, whatever the prediction);
* product: the octave with the largest Bayes factor gives a mean within 3 % of the true wheel
  frequency (k times it);
* oracle: the same with the prediction centred on the truth (its spread the filter's): whether
  the posterior pulls a right prediction away;
* now: the current online ``fuse`` within 3 %.

Split by whether the causal tracker claims a line (``has_signal``). Prints a table; nothing
is written.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from fuse import _grid, near_axes, sim_recording


def product(post, grid, m, s, width=4.0):
    """Bayes factor against a flat posterior and moment-matched mean of ``post`` (N,) times
    ``N(grid; m, s^2)`` over the grid points within ``width`` s of m (NaN, 0: none)."""
    sel = np.abs(grid - m) <= width * s
    if not sel.any():
        return 0.0, np.nan
    g = np.exp(-0.5 * ((grid[sel] - m) / s) ** 2)
    w = post[sel] * g
    z = w.sum()
    flat = g.sum() / grid.size
    if z <= 0:
        return 0.0, np.nan
    return z / flat, float(np.sum(w * grid[sel]) / z)


def seed_bound(seed, cache):
    import vibrospeed.estimators.fuse.method as fm
    from vibrospeed.estimators import fuse

    rec = sim_recording(seed)
    if not near_axes(rec):
        return None
    lo, hi = rec.meta["omega_range"]
    p = {"omega_min": lo, "omega_max": hi}
    g_off = _grid(rec, p, cache, f"sim{seed}_off")
    fix = np.isfinite(rec["gps_speed"])
    ends = fuse.fusion_samples(rec.t, fix, fuse.Config().fuse_rate)
    g_on = _grid(rec, {**p, "smooth": "none"}, cache, f"sim{seed}_on", posterior=True)
    got = {}
    real_run = fm.run

    def spy(cfg, arrays, state=None):
        res = real_run(cfg, arrays, state=state)
        got["o"] = res.output
        return res

    fm.run = spy
    try:
        f_on = fuse.estimate(rec, vibration=g_on, params={"online": True})
    finally:
        fm.run = real_run
    o = got["o"]
    r_true = rec.meta["drawn"]["wheel_radius"]
    v = rec["speed_true"][ends]
    vis = ((rec["gps_sats"] == 0) & (g_off.extras["has_signal"] > 0.5))[ends] & (v > 1.0)
    post = g_on.extras["posterior"]
    grid = g_on.extras["grid"]
    pn = g_on.extras["p_null"][ends]
    claim = g_on.extras["has_signal"][ends] > 0.5
    dg = float(np.median(np.diff(grid)))
    rows = []
    for i in np.flatnonzero(vis):
        q = post[i].astype(np.float64) / max(1.0 - pn[i], 1e-12)
        om_true = v[i] / r_true
        peak = False
        for k in (1.0, 0.5, 2.0):
            x = om_true / k
            near = np.abs(grid - x) <= 0.03 * x + 0.5 * dg
            peak |= q[near].sum() > 2.0 * near.sum() / grid.size
        vp, rp = o.xp[i, fuse.IV], o.xp[i, fuse.IR]
        Pvv, Prr = o.Pp[i, fuse.IV, fuse.IV], o.Pp[i, fuse.IR, fuse.IR]
        res = []
        for centre in (vp / rp, om_true):
            sw = np.sqrt(Pvv / rp ** 2 + (vp / rp ** 2) ** 2 * Prr + dg ** 2 / 12.0)
            best, est = 0.0, np.nan
            for k in (1.0, 0.5, 2.0):
                bf, mean = product(q, grid, centre / k, sw / k)
                if bf > best:
                    best, est = bf, k * mean
            res.append(bool(abs(est - om_true) <= 0.03 * om_true) if best > 0 else False)
        now = abs(f_on.speed[ends[i]] - v[i]) <= 0.03 * v[i]
        rows.append((claim[i], peak, res[0], res[1], now))
    return seed, np.array(rows, dtype=bool).reshape(-1, 5)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--cache", default=None)
    a = ap.parse_args()
    t0 = time.time()
    res, seed = [], 0
    while len(res) < a.seeds:
        x = seed_bound(seed, a.cache)
        if x is not None:
            res.append(x)
            s, r = x
            if r.size:
                print(f"seed {s}: n {len(r)}, peak {r[:, 1].mean():.2f} product "
                      f"{r[:, 2].mean():.2f} oracle {r[:, 3].mean():.2f} now {r[:, 4].mean():.2f}",
                      flush=True)
        seed += 1
    r = np.concatenate([x[1] for x in res])
    print(f"\n{len(res)} drives, {len(r)} line-visible fusion samples ({time.time() - t0:.0f} s)\n")
    print("| causal tracker | share | peak | product | oracle | now |")
    print("|---|---|---|---|---|---|")
    for name, m in (("all", np.ones(len(r), bool)), ("claims a line", r[:, 0]),
                    ("claims none", ~r[:, 0])):
        print(f"| {name} | {100 * m.mean():.1f} % | " + " | ".join(
            f"{100 * r[m, j].mean():.1f} %" for j in (1, 2, 3, 4)) + " |")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
