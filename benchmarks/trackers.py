"""Harmonic trackers benchmark (issue 3): accuracy on the simulator, lock from an unknown start
at cruise (the paper's transient experiment), and speed.

Usage (run by hand; results are pasted into benchmarks/trackers/RESULTS.md)::

    PYTHONPATH=src .venv/bin/python benchmarks/trackers.py accuracy --seeds 15 --rbpf-seeds 2
    PYTHONPATH=src .venv/bin/python benchmarks/trackers.py transient --seeds 15 --rbpf-seeds 5
    PYTHONPATH=src .venv/bin/python benchmarks/trackers.py speed

Every tracker is used through ``vibrospeed.estimators.get(name).estimate(recording, axis=...,
params=...)`` only, so the numbers follow the current implementation.

``accuracy`` (``car`` and ``cart``, whole drives; "moving" = omega_true > 5 rad/s): RMSE, median
|error|, share within max(2 rad/s, 10 %), wrong-harmonic share (benchmarks/peers.py
``metrics``), 98 % band coverage, and for the grid tracker the same "where it claims a signal"
(``extras["has_signal"] > 0.5``); plus the lock time **from the drive's start (standstill)**:
from the first moving sample to the first time |error| < 2 rad/s holds for 1 s.

``transient`` (the paper's experiment, section IV: the filter is started with an unknown omega
while the car drives; see :func:`cruise_starts` and :func:`lock_after`): ``car`` seeds, start
times in the middle of every cruise, each run from the tracker's uninformed prior on the
recording cut at the start, time to lock (|error| < 2 rad/s from then on to the end of that
cruise) and whether it is left on omega/2. RBPMF / grid runs are also scored on their MAP
point ("[MAP]") and on the mean of the MAP mode ("[mode]", ``extras["omega_mode"]``).

``speed``: samples per second of ``estimate()`` on 1000 s of 100 Hz noise (RBPMF vs grid size
N, RBPF, SHS, grid), peak traced memory.
"""

from __future__ import annotations

import argparse
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

from vibrospeed import sim
from vibrospeed.estimators import get
from vibrospeed.presets import PRESETS
from vibrospeed.signal import prefilter as pf
from vibrospeed.types import Recording

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers as P  # noqa: E402  (metrics, spectrogram-peak peer, claims)

SCENARIO_PARAMS = {
    # car: paper grid; thesis HP (the paper's 8 Hz HP removes the fundamental below ~50 rad/s)
    "car": {"prefilter": "thesis-hp"},
    # cart: wheel speeds ~10 rad/s (thesis), so a low grid range
    "cart": {"prefilter": "thesis-hp", "omega_min": 2.0, "omega_max": 30.0},
}
GRID_PARAMS = {"car": {}, "cart": {"omega_min": 2.0, "omega_max": 30.0}}  # product defaults
SHS_PARAMS = {"car": {"prefilter": "thesis-hp"},
              # SHS needs one period of omega_min per 2 s batch
              "cart": {"prefilter": "thesis-hp", "omega_min": 4.0, "omega_max": 30.0}}
LOCK_TOL = 2.0  # rad/s (issue 3)
LOCK_TARGET = 2.0  # s (issue 3 / the paper)

# -- transient protocol --------------------------------------------------------------------------
CRUISE_OMEGA = 30.0  # rad/s: a cruise is above this ...
CRUISE_RATE = 2.0  # rad/s^2: ... with |d omega_true / dt| below this ...
CRUISE_MIN_S = 10.0  # s: ... for at least this long
HALF_AFTER_S = LOCK_TARGET  # the transient allowed before omega/2 time is counted
END_S = 1.0  # s: "ends on omega/2" = median estimate over the cruise's last second near omega/2


def cruise_starts(t: np.ndarray, omega_true: np.ndarray, *, omega_min: float = CRUISE_OMEGA,
                  max_rate: float = CRUISE_RATE, min_len: float = CRUISE_MIN_S
                  ) -> list[tuple[float, float]]:
    """Start times of the transient experiment: ``(t0, t_end)`` per cruise.

    A cruise is a maximal stretch where ``omega_true > omega_min`` and
    ``|d omega_true / dt| < max_rate`` (central differences), at least ``min_len`` s long;
    ``t0`` is its middle and ``t_end`` its end (the first sample after it), so every start
    leaves >= ``min_len`` / 2 s of steady driving to lock and stay locked in.
    """
    ok = (omega_true > omega_min) & (np.abs(np.gradient(omega_true, t)) < max_rate)
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        t_end = t[b] if b < t.size else t[-1] + (t[-1] - t[-2])
        if t_end - t[a] >= min_len:
            out.append((float(0.5 * (t[a] + t_end)), float(t_end)))
    return out


def in_fade(meta: dict, t0: float, t1: float) -> bool:
    """Whether a simulated harmonic fade (``meta["fades"]``, harmonic m dropped to
    ``fade_depth``) overlaps ``[t0, t1]``: the wheel comb is then incomplete (one or two of
    its lines missing), so a single line or a pair may be genuinely ambiguous."""
    return any(f["t_start"] < t1 and f["t_start"] + f["duration"] > t0
               for f in meta.get("fades", []))


def lock_after(t: np.ndarray, est: np.ndarray, truth: np.ndarray, *, tol: float = LOCK_TOL,
               half_after: float = HALF_AFTER_S, end_s: float = END_S,
               share: float = 0.95) -> dict:
    """Lock statistics of a run started at ``t[0]`` (the whole arrays are one cruise).

    Trailing samples without an estimate (SHS's unfinished last batch) are dropped first.
    lock_s: the time from ``t[0]`` to the first sample from which ``|est - truth| < tol`` holds
    for every remaining sample (the issue's "lock and stay there"; NaN: not locked at the end;
    0: locked from the first sample); lock95_s: the first sample within ``tol`` from which at
    least ``share`` of the remaining samples are within ``tol`` (sub-second excursions of a
    locked track allowed); half: share of the samples after ``t[0] + half_after`` with the
    estimate within ``tol`` of omega/2 (and not of omega); double: the same for 2 omega;
    ends_half: the median estimate over the last ``end_s`` s is within ``tol`` of omega/2 there.
    """
    fin = np.flatnonzero(np.isfinite(est))
    if fin.size:
        keep = slice(0, fin[-1] + 1)
        t, est, truth = t[keep], est[keep], truth[keep]
    good = np.abs(est - truth) < tol  # NaN compares False: no estimate is not locked
    if not good[-1]:
        lock = np.nan
    else:
        bad = np.flatnonzero(~good)
        lock = 0.0 if bad.size == 0 else float(t[bad[-1] + 1] - t[0])
    rest = np.cumsum(good[::-1])[::-1] / np.arange(good.size, 0, -1)  # share good in [k, end]
    ok95 = np.flatnonzero(good & (rest >= share))
    lock95 = float(t[ok95[0]] - t[0]) if ok95.size else np.nan
    after = t >= t[0] + half_after
    half = after & ~good & (np.abs(est - truth / 2) < tol)
    double = after & ~good & (np.abs(est - 2 * truth) < tol)
    n = max(int(after.sum()), 1)
    last = t >= t[-1] - end_s
    e_end = np.nanmedian(est[last]) if np.isfinite(est[last]).any() else np.nan
    return {"lock_s": lock, "lock95_s": lock95, "half": half.sum() / n,
            "double": double.sum() / n,
            "ends_half": bool(abs(e_end - np.median(truth[last]) / 2) < tol)}


#: (q_omega, q_omega_fast, p_fast) of the two-component walk rows: the paper's q with a rare
#: fast component, cruise q 1 with a moderate / a heavy-tailed fast one, a low q with a mild one
WALK_MIX = [(4.0, 100.0, 0.02), (1.0, 16.0, 0.01), (1.0, 100.0, 0.002), (0.5, 4.0, 0.1)]


def _mix(q_slow: float, q_fast: float, p_fast: float) -> dict:
    return {"q_omega": q_slow, "q_omega_fast": q_fast, "p_fast": p_fast}


def _selected(methods, only: str | None):
    """Rows whose label contains one of the comma-separated substrings of ``only``."""
    if not only:
        return methods
    keys = [k.strip() for k in only.split(",") if k.strip()]
    return [m for m in methods if any(k in m[0] for k in keys)]


#: the causal grid settings for a lock from an unknown start (benchmarks/trackers/RESULTS.md,
#: follow-up 5)
#: the lock recipe as it was measured in follow-up 5 (benchmarks/trackers/RESULTS.md)
LOCK_RECIPE = {"smooth": "none", "q_omega": 4.0, "comb_axes": "xyz", "amb_rel": 0.02,
               "amb_abs": 1.0, "mode_hold": 4.0}
#: what ``--preset lock`` gives today (the recipe and the strict comb; vibrospeed.presets)
LOCK_PRESET = dict(PRESETS["grid"]["lock"].params)


def transient_methods(rbpf_seeds: int, particles: int):
    """(label, method, params, seeds) of the transient experiment (all causal)."""
    return [
        ("RBPMF (paper filter, thesis-hp)", "rbpmf", {"prefilter": "thesis-hp"}, None),
        ("RBPMF (paper filter, paper-hp)", "rbpmf", {}, None),
        ("RBPMF (q_omega 1, point=mode, thesis-hp)", "rbpmf",
         {"prefilter": "thesis-hp", "q_omega": 1.0, "point": "mode"}, None),
        ("grid (filter, smooth=none)", "grid", {"smooth": "none"}, None),
        ("grid (filter, q_omega 4, point=mode)", "grid",
         {"smooth": "none", "q_omega": 4.0, "point": "mode"}, None),
        # all three accelerometer axes in the comb evidence (grid.Config.comb_axes)
        ("grid (filter, comb_axes xyz)", "grid", {"smooth": "none", "comb_axes": "xyz"}, None),
        ("grid (filter, q_omega 4, point=mode, comb_axes xyz)", "grid",
         {"smooth": "none", "q_omega": 4.0, "point": "mode", "comb_axes": "xyz"}, None),
        # the lock recipe (benchmarks/trackers/RESULTS.md follow-up 5): all axes, a narrower mode
        # window and its hysteresis
        ("grid (filter, lock recipe: q_omega 4, comb_axes xyz, mode 2 % / 1 rad/s, hold 4)",
         "grid", LOCK_RECIPE, None),
        ("grid (--preset lock: the lock recipe and the strict comb)", "grid", LOCK_PRESET, None),
        # two-component omega walk (rbpmf.Config.q_omega_fast / p_fast; issue 3 follow-up)
        *[(f"RBPMF (walk mix q {qs:g} / {qf:g}, p_fast {pf_:g}, thesis-hp)", "rbpmf",
           {"prefilter": "thesis-hp", **_mix(qs, qf, pf_)}, None) for qs, qf, pf_ in WALK_MIX],
        ("RBPMF (walk mix q 1 / 16, p_fast 0.01, point=mode, thesis-hp)", "rbpmf",
         {"prefilter": "thesis-hp", **_mix(1.0, 16.0, 0.01), "point": "mode"}, None),
        ("grid (filter, walk mix q 1 / 16, p_fast 0.05, point=mode)", "grid",
         {"smooth": "none", **_mix(1.0, 16.0, 0.05), "point": "mode"}, None),
        ("SHS", "shs", {"prefilter": "thesis-hp"}, None),
        ("EKF (omega0 = 65, the grid centre)", "ekf", {"omega0": 65.0}, None),
        (f"RBPF K={particles} (thesis-hp)", "rbpf",
         {"prefilter": "thesis-hp", "n_particles": particles}, rbpf_seeds),
    ]


def transient(seeds: int, rbpf_seeds: int, particles: int, only: str | None = None,
              seed0: int = 0) -> None:
    rows: dict[str, list[dict]] = {}
    times: dict[str, float] = {}
    n_starts = []
    methods = _selected(transient_methods(rbpf_seeds, particles), only)
    for seed in range(seed0, seed0 + seeds):
        rec = sim.simulate("car", seed=seed)
        starts = cruise_starts(rec.t, rec["omega_true"])
        n_starts.append(len(starts))
        for t0, t_end in starts:
            # causal trackers: the output on [t0, t_end) does not depend on later data, so the
            # cut at t_end only saves time
            cut = rec.slice_time(t0, t_end)
            truth = cut["omega_true"]
            for label, method, params, n_seeds in methods:
                if n_seeds is not None and seed - seed0 >= n_seeds:
                    continue
                p = {**params, "seed": seed} if method == "rbpf" else params
                c0 = time.process_time()
                try:
                    tr = get(method).estimate(cut, axis="y", params=p)
                except Exception as exc:  # noqa: BLE001 - a tracker under change
                    print(f"  seed {seed} t0 {t0:.1f}: {label} failed: {exc}")
                    continue
                times[label] = times.get(label, 0.0) + time.process_time() - c0
                outs = [(label, tr.omega)]
                if method in ("rbpmf", "grid") and "omega_map" in tr.extras:
                    outs.append((label + " [MAP]", np.asarray(tr.extras["omega_map"], float)))
                if method in ("rbpmf", "grid") and params.get("point") != "mode":
                    outs.append((label + " [mode]", np.asarray(tr.extras["omega_mode"], float)))
                for lab, est in outs:
                    r = lock_after(cut.t, est, truth)
                    r.update(seed=seed, t0=t0, dur=t_end - t0,
                             fade=in_fade(rec.meta, t0, t0 + LOCK_TARGET))
                    rows.setdefault(lab, []).append(r)
        print(f"  seed {seed}: {len(starts)} starts "
              f"({', '.join(f'{a:.0f}' for a, _ in starts)} s)", flush=True)
    print(f"\n## transient: car, seeds {seed0}..{seed0 + seeds - 1}, {sum(n_starts)} starts "
          f"({min(n_starts)}-{max(n_starts)} per seed)\n")
    print("| method | seeds | starts | lock s median / 90 % / max | starts locked < 2 s % | "
          "comb complete / in a fade: locked < 2 s % | "
          "seeds with every start < 2 s % | never locked | lock (95 % of the rest) s median "
          "(< 2 s %) | ends on omega/2 | omega/2 after 2 s % | 2 omega after 2 s % | "
          "CPU s/start |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")

    def q(x):
        return "inf" if not np.isfinite(x) else f"{x:.2f}"

    for label, rs in rows.items():
        lk = np.array([r["lock_s"] for r in rs])
        lk_inf = np.where(np.isfinite(lk), lk, np.inf)
        l95 = np.array([r["lock95_s"] for r in rs])
        l95_inf = np.where(np.isfinite(l95), l95, np.inf)
        sd = np.array([r["seed"] for r in rs])
        per_seed = [lk_inf[sd == s] for s in np.unique(sd)]
        every = np.mean([np.all(x < LOCK_TARGET) for x in per_seed])
        base = label.replace(" [MAP]", "").replace(" [mode]", "")
        fade = np.array([r["fade"] for r in rs])
        strat = (f"{100 * np.mean(lk_inf[~fade] < LOCK_TARGET):.0f} ({int(np.sum(~fade))}) / "
                 f"{100 * np.mean(lk_inf[fade] < LOCK_TARGET):.0f} ({int(np.sum(fade))})"
                 if fade.any() and (~fade).any() else "-")
        print(f"| {label} | {len(per_seed)} | {len(rs)} | {q(np.median(lk_inf))} / "
              f"{q(np.sort(lk_inf)[int(np.ceil(0.9 * lk_inf.size)) - 1])} / "
              f"{q(np.max(lk_inf))} | "
              f"{100 * np.mean(lk_inf < LOCK_TARGET):.0f} | {strat} | {100 * every:.0f} | "
              f"{int(np.sum(~np.isfinite(lk)))} | {q(np.median(l95_inf))} "
              f"({100 * np.mean(l95_inf < LOCK_TARGET):.0f} %) | "
              f"{sum(r['ends_half'] for r in rs)} | "
              f"{100 * np.mean([r['half'] for r in rs]):.2f} | "
              f"{100 * np.mean([r['double'] for r in rs]):.2f} | "
              f"{times[base] / len(rs):.2f} |")
    durs = [r["dur"] for r in next(iter(rows.values()))]
    print(f"\nCruise left after the start: median {np.median(durs):.1f} s "
          f"(min {np.min(durs):.1f}, max {np.max(durs):.1f})")


# -- accuracy over whole drives ------------------------------------------------------------------

def lock_from_standstill(t, est, truth, hold_s: float = 1.0) -> float:
    """From the first moving sample (truth > 5 rad/s) to the first time |error| < 2 rad/s holds
    for ``hold_s`` (NaN if never)."""
    mov = truth > P.MOVING
    if not mov.any():
        return np.nan
    k0 = int(np.argmax(mov))
    hold = max(1, int(round(hold_s / float(np.median(np.diff(t))))))
    good = np.abs(est - truth) < LOCK_TOL
    run = 0
    for k in range(k0, t.size):
        run = run + 1 if good[k] else 0
        if run >= hold:
            return float(t[k - hold + 1] - t[k0])
    return np.nan


def accuracy_methods(scen: str, rbpf_seeds: int, particles: int):
    p = SCENARIO_PARAMS[scen]
    return [
        ("RBPMF N=200", "rbpmf", p, None),
        ("RBPMF N=200, q_omega 1", "rbpmf", {**p, "q_omega": 1.0}, None),
        ("RBPMF N=200, walk mix q 1 / 16, p_fast 0.01", "rbpmf",
         {**p, **_mix(1.0, 16.0, 0.01)}, None),
        ("RBPMF N=200, walk mix q 4 / 100, p_fast 0.02", "rbpmf",
         {**p, **_mix(4.0, 100.0, 0.02)}, None),
        (f"RBPF K={particles}", "rbpf", {**p, "n_particles": particles}, rbpf_seeds),
        ("grid (smoother, offline)", "grid", GRID_PARAMS[scen], None),
        ("grid (filter, causal)", "grid", {**GRID_PARAMS[scen], "smooth": "none"}, None),
        ("grid (smoother, comb_axes xyz)", "grid", {**GRID_PARAMS[scen], "comb_axes": "xyz"},
         None),
        ("grid (filter, comb_axes xyz)", "grid",
         {**GRID_PARAMS[scen], "smooth": "none", "comb_axes": "xyz"}, None),
        ("SHS", "shs", SHS_PARAMS[scen], None),
        ("EKF", "ekf", {}, None),
    ]


def accuracy(seeds: int, rbpf_seeds: int, particles: int, scenarios: list[str],
             only: str | None = None) -> None:
    for scen in scenarios:
        rows: dict[str, list[dict]] = {}
        times: dict[str, float] = {}
        p = SCENARIO_PARAMS[scen]
        wmin, wmax = p.get("omega_min", 10.0), p.get("omega_max", 120.0)
        if scen == "cart":
            wmin = 4.0
        n = 0
        for seed in range(seeds):
            rec = sim.simulate(scen, seed=seed)
            truth = rec["omega_true"]
            n = len(rec)

            def add(name, est, el, lo=None, hi=None, claim=None, rec=rec, truth=truth,
                    rows=rows, times=times):
                m = P.metrics(est, truth, lo, hi, claim)
                m["lock_s"] = lock_from_standstill(rec.t, est, truth)
                rows.setdefault(name, []).append(m)
                times[name] = times.get(name, 0.0) + el

            for label, method, params, n_seeds in _selected(
                    accuracy_methods(scen, rbpf_seeds, particles), only):
                if n_seeds is not None and seed >= n_seeds:
                    continue
                pp = {**params, "seed": seed} if method == "rbpf" else params
                c0 = time.process_time()
                try:
                    tr = get(method).estimate(rec, axis="y", params=pp)
                except Exception as exc:  # noqa: BLE001
                    print(f"  {scen} seed {seed}: {label} failed: {exc}")
                    continue
                add(label, tr.omega, time.process_time() - c0, tr.omega_lo, tr.omega_hi,
                    P.claims(tr))
            if only:  # a selection of rows: no peer
                print(f"  {scen} seed {seed} done", flush=True)
                continue
            fs = 1.0 / float(np.median(np.diff(rec.t)))
            x = rec["ay"]
            head = x[: int(fs)][np.isfinite(x[: int(fs)])]
            y = pf.apply(pf.design("thesis-hp", fs), x,
                         level=float(np.mean(head)) if head.size else None)
            c0 = time.process_time()
            tf, wf = P.spectrogram_peak(y, fs, wmin, wmax)
            add("spectrogram peak (peer, centred 2 s)", P.to_samples(rec.t, tf, wf),
                time.process_time() - c0)
            print(f"  {scen} seed {seed} done", flush=True)
        print(f"\n## {scen}: {seeds} seeds ({n} samples each)\n")
        print("| method | runs | RMSE best / median / worst | median abs err | within "
              "max(2, 10 %) % | wrong harmonic % | claims signal % | within where claimed % | "
              "RMSE where claimed (median) | band coverage % (where claimed) | lock from "
              "standstill s median (< 2 s %) | s/run |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for name, rs in rows.items():
            rm = np.array([r["rmse"] for r in rs])
            lk = np.array([r["lock_s"] for r in rs])
            rc = np.array([r.get("rmse_c", np.nan) for r in rs], float)
            cov = P._pct(rs, "cover")
            if cov != "-" and P._pct(rs, "cover_c") != "-":
                cov += f" ({P._pct(rs, 'cover_c')})"
            rctxt = f"{np.nanmedian(rc):.2f}" if np.isfinite(rc).any() else "-"
            print(f"| {name} | {len(rs)} | {np.nanmin(rm):.2f} / {np.nanmedian(rm):.2f} / "
                  f"{np.nanmax(rm):.2f} | {np.nanmedian([r['medae'] for r in rs]):.2f} | "
                  f"{100 * np.mean([r['within'] for r in rs]):.1f} | "
                  f"{100 * np.mean([r['harm'] for r in rs]):.1f} | {P._pct(rs, 'claimed')} | "
                  f"{P._pct(rs, 'within_c')} | {rctxt} | {cov} | {np.nanmedian(lk):.1f} "
                  f"({100 * np.mean(np.isfinite(lk) & (lk < LOCK_TARGET)):.0f} %) | "
                  f"{times[name] / len(rs):.2f} |")
        print(f"(n = {n})")


# -- speed ---------------------------------------------------------------------------------------

def speed() -> None:
    rng = np.random.default_rng(0)
    n = 100_000  # 1000 s at 100 Hz
    t = np.arange(n) * 0.01
    rec = Recording(t, {"ay": 0.5 * rng.normal(size=n)})
    short = rec.slice_time(0, 1.0)

    def rate(method, params, frac=5):
        get(method).estimate(short, axis="y", params=params)  # compile / warm caches
        part = rec.slice_time(0, t[-1] / frac)
        c0 = time.process_time()
        get(method).estimate(part, axis="y", params=params)
        el = (time.process_time() - c0) * n / len(part)
        return el

    for N in (50, 100, 200, 400):
        el = rate("rbpmf", {"n_grid": N})
        print(f"RBPMF N={N} M=3: {el:.2f} s CPU per 1000 s of 100 Hz data "
              f"({n / el:,.0f} samples/s, {1000 / el:.0f}x real time)")
    for label, params in (("grid (smoother)", {}), ("grid (filter)", {"smooth": "none"})):
        el = rate("grid", params)
        print(f"{label} N=200 M=3: {el:.2f} s CPU per 1000 s ({n / el:,.0f} samples/s)")
    el = rate("rbpf", {"n_particles": 3000, "seed": 0}, frac=50)
    print(f"RBPF K=3000: {n / el:,.0f} samples/s ({el:.0f} s per 1000 s)")
    el = rate("shs", {}, frac=1)
    print(f"SHS batch 200: {n / el:,.0f} samples/s")
    for method, params in (("rbpmf", {}), ("grid", {})):
        part = rec.slice_time(0, 200.0)
        tracemalloc.start()
        get(method).estimate(part, axis="y", params=params)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        print(f"{method} N=200 peak traced memory over 20000 samples (estimate(), Track "
              f"included): {peak / 1e6:.1f} MB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["accuracy", "transient", "speed"])
    ap.add_argument("--seeds", type=int, default=15)
    ap.add_argument("--rbpf-seeds", type=int, default=2)
    ap.add_argument("--particles", type=int, default=3000)
    ap.add_argument("--scenarios", default="car,cart")
    ap.add_argument("--seed0", type=int, default=0,
                    help="transient: first seed (e.g. 15 for a held-out set beside 0..14)")
    ap.add_argument("--only", default=None,
                    help="run only the rows whose label contains one of these comma-separated "
                         "substrings (accuracy: without the spectrogram peer)")
    a = ap.parse_args()
    if a.what == "accuracy":
        accuracy(a.seeds, a.rbpf_seeds, a.particles, a.scenarios.split(","), a.only)
    elif a.what == "transient":
        transient(a.seeds, a.rbpf_seeds, a.particles, a.only, a.seed0)
    else:
        speed()


if __name__ == "__main__":
    main()
