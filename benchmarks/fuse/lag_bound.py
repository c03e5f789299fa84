"""How far a fixed-lag grid tracker could take the online ``fuse``: its line at ``t - L`` is
nearly the offline one, but the speed at ``t`` must then come from the accelerometer over ``L``.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/lag_bound.py [--seeds 59] [--jobs 2]
        [--lags 0.5,1,2,3]

Same drives and scoring as ``fuse.py sim`` (cars of the random family with a tunnel, mount near
the axes; line-visible tunnel time = tunnel samples where the offline tracker claims a line;
within 3 % of ``speed_true``), fuse's tracker settings (``fuse.TRACKER_DEFAULTS``). Per lag
``L`` (s), pooled over the line-visible time, the share within 3 % of:

* ``line``: the tracker with ``smooth=lag`` (each sample's omega from the data up to ``t + L``)
  times the true radius, read at ``t`` (what the line itself is worth, were it not late);
* ``stale``: the same line read ``L`` late, ``r omega(t - L)`` (held, no propagation);
* ``line + accel``: ``r omega(t - L) + int_{t-L}^{t} (a_x - b) dt``, the line carried to ``t``
  by the longitudinal accelerometer ``ax`` with its offset ``b`` taken as the median of ``ax -
  dv/dt`` over the tunnel (an oracle offset: the truth's, constant through the tunnel);
* ``truth + accel``: the same with the true speed at ``t - L``: the accelerometer's own bound.

The causal tracker (``smooth=none``) and the offline one are the first two rows. Prints
markdown; nothing is written.
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fuse import near_axes, sim_recording  # noqa: E402

ROWS = ("line", "stale", "line + accel", "truth + accel")


def one_seed(seed: int, lags: tuple[float, ...]) -> dict | None:
    """Counts within 3 % on the line-visible tunnel time of ``seed`` (None: mount off axes)."""
    from vibrospeed.estimators import fuse, get

    rec = sim_recording(seed)
    if not near_axes(rec):
        return None
    lo, hi = rec.meta["omega_range"]
    p = {**fuse.TRACKER_DEFAULTS, "omega_min": lo, "omega_max": hi}
    grid = get("grid")
    r = rec.meta["drawn"]["wheel_radius"]
    v = rec["speed_true"]
    fs = rec.fs
    tun = rec["gps_sats"] == 0
    off = grid.estimate(rec, axis="y", params=p)
    vis = tun & (off.extras["has_signal"] > 0.5)
    out = {"seed": seed, "n": int(vis.sum())}
    if not out["n"]:
        return out
    ax = rec["ax"]
    b = float(np.median((ax - np.gradient(v) * fs)[tun]))
    integral = np.concatenate([[0.0], np.cumsum(ax - b) / fs])

    def within(x):
        return int(np.sum(np.abs(x - v)[vis] <= 0.03 * v[vis]))

    out["offline"] = within(off.omega * r)
    out["causal"] = within(grid.estimate(rec, axis="y", params={**p, "smooth": "none"}).omega * r)
    i = np.arange(len(v))
    for lag in lags:
        tr = grid.estimate(rec, axis="y", params={**p, "smooth": "lag", "lag": lag})
        j = np.maximum(i - int(round(lag * fs)), 0)
        carried = integral[i] - integral[j]
        out[lag] = {"line": within(tr.omega * r), "stale": within(tr.omega[j] * r),
                    "line + accel": within(tr.omega[j] * r + carried),
                    "truth + accel": within(v[j] + carried)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=59, help="seeds 0..N-1 (cars near the axes used)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--lags", default="0.5,1,2,3", help="s, comma-separated")
    a = ap.parse_args()
    lags = tuple(float(x) for x in a.lags.split(","))
    with ProcessPoolExecutor(a.jobs) as ex:
        rows = [r for r in ex.map(one_seed, range(a.seeds), [lags] * a.seeds) if r and r["n"]]
    n = sum(r["n"] for r in rows)
    print(f"{len(rows)} drives with a visible line, {n} line-visible tunnel samples\n")
    print(f"offline tracker x true r: {100 * sum(r['offline'] for r in rows) / n:.1f} % within "
          f"3 %; causal: {100 * sum(r['causal'] for r in rows) / n:.1f} %\n")
    print("| lag (s) | " + " | ".join(ROWS) + " |")
    print("|---|" + "---|" * len(ROWS))
    for lag in lags:
        cells = [f"{100 * sum(r[lag][k] for r in rows) / n:.1f} %" for k in ROWS]
        print(f"| {lag:g} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
