"""Benchmark of the inertial-aided tracker (issue 4; thesis ch. 3). Run by hand:

    PYTHONPATH=src .venv/bin/python benchmarks/aided.py [sim] [sweep] [hungary] [hungary_grid]
        [hungary_default]

* sim: stop_and_go and sudden_change, 15 seeds each: RMSE over the whole drive (starts and stops
  included) of the aided tracker (window and CUSUM standstill tests, the thesis' scheme and the
  aid_always variant) against the unaided EKF (``ekf.estimate`` defaults started at 0, and the
  same kernel with the aiding switched off); latency to omega < 0.1 rad/s after each stop;
  standstill flags while moving (truth > 0.5 rad/s).
* sweep: R x low-pass cut-off per M on the simulated ``cart`` scenario (15 seeds), next to
  thesis table 3.1.
* hungary: the phyphox car drives (x lateral, y forward, gyro z): speed vs GPS with the wheel
  radius fitted once per drive, aided (with and without steady-turn fixes) next to the
  unaided EKF and RBPMF.
* hungary_grid: the aided grid trackers (-p tracker=rbpmf and tracker=grid) on the same drives,
  with the band's coverage split by the "no line" state (has_signal = p_null <= 0.5).
* hungary_default: ``-m grid`` and the aided trackers with their defaults (the candidates for
  ``-m aided``'s default) on the same drives, speed vs GPS (radius fitted to ``-m grid``).
Results are printed as markdown (pasted into benchmarks/aided/RESULTS.md).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from vibrospeed.estimators import aided, ekf, rbpmf
from vibrospeed.sim.aided import SCENARIOS

SEEDS = range(15)
DATA = Path(__file__).resolve().parents[1] / "../shared/datasets/hungary_car_phyphox"


def _rmse(a, b):
    ok = np.isfinite(a) & np.isfinite(b)
    return float(np.sqrt(np.mean((a[ok] - b[ok]) ** 2)))


def _stop_latency(rec, omega, tol=0.1):
    out = []
    for a, b in rec.meta["stops"]:
        if b - a < 1.0 or a == rec.t[0]:
            continue  # the initial standstill is no stop
        i = (rec.t >= a) & (rec.t <= b)
        bad = np.flatnonzero(omega[i] > tol)
        n = int(i.sum())
        out.append(0.0 if bad.size == 0 else
                   (rec.t[i][bad[-1]] - a if bad[-1] < n - 1 else np.inf))
    return out


NO_AID = {"standstill": "none", "mode_mu": 1e9, "boost": False, "q_bias": 0.0,
          "p0_bias": 1e-300}
#: the thesis' tracker (the defaults of aided.estimate before issue 13: window test, a_x as
#: recorded, no comb check)
THESIS = {"tracker": "ekf", "standstill": "window", "accel_offset": "none", "comb": False}
VARIANTS = {
    "aided (window, thesis)": THESIS,
    "aided EKF (-p tracker=ekf: broadband standstill, a_x offset, comb check)":
        {"tracker": "ekf"},
    "aided (CUSUM)": {**THESIS, "standstill": "cusum"},
    "aided (window, aid_always)": {**THESIS, "aid_always": True},
    "same kernel, no aiding": {**THESIS, **NO_AID},
    "aided RBPMF (window, -p tracker=rbpmf)": {"tracker": "rbpmf"},
    "aided grid (-p tracker=grid: mount estimated, offline the aided smoother; range 2-40)":
        {"tracker": "grid", "omega_min": 2.0, "omega_max": 40.0},
    "aided grid on a_x (-p tracker=grid -p accel_axis=ax, range 2-40 rad/s)":
        {"tracker": "grid", "omega_min": 2.0, "omega_max": 40.0, "accel_axis": "ax"},
    "aided grid unaided (-p tracker=grid -p aiding=none: -m grid, range 2-40 rad/s)":
        {"tracker": "grid", "omega_min": 2.0, "omega_max": 40.0, "accel_axis": "ax",
         "aiding": "none"},
}
PLAIN_RBPMF = dict(omega_min=0.0, omega_max=40.0, n_grid=161, M=2, prefilter="thesis-hplp")


def bench_sim() -> None:
    for name in ("stop_and_go", "sudden_change"):
        rows = {k: {"rmse": [], "lat": [], "fa": []} for k in VARIANTS}
        rows["EKF (ekf.estimate, omega0 = 0)"] = {"rmse": [], "lat": [], "fa": []}
        rows["RBPMF (rbpmf.estimate, same grid, unaided)"] = {"rmse": [], "lat": [], "fa": []}
        t0 = time.time()
        for seed in SEEDS:
            rec = SCENARIOS[name](seed=seed)
            w = rec["omega_true"]
            moving = w > 0.5
            for k, p in VARIANTS.items():
                tr = aided.estimate(rec, params=p)
                rows[k]["rmse"].append(_rmse(tr.omega, w))
                rows[k]["lat"] += _stop_latency(rec, tr.omega)
                rows[k]["fa"].append(float(np.mean(tr.extras["standstill"][moving] > 0)))
            e = ekf.estimate(rec, params={"omega0": 0.0})
            r = rows["EKF (ekf.estimate, omega0 = 0)"]
            r["rmse"].append(_rmse(e.omega, w))
            r["lat"] += _stop_latency(rec, e.omega)
            r["fa"].append(np.nan)
            e = rbpmf.estimate(rec, params=PLAIN_RBPMF)
            r = rows["RBPMF (rbpmf.estimate, same grid, unaided)"]
            r["rmse"].append(_rmse(e.omega, w))
            r["lat"] += _stop_latency(rec, e.omega)
            r["fa"].append(np.nan)
        base = np.array(rows["EKF (ekf.estimate, omega0 = 0)"]["rmse"])
        print(f"\n### {name}, {len(SEEDS)} seeds ({time.time() - t0:.0f} s)\n")
        print("| tracker | RMSE mean | RMSE max | worst ratio EKF/this | stops with omega < 0.1 "
              "within 1 s | max stop latency (s) | standstill flags while moving (mean / max) |")
        print("|---|---|---|---|---|---|---|")
        for k, r in rows.items():
            rm = np.array(r["rmse"])
            lat = np.array(r["lat"])
            fa = np.array(r["fa"])
            ratio = np.min(base / rm)
            fa_s = ("-" if np.all(np.isnan(fa))
                    else f"{100 * fa.mean():.2f} % / {100 * fa.max():.2f} %")
            print(f"| {k} | {rm.mean():.3f} | {rm.max():.3f} | {ratio:.1f} | "
                  f"{int(np.sum(lat <= 1.0))}/{lat.size} | {np.max(lat):.2f} | {fa_s} |")


def bench_sweep() -> None:
    from vibrospeed.eval.sweep import format_table, sweep
    from vibrospeed.sim import simulate

    recs = [simulate("cart", seed=s) for s in SEEDS]
    t0 = time.time()
    res = sweep(recs, M_values=(1, 2, 3, 4), r_values=(0.0004, 0.0008, 0.0012, 0.0016, 0.0022,
                                                      0.003),
                lp_values=(6.0, 8.0, 10.0, 12.0, 15.0, 19.0, 25.0, 30.0))
    print(f"\n### sweep on the simulated cart, {len(recs)} seeds x 120 s "
          f"({time.time() - t0:.0f} s)\n")
    print(format_table(res))
    i2 = list(res.M_values).index(2)
    j = list(res.r_values).index(0.0022)
    k = list(res.lp_values).index(19.0)
    print(f"\nAt the thesis' M = 2 setting (R = 0.0022, omega_lp = 19): summed "
          f"{res.summed[i2, j, k]:.3f}, median {res.median[i2, j, k]:.3f}, mean "
          f"{res.summed[i2, j, k] / len(recs):.3f} rad/s.")


def _fit_radius(speed_gps, omega):
    ok = np.isfinite(speed_gps) & np.isfinite(omega) & (speed_gps > 1.0)
    return float(np.sum(speed_gps[ok] * omega[ok]) / np.sum(omega[ok] ** 2))


def _gps_stats(t, v, gps):
    ok = np.isfinite(gps) & np.isfinite(v)
    e = v[ok] - gps[ok]
    c = np.corrcoef(v[ok], gps[ok])[0, 1]
    return float(np.sqrt(np.mean(e**2))), float(np.median(np.abs(e))), float(c)


HUNGARY_BASE = {"tracker": "ekf", "normalize_tau": 5.0, "prefilter": "thesis-hp"}
HUNGARY = {
    "aided EKF (thesis scheme)": {**HUNGARY_BASE, **THESIS},
    "aided EKF (defaults: broadband standstill, a_x offset, comb check)": HUNGARY_BASE,
    "aided EKF, detrended + turn fixes": {**HUNGARY_BASE, **THESIS, "accel_detrend": 60.0,
                                          "reference": "turn"},
    "aided EKF, detrended + turn fixes, init from 1st fix, line gate, aid_always": {
        **HUNGARY_BASE, **THESIS, "accel_detrend": 60.0, "reference": "turn", "init_ref": True,
        "p0_omega": 1e4, "line_min": 0.5, "aid_always": True},
    "aided RBPMF, detrended + turn fixes": {
        "tracker": "rbpmf", "accel_detrend": 60.0, "reference": "turn", "prefilter": "thesis-hp",
        "scaling": "rms", "r": rbpmf.DEFAULT_R, "q_amp": 0.001, "q_omega": 1.0,
        "n_grid": 241, "omega_max": 120.0},
}


def bench_hungary() -> None:
    from vibrospeed.eval import reference as refmod
    from vibrospeed.io import read
    from vibrospeed.io.timebase import resample_uniform

    drives = sorted(p for p in DATA.iterdir() if p.is_dir())
    print("\n### Hungary phyphox drives: speed vs GPS (m/s), radius fitted once per drive\n")
    print("| drive | min | turn fixes (first at s) | tracker | r fitted (m) | RMSE | "
          "median abs err | corr | GPS inside 98 % band | median band half-width |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for d in drives:
        rec = read(d, "phyphox")
        rec = resample_uniform(rec) if not rec.is_uniform(0.01) else rec
        # canonical body axes: x forward = phone y; y left = -(phone x, which points right)
        body = rec.with_channels(ax=rec["ay"], ay=-rec["ax"])
        gps = rec["gps_speed"]
        fx = refmod.detect(body, kinds="turn")
        first = f"{fx.t_detect[0] - rec.t[0]:.0f}" if len(fx) else "-"
        head = f"| {d.name} | {rec.duration / 60:.1f} | {len(fx)} ({first}) |"
        for k, p in HUNGARY.items():
            tr = aided.estimate(body, axis="y", wheel_radius=0.3, params=p)
            r1 = _fit_radius(gps, tr.omega)
            tr = aided.estimate(body, axis="y", wheel_radius=r1, params=p)
            print(f"{head} {k} | {r1:.3f} | {_row(tr.speed, tr.speed_lo, tr.speed_hi, gps)} |")
        for name in ("ekf", "rbpmf"):
            try:
                from vibrospeed.estimators import get

                mod = get(name)
                tr = mod.estimate(body, axis="y", wheel_radius=None)
            except Exception as exc:  # noqa: BLE001 - report and go on
                print(f"{head} {name} | failed: {type(exc).__name__}: {exc} | | | | | |")
                continue
            r1 = _fit_radius(gps, tr.omega)
            lo = None if tr.omega_lo is None else r1 * tr.omega_lo
            hi = None if tr.omega_hi is None else r1 * tr.omega_hi
            print(f"{head} {name} (unaided) | {r1:.3f} | {_row(r1 * tr.omega, lo, hi, gps)} |")


HUNGARY_GRID_BASE = {"accel_detrend": 60.0, "reference": "turn", "prefilter": "thesis-hp",
                     "scaling": "rms", "n_grid": 241, "omega_max": 120.0, "q_omega": 1.0}
HUNGARY_GRID = {
    "aided RBPMF (tracker=rbpmf, as above)": {**HUNGARY_GRID_BASE, "tracker": "rbpmf",
                                              "r": rbpmf.DEFAULT_R, "q_amp": 0.001},
    "aided grid (tracker=grid)": {**HUNGARY_GRID_BASE, "tracker": "grid", "accel_axis": "ax",
                                  "r": 0.15,
                                  "q_amp": 0.002},
}


def bench_hungary_grid() -> None:
    from vibrospeed.io import read
    from vibrospeed.io.timebase import resample_uniform

    drives = sorted(p for p in DATA.iterdir() if p.is_dir())
    print("\n### Hungary drives, aided grid trackers: band coverage by \"no line\" state\n")
    print("| drive | tracker | r fitted (m) | RMSE | corr | GPS inside 98 % band | has_signal | "
          "inside where has_signal | inside where p_null < 0.1 (share) | inside where no line "
          "| median half-width has_signal / no line (m/s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for d in drives:
        rec = read(d, "phyphox")
        rec = resample_uniform(rec) if not rec.is_uniform(0.01) else rec
        body = rec.with_channels(ax=rec["ay"], ay=-rec["ax"])
        gps = rec["gps_speed"]
        for k, p in HUNGARY_GRID.items():
            tr = aided.estimate(body, axis="y", wheel_radius=0.3, params=p)
            r1 = _fit_radius(gps, tr.omega)
            tr = aided.estimate(body, axis="y", wheel_radius=r1, params=p)
            v, lo, hi = tr.speed, tr.speed_lo, tr.speed_hi
            ok = np.isfinite(gps) & np.isfinite(v)
            rm, _, c = _gps_stats(None, v, gps)
            ins = (gps >= lo) & (gps <= hi)
            hs = tr.extras.get("has_signal", np.ones(v.size)) > 0
            conf = tr.extras["p_null"] < 0.1
            half = 0.5 * (hi - lo)

            def pct(m, ins=ins):
                return f"{100 * np.mean(ins[m]):.0f} %" if np.any(m) else "-"

            def med(m, half=half):
                return f"{np.median(half[m]):.2f}" if np.any(m) else "-"

            print(f"| {d.name} | {k} | {r1:.3f} | {rm:.2f} | {c:.2f} | {pct(ok)} | "
                  f"{100 * np.mean(hs[ok]):.0f} % | {pct(ok & hs)} | {pct(ok & conf)} "
                  f"({100 * np.mean(conf[ok]):.0f} %) | {pct(ok & ~hs)} | "
                  f"{med(ok & hs)} / {med(ok & ~hs)} |", flush=True)


#: ``hungary_default``: the candidates for ``-m aided``'s default next to ``-m grid``, each on the
#: phone's axes as logged in the body frame (x forward), the car's search range 10-120 rad/s
HUNGARY_DEFAULT = {
    "-m grid (unaided)": None,
    "aided tracker=grid (mount estimated)": {"tracker": "grid"},
    "aided tracker=grid, accel_axis=ax": {"tracker": "grid", "accel_axis": "ax"},
    "aided tracker=ekf (family defaults)": {"tracker": "ekf", "omega_min": 10.0,
                                            "omega_max": 120.0},
}


def bench_hungary_default() -> None:
    """Speed vs GPS on the Hungary drives for ``-m grid`` and the aided trackers, one wheel
    radius per drive fitted to ``-m grid``'s omega (so the aiding's r is that of the grid):
    RMSE, share of the time with GPS above 5 m/s within 5 % / 10 % of it."""
    from vibrospeed.estimators import grid
    from vibrospeed.io import read
    from vibrospeed.io.timebase import resample_uniform

    drives = sorted(p for p in DATA.iterdir() if p.is_dir())
    print("\n### Hungary drives: -m grid and the aided trackers (radius fitted to -m grid)\n")
    print("| drive | tracker | r (m) | RMSE (m/s) | within 5 % | within 10 % | mount confident |")
    print("|---|---|---|---|---|---|---|")
    for d in drives:
        rec = read(d, "phyphox")
        rec = resample_uniform(rec) if not rec.is_uniform(0.01) else rec
        body = rec.with_channels(ax=rec["ay"], ay=-rec["ax"])
        gps = rec["gps_speed"]
        g = grid.estimate(body, axis="y")
        r1 = _fit_radius(gps, g.omega)
        for k, p in HUNGARY_DEFAULT.items():
            tr = g if p is None else aided.estimate(body, axis="y", wheel_radius=r1, params=p)
            v = r1 * np.asarray(tr.omega, float)
            ok = np.isfinite(gps) & np.isfinite(v)
            mv = ok & (gps > 5.0)
            rel = np.abs(v[mv] - gps[mv]) / gps[mv]
            rm = float(np.sqrt(np.mean((v[ok] - gps[ok]) ** 2)))
            conf = tr.params.get("mount_confident", "-")
            print(f"| {d.name} | {k} | {r1:.3f} | {rm:.2f} | {100 * np.mean(rel <= 0.05):.1f} % "
                  f"| {100 * np.mean(rel <= 0.10):.1f} % | {conf} |", flush=True)


def _row(v, lo, hi, gps) -> str:
    rm, mae, c = _gps_stats(None, v, gps)
    ok = np.isfinite(gps) & np.isfinite(v)
    if lo is None or hi is None:
        return f"{rm:.2f} | {mae:.2f} | {c:.2f} | - | -"
    inside = np.mean((gps[ok] >= lo[ok]) & (gps[ok] <= hi[ok]))
    half = np.median(0.5 * (hi[ok] - lo[ok]))
    return f"{rm:.2f} | {mae:.2f} | {c:.2f} | {100 * inside:.0f} % | {half:.2f}"


if __name__ == "__main__":
    parts = sys.argv[1:] or ["sim", "sweep", "hungary"]
    if "sim" in parts:
        bench_sim()
    if "sweep" in parts:
        bench_sweep()
    if "hungary" in parts:
        bench_hungary()
    if "hungary_grid" in parts:
        bench_hungary_grid()
    if "hungary_default" in parts:
        bench_hungary_default()
