"""``fuse`` (vibration + acceleration + GPS, radius learned) through GPS outages.

    PYTHONPATH=src .venv/bin/python benchmarks/fuse/fuse.py [sim] [real] [--seeds 30]
        [--jobs 2] [--cache DIR] [--write]

(a) Simulated: cars of the random family (``simulate("random", seed=N, duration=300,
vehicle="car", gps_model=outage_gps())``: one tunnel of 30-180 s entered at 10-30 m/s no
earlier than 60 s, two receiver jumps, two weak-sky periods with 4-6 satellites). Only seeds
whose drawn mount is near the vehicle's axes (every angle within 0.35 rad) are used: the
accelerometer methods need a longitudinal axis (``ax``), which a mount "anywhere" does not give.
Vibration on ``ay`` (the default axis), range ``meta["omega_range"]``. Scored inside the
tunnels (satellites 0), against ``speed_true``: RMSE, share within 3 % of the speed, pooled over
time; "line visible" = where the offline grid tracker claims a line (``has_signal``). Methods:
``fuse`` offline (smoothed grid + RTS), online (causal grid + forward filter) and with a 2 s
lag (``-p lag=2``: the grid's fixed-lag smoother + forward filter), ``gps-riss``
(its defaults, accelerometer only through the outage), and the grid tracker alone times the
true radius (offline / causal). Also: the learned radius against the truth, the largest step of
the online fused speed in the 10 s after the tunnel in units of its 98 % band.

(b) Real: the GoPro kart (raw ACCL counts, scaled to m/s^2 by the median norm = g; the
longitudinal axis is the one whose 1 s mean correlates best with the derivative of the GPS
speed, sign included; vibration on z, 20-300 rad/s as benchmarks/robustness/real_check.py)
and the seven Hungary phone drives (phyphox, ay forward, GPS 1 Hz, no visible wheel line).
GPS is withheld in consecutive 60 s windows (one at a time, from 60 s on); the withheld fixes
are the truth. The grid tracker runs once per recording (it does not see GPS).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pickle
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: heading of the hand-kept section of RESULTS.md that ``--write`` keeps
EARLIER = "## Earlier runs"
DATA = HERE.parents[2] / "shared" / "datasets"
Z98 = 2.326


def _grid(rec, params, cache, key, axis="y", posterior=False):
    """The grid track ``fuse.estimate`` would run itself: fuse's tracker settings
    (``fuse.TRACKER_DEFAULTS``, the strict comb) under ``params``; cached under ``key``.
    ``posterior``: with the tracker's grid posterior kept at ``fuse``'s fusion samples of the
    recording with all its fixes (``extras["posterior"]``, ``"posterior_index"``, ``"grid"``;
    a recording with fixes withheld has a subset of those samples), for ``vib_measure=
    posterior``."""
    from vibrospeed.estimators import fuse, get

    key = key + ("_post" if posterior else "")
    f = Path(cache) / f"{key}.pkl" if cache else None
    if f is not None and f.is_file():
        return pickle.loads(f.read_bytes())
    tr = get("grid").estimate(rec, axis=axis, params={**fuse.TRACKER_DEFAULTS, **params},
                              return_posterior=posterior)
    if posterior:
        g = rec.channels.get("gps_speed", np.full(len(rec), np.nan))
        ends = fuse.fusion_samples(rec.t, np.isfinite(g), fuse.Config().fuse_rate)
        tr.extras["posterior"] = np.ascontiguousarray(tr.extras["posterior"][ends])
        tr.extras["posterior_index"] = ends
    if f is not None:
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(pickle.dumps(tr))
    return tr


def sim_recording(seed: int):
    from vibrospeed.sim import simulate
    from vibrospeed.sim.gps import outage_gps

    return simulate("random", seed=seed, duration=300.0, vehicle="car",
                    gps_model=outage_gps())


def near_axes(rec) -> bool:
    return bool(np.max(np.abs(rec.meta["drawn"]["mount"])) <= 0.35)


def _score(est, v, mask, std=None):
    """Pooled counts over ``mask``: samples, squared error, within 3 % of the speed and, with
    the estimate's ``std``, inside its 98 % band (``|e| <= 2.326 std``)."""
    if not mask.any():
        return {"n": 0, "sse": 0.0, "w3": 0, "cov": 0}
    e = est[mask] - v[mask]
    cov = -1 if std is None else int(np.sum(np.abs(e) <= Z98 * std[mask]))
    return {"n": int(mask.sum()), "sse": float(np.sum(e * e)),
            "w3": int(np.sum(np.abs(e) <= 0.03 * v[mask])), "cov": cov}


#: s, fuse's fixed lag (``-p lag``: a device that can wait that long) of the lag rows
LAG = 2.0

#: extra fuse parameters for every run (--param NAME=VALUE; gps-riss takes the receiver's)
EXTRA: dict = {}
#: extra gps-riss parameters (--gps-riss-param NAME=VALUE)
EXTRA_GR: dict = {}


def sim_seed(seed: int, cache: str | None, extra: dict | None = None) -> dict:
    from vibrospeed.estimators import fuse, gps_riss

    t0 = time.time()
    rec = sim_recording(seed)
    lo, hi = rec.meta["omega_range"]
    p = {"omega_min": lo, "omega_max": hi}
    g_off = _grid(rec, p, cache, f"sim{seed}_off")
    g_on = _grid(rec, {**p, "smooth": "none"}, cache, f"sim{seed}_on", posterior=True)
    g_lag = _grid(rec, {**p, "smooth": "lag", "lag": LAG}, cache, f"sim{seed}_lag{LAG:g}")
    r = rec.meta["drawn"]["wheel_radius"]
    v = rec["speed_true"]
    tun = rec["gps_sats"] == 0
    vis = tun & (g_off.extras["has_signal"] > 0.5)
    extra = dict(extra or {})
    f_off = fuse.estimate(rec, vibration=g_off, params=extra)
    f_on = fuse.estimate(rec, vibration=g_on, params={**extra, "online": True})
    f_lag = fuse.estimate(rec, vibration=g_lag, params={**extra, "lag": LAG})
    shared = {f.name for f in dataclasses.fields(gps_riss.GpsFields)}
    gr = gps_riss.estimate(rec, params={**{k: x for k, x in extra.items() if k in shared},
                                        **EXTRA_GR})
    ests = {"fuse offline": f_off.speed, "fuse online": f_on.speed,
            f"fuse, lag {LAG:g} s": f_lag.speed, "gps-riss": gr.speed,
            "vibration x true r, offline": g_off.omega * r,
            "vibration x true r, causal": g_on.omega * r}
    stds = {"fuse offline": f_off.speed_std, "fuse online": f_on.speed_std,
            f"fuse, lag {LAG:g} s": f_lag.speed_std, "gps-riss": gr.speed_std}
    # with GPS: moving (true speed above 0.3 m/s) outside the tunnels
    gps_on = ~tun & (v > 0.3)
    out = {"seed": seed, "tunnel_s": float(tun.sum() / rec.fs), "vis_share": float(
        vis.sum() / max(tun.sum(), 1)), "r": r,
        "r_off": f_off.params["learned_radius"], "r_on": f_on.params["learned_radius"],
        "r_std": f_off.params["learned_radius_std"],
        "r_std_on": f_on.params["learned_radius_std"], "comb": rec.meta["drawn"]["comb_shape"],
        "fs": rec.fs, "scores": {k: {"tunnel": _score(x, v, tun, stds.get(k)),
                                     "visible": _score(x, v, vis),
                                     "gps": _score(x, v, gps_on, stds.get(k))}
                                 for k, x in ests.items()},
        "gps_lag": (f_off.params.get("learned_gps_lag"), gr.params.get("learned_gps_lag"))}
    # the online speed's steps in the 10 s after the tunnel, in units of its band before
    idx = np.flatnonzero(tun)
    if idx.size and idx[-1] + 2 < len(rec):
        k1 = idx[-1] + 1
        sl = slice(k1 - 1, min(len(rec), k1 + int(10 * rec.fs)))
        dv = np.abs(np.diff(f_on.speed[sl]))
        out["jump"] = float(np.max(dv / (Z98 * f_on.speed_std[sl][:-1])))
    src = f_off.extras["source"]
    out["src_tunnel"] = [float(np.mean(src[tun] == c)) for c in range(4)]
    out["lines"] = {"offline": _line_stats(g_off, r, v, tun), "causal": _line_stats(g_on, r, v,
                                                                                     tun)}
    out["secs"] = time.time() - t0
    return out


def _line_stats(tr, r, v, tun) -> dict:
    """The tracker's claimed lines in the tunnel while moving: which are the wheel's (mode
    times the true radius within 3 % of the speed), their spreads relative to omega (whole
    posterior, within the mode), and which a gate on the mode's share of the whole posterior,
    ``(1 - p_null) p_mode > 1/2``, would pass (measured for fuse, not used: RESULTS.md)."""
    ex = tr.extras
    m = tun & (ex["has_signal"] > 0.5) & (v > 1.0)
    om = ex["omega_mode"][m]
    right = np.abs(om * r / v[m] - 1.0) <= 0.03
    gate = (1.0 - ex["p_null"][m]) * ex["p_mode"][m] > 0.5
    return {"right": right, "gate": gate, "sd": tr.omega_std[m][right] / om[right],
            "sd_mode": ex["omega_mode_std"][m][right] / om[right]}


def _lines_line(res, kind: str) -> str:
    st = [r["lines"][kind] for r in res]
    right = np.concatenate([x["right"] for x in st])
    gate = np.concatenate([x["gate"] for x in st])
    sd = np.concatenate([x["sd"] for x in st])
    sdm = np.concatenate([x["sd_mode"] for x in st])
    if not right.size:
        return f"The {kind} tracker claims no line in the tunnels."
    return (f"The {kind} tracker in the tunnels, where it claims a line and the car moves: "
            f"{100 * right.mean():.1f} % of its lines are the wheel's (within 3 %); on those "
            f"its whole posterior's std is {100 * np.median(sd):.1f} % of omega (median; 90th "
            f"percentile {100 * np.quantile(sd, 0.9):.1f} %), the spread within its mode "
            f"{100 * np.median(sdm):.1f} % ({100 * np.quantile(sdm, 0.9):.1f} %); a gate "
            f"(1 - p_null) p_mode > 1/2 would pass {100 * gate[right].mean():.1f} % of the "
            f"wheel's lines and "
            f"{100 * gate[~right].mean() if (~right).any() else 0.0:.1f} % of the others.")


def sim_part(n_seeds: int, jobs: int, cache: str | None) -> str:
    seeds, skipped, s = [], 0, 0
    while len(seeds) < n_seeds:
        rec = sim_recording(s)
        if near_axes(rec):
            seeds.append(s)
        else:
            skipped += 1
        s += 1
    t0 = time.time()
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            res = list(ex.map(sim_seed, seeds, [cache] * len(seeds), [EXTRA] * len(seeds)))
    else:
        res = [sim_seed(x, cache, EXTRA) for x in seeds]
    wall = time.time() - t0
    methods = list(res[0]["scores"])
    tun_s = sum(r["tunnel_s"] for r in res)
    vis = 100 * sum(r["vis_share"] * r["tunnel_s"] for r in res) / tun_s
    lines = [f"Seeds {seeds[0]}..{seeds[-1]}: {len(seeds)} cars with the mount near the axes "
             f"({skipped} seeds with a mount anywhere skipped); tunnels "
             f"{min(r['tunnel_s'] for r in res):.0f}-{max(r['tunnel_s'] for r in res):.0f} s, "
             f"{tun_s / 60:.1f} min in all; the offline tracker claims a line on {vis:.1f} % "
             f"of the tunnel time. {sum(r['secs'] for r in res):.0f} s of compute "
             f"({wall:.0f} s wall, {jobs} processes).\n",
             "| method | tunnel RMSE (m/s) | tunnel within 3 % | line visible: RMSE | "
             "line visible: within 3 % | seeds with tunnel RMSE <= gps-riss |",
             "|---|---|---|---|---|---|"]
    for m in methods:
        agg = {}
        for part in ("tunnel", "visible"):
            n = sum(r["scores"][m][part]["n"] for r in res)
            sse = sum(r["scores"][m][part]["sse"] for r in res)
            w3 = sum(r["scores"][m][part]["w3"] for r in res)
            agg[part] = (np.sqrt(sse / max(n, 1)), 100 * w3 / max(n, 1))

        def rmse(r, mm):
            sc = r["scores"][mm]["tunnel"]
            return np.sqrt(sc["sse"] / max(sc["n"], 1))

        better = sum(rmse(r, m) <= rmse(r, "gps-riss") for r in res)
        lines.append(f"| {m} | {agg['tunnel'][0]:.2f} | {agg['tunnel'][1]:.1f} % | "
                     f"{agg['visible'][0]:.2f} | {agg['visible'][1]:.1f} % | "
                     f"{better} / {len(res)} |")
    lines += ["", "98 % band: share of the samples whose error lies inside the band "
              "(`|e| <= 2.326 speed_std`), and RMSE, with GPS (moving, outside the tunnels) and "
              "in the tunnels:", "",
              "| method | with GPS: in band | with GPS: RMSE (m/s) | tunnel: in band | "
              "tunnel: RMSE (m/s) |", "|---|---|---|---|---|"]
    for m in ("fuse offline", "fuse online", f"fuse, lag {LAG:g} s", "gps-riss"):
        row = []
        for part in ("gps", "tunnel"):
            n = sum(r["scores"][m][part]["n"] for r in res)
            row.append(100 * sum(r["scores"][m][part]["cov"] for r in res) / max(n, 1))
            row.append(np.sqrt(sum(r["scores"][m][part]["sse"] for r in res) / max(n, 1)))
        lines.append(f"| {m} | {row[0]:.1f} % | {row[1]:.3f} | {row[2]:.1f} % | {row[3]:.2f} |")
    jumps = np.array([r["jump"] for r in res if "jump" in r])

    def radius_line(key, skey, label):
        learned = np.array([r[skey] < 0.01 for r in res])  # else the prior 0.3 +- 0.15 m kept
        ratio = np.array([r[key] / r["r"] for r in res])[learned]
        octave = np.abs(np.log2(ratio)) > 0.5
        err = np.abs(ratio[~octave] - 1.0)
        return (f"{label}: learned on {learned.sum()} of {len(res)} seeds (the others saw no "
                f"line while GPS was good and keep the prior); |error| median "
                f"{100 * np.median(err):.2f} %, 90th percentile {100 * np.quantile(err, 0.9):.2f} "
                f"% over the {err.size} without an octave offset; {int(octave.sum())} learned "
                "an octave (r/2 or 2r: the tracker's line was mostly a harmonic).")

    lines += [
        "",
        "Learned radius (end of drive) against the truth. " + radius_line(
            "r_off", "r_std", "Offline") + " " + radius_line("r_on", "r_std_on", "Online"),
        f"Online fused speed after the tunnel (10 s): largest per-sample step / its 98 % band "
        f"before the step: median {np.median(jumps):.3f}, max {np.max(jumps):.3f} "
        f"({len(jumps)} tunnels).",
        "",
        _lines_line(res, "offline") + " " + _lines_line(res, "causal"),
        "",
        "Per seed (tunnel s, line visible share, RMSE in the tunnel m/s: fuse offline / online / "
        "gps-riss / vibration x true r offline; learned radius vs truth; source shares in the "
        "tunnel offline: inertial / gps / vibration / standstill):",
        "",
        "| seed | comb | fs | tunnel s | visible | fuse off | fuse on | gps-riss | vib x r | "
        "r learned / true | sources in tunnel |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in res:
        def rm(mm, r=r):
            sc = r["scores"][mm]["tunnel"]
            return np.sqrt(sc["sse"] / max(sc["n"], 1))

        lines.append(
            f"| {r['seed']} | {r['comb']} | {r['fs']:.0f} | {r['tunnel_s']:.0f} | "
            f"{100 * r['vis_share']:.0f} % | {rm('fuse offline'):.2f} | {rm('fuse online'):.2f} "
            f"| {rm('gps-riss'):.2f} | {rm('vibration x true r, offline'):.2f} | "
            f"{r['r_off']:.4f} / {r['r']:.4f} | "
            f"{' / '.join(f'{100 * x:.0f}' for x in r['src_tunnel'])} |")
    return "\n".join(lines) + "\n"


# -- real recordings ---------------------------------------------------------------------------

def kart_recording():
    import pandas as pd

    from vibrospeed import io
    from vibrospeed.types import Recording

    d = DATA / "gopro_kart"
    rec = io.read(d / "GX030410_accl_raw.csv", columns="ax=c1,ay=c2,az=c3", rate=198.4)
    X = np.column_stack([rec["ax"], rec["ay"], rec["az"]])
    scale = 9.80665 / float(np.median(np.linalg.norm(X, axis=1)))
    X = X * scale
    gps = pd.read_csv(d / "GX030410_gps_speed.csv")
    tg, vg = gps["t_video_s"].to_numpy(float), gps["gps_speed2d_mps"].to_numpy(float)
    t = rec.t
    g = np.full(t.size, np.nan)
    j = np.clip(np.searchsorted(t, tg), 0, t.size - 1)
    g[j] = vg
    # longitudinal axis: best correlation of the 1 s mean with d(GPS speed)/dt
    w = int(round(rec.fs))
    ker = np.ones(w) / w
    dv = np.gradient(np.convolve(np.interp(t, tg, vg), ker, "same"), t)
    corr = [np.corrcoef(np.convolve(X[:, i] - X[:, i].mean(), ker, "same"), dv)[0, 1]
            for i in range(3)]
    i = int(np.argmax(np.abs(corr)))
    along = np.sign(corr[i]) * X[:, i]
    ch = {"ax": X[:, 0], "ay": X[:, 1], "az": X[:, 2], "a_long": along, "gps_speed": g}
    note = (f"ACCL counts x {scale:.5f} (median norm = g); longitudinal = "
            f"{'+' if corr[i] > 0 else '-'}{'xyz'[i]} (corr {corr[i]:.2f} with dv/dt; "
            f"others {', '.join(f'{c:.2f}' for c in corr)})")
    return Recording(t, ch, source="gopro_kart"), note


def hungary_recordings():
    from vibrospeed import io

    d = DATA / "hungary_car_phyphox"
    return [io.read(p, "phyphox") for p in sorted(q for q in d.iterdir() if q.is_dir())]


def _withheld(rec, w0, w1):
    g = rec["gps_speed"].copy()
    inside = (rec.t >= w0) & (rec.t < w1)
    truth = np.where(inside & np.isfinite(g), g, np.nan)
    g[inside] = np.nan
    return rec.with_channels(gps_speed=g), truth


def real_windows(rec, axis, accel_axis, grid_params, cache, key):
    """Per 60 s window: (sse, n, within 3 %) for fuse offline/online and gps-riss; the learned
    radius of the full-GPS runs."""
    from vibrospeed.estimators import fuse, gps_riss

    g_off = _grid(rec, grid_params, cache, key + "_off", axis)
    g_on = _grid(rec, {**grid_params, "smooth": "none"}, cache, key + "_on", axis,
                 posterior=True)
    g_lag = _grid(rec, {**grid_params, "smooth": "lag", "lag": LAG}, cache,
                  key + f"_lag{LAG:g}", axis)
    full_off = fuse.estimate(rec, axis=axis, vibration=g_off, params={"accel_axis": accel_axis})
    full_on = fuse.estimate(rec, axis=axis, vibration=g_on,
                            params={"accel_axis": accel_axis, "online": True})
    full_all = fuse.estimate(rec, axis=axis, vibration=g_off,
                             params={"accel_axis": accel_axis, "vib_use": "all"})
    lagged = f"fuse, lag {LAG:g} s"
    acc = {"fuse offline": [0.0, 0, 0, 0], "fuse online": [0.0, 0, 0, 0],
           lagged: [0.0, 0, 0, 0], "fuse offline, vib_use=all": [0.0, 0, 0, 0],
           "gps-riss": [0.0, 0, 0, 0]}
    ex = dict(EXTRA)
    shared = {f.name for f in dataclasses.fields(gps_riss.GpsFields)}
    ex_gr = {**{k: x for k, x in ex.items() if k in shared}, **EXTRA_GR}
    src = np.zeros(4)
    nwin = 0
    for w0 in np.arange(rec.t[0] + 60.0, rec.t[-1] - 30.0, 60.0):
        r2, truth = _withheld(rec, w0, w0 + 60.0)
        ok = np.isfinite(truth) & (truth > 1.0)
        if ok.sum() < 5:
            continue
        nwin += 1
        f_off = fuse.estimate(r2, axis=axis, vibration=g_off,
                              params={**ex, "accel_axis": accel_axis})
        f_on = fuse.estimate(r2, axis=axis, vibration=g_on,
                             params={**ex, "accel_axis": accel_axis, "online": True})
        f_lag = fuse.estimate(r2, axis=axis, vibration=g_lag,
                              params={**ex, "accel_axis": accel_axis, "lag": LAG})
        f_all = fuse.estimate(r2, axis=axis, vibration=g_off,
                              params={**ex, "accel_axis": accel_axis, "vib_use": "all"})
        gr = gps_riss.estimate(r2, axis=accel_axis, params=dict(ex_gr))
        for name, tr in (("fuse offline", f_off), ("fuse online", f_on), (lagged, f_lag),
                         ("fuse offline, vib_use=all", f_all), ("gps-riss", gr)):
            e = tr.speed[ok] - truth[ok]
            acc[name][0] += float(np.sum(e * e))
            acc[name][1] += int(ok.sum())
            acc[name][2] += int(np.sum(np.abs(e) <= 0.03 * truth[ok]))
            acc[name][3] += int(np.sum(np.abs(e) <= Z98 * tr.speed_std[ok]))
        inside = (rec.t >= w0) & (rec.t < w0 + 60.0)
        src += [np.sum(f_off.extras["source"][inside] == c) for c in range(4)]
    return {"acc": acc, "windows": nwin, "src": (src / max(src.sum(), 1)).tolist(),
            "r_off": (full_off.params["learned_radius"], full_off.params["learned_radius_std"]),
            "r_on": (full_on.params["learned_radius"], full_on.params["learned_radius_std"]),
            "r_all": (full_all.params["learned_radius"], full_all.params["learned_radius_std"]),
            "line": float(np.mean(g_off.extras["has_signal"] > 0.5))}


def real_part(cache: str | None) -> str:
    out = []
    rec, note = kart_recording()
    res = real_windows(rec, "z", "a_long", {"omega_min": 20.0, "omega_max": 300.0}, cache,
                       "kart")
    out.append("### GoPro kart (7.6 min, GPS ~18 Hz)\n\n" + note + ". " + _real_rows(res) +
               f"\nLearned radius (line ratio v / omega, full GPS): offline "
               f"{res['r_off'][0]:.4f} +- {res['r_off'][1]:.4f} m, online "
               f"{res['r_on'][0]:.4f} +- {res['r_on'][1]:.4f} m, offline with vib_use=all "
               f"{res['r_all'][0]:.4f} +- {res['r_all'][1]:.4f} m; documented (datasets "
               "README): effective radius ~0.089 m for the line at k = 1.\n")
    recs = hungary_recordings()
    tot = None
    lines_claimed = []
    for i, r in enumerate(recs):
        res = real_windows(r, "y", "y", {}, cache, f"hungary{i}")
        lines_claimed.append(res["line"])
        if tot is None:
            tot = res
        else:
            for k in tot["acc"]:
                tot["acc"][k] = [a + b for a, b in zip(tot["acc"][k], res["acc"][k],
                                                       strict=True)]
            tot["windows"] += res["windows"]
            tot["src"] = [a + b for a, b in zip(tot["src"], res["src"], strict=True)]
    tot["src"] = [x / len(recs) for x in tot["src"]]
    out.append(f"### Hungary phone drives ({len(recs)} drives, GPS 1 Hz, ay forward)\n\n"
               + _real_rows(tot) +
               f"\nThe grid tracker claims a line on {100 * np.mean(lines_claimed):.1f} % of "
               "the samples (mean over drives): no radius can be learned there, the fused speed "
               "is GPS + accelerometer + standstill.\n")
    return "\n".join(out)


def _real_rows(res) -> str:
    rows = [f"{res['windows']} windows of 60 s with GPS withheld; scored at the withheld fixes "
            "above 1 m/s.\n", "| method | RMSE (m/s) | within 3 % | inside its 98 % band |",
            "|---|---|---|---|"]
    for k, (sse, n, w3, cov) in res["acc"].items():
        rows.append(f"| {k} | {np.sqrt(sse / max(n, 1)):.2f} | {100 * w3 / max(n, 1):.1f} % | "
                    f"{100 * cov / max(n, 1):.1f} % |")
    rows.append("")
    rows.append("Sources inside the windows (offline): " + ", ".join(
        f"{name} {100 * x:.0f} %" for name, x in zip(
            ("inertial", "gps", "vibration", "standstill"), res["src"], strict=True)) + ".")
    return "\n".join(rows) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("parts", nargs="*", help="sim, real (default: both)")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--cache", default=None, help="folder for the grid tracks (reruns)")
    ap.add_argument("--write", action="store_true", help="write RESULTS.md")
    ap.add_argument("--param", action="append", default=[],
                    help="fuse parameter NAME=VALUE for every run (variants; gps-riss takes "
                         "the receiver's: GpsFields)")
    ap.add_argument("--gps-riss-param", action="append", default=[],
                    help="gps-riss parameter NAME=VALUE for every run")
    a = ap.parse_args()
    EXTRA.update(dict(x.split("=", 1) for x in a.param))
    EXTRA_GR.update(dict(x.split("=", 1) for x in a.gps_riss_param))
    parts = a.parts or ["sim", "real"]
    t0 = time.time()
    body = []
    if "sim" in parts:
        body.append("## (a) Simulated drives with a tunnel\n\n" + sim_part(a.seeds, a.jobs,
                                                                         a.cache))
    if "real" in parts:
        body.append("## (b) Real recordings, GPS withheld in 60 s windows\n\n" +
                    real_part(a.cache))
    text = ("# fuse through GPS outages\n\nGenerated by `PYTHONPATH=src .venv/bin/python "
            f"benchmarks/fuse/fuse.py {' '.join(parts)} --seeds {a.seeds} --write` "
            f"({time.time() - t0:.0f} s; do not edit by hand, except the section \"Earlier runs\" "
            "at the end). See the script's docstring for the setup.\n\n" + "\n".join(body))
    print(text)
    if a.write:
        # the hand-kept log of earlier runs (from its heading on) stays below the new run
        old = (HERE / "RESULTS.md").read_text() if (HERE / "RESULTS.md").is_file() else ""
        k = old.find(EARLIER)
        (HERE / "RESULTS.md").write_text(text + ("\n" + old[k:] if k >= 0 else ""))


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
