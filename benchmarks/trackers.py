"""Harmonic trackers benchmark: accuracy on the simulator's car and cart scenarios and speed.

Usage (run by hand; results are pasted into docs/trackers.md)::

    PYTHONPATH=src python benchmarks/trackers.py accuracy --seeds 15 --rbpf-seeds 3
    PYTHONPATH=src python benchmarks/trackers.py speed

Metrics per run (truth ``omega_true``; "moving" = omega_true > 5 rad/s):

* RMSE (rad/s) over the moving samples, and the median absolute error;
* time to lock (s): from the first moving sample to the first time |error| < 2 rad/s holds
  for 1 s (NaN if never);
* wrong-harmonic share: moving samples with the estimate within 2 rad/s of omega/2 or 2 omega;
* band coverage (Bayesian trackers): share of moving samples with omega_true in the 98 % band.

Peers: a plain spectrogram-peak tracker (argmax of the 2 s Hann-window magnitude spectrum in
the search range) and, if installed, librosa's pyin and Praat's pitch tracker via
praat-parselmouth (optional; they are skipped with a note when missing).
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from vibrospeed import sim
from vibrospeed.estimators import rbpf, rbpmf, shs

SCENARIO_PARAMS = {
    # car: paper grid; thesis HP (the paper's 8 Hz HP removes the fundamental below ~50 rad/s)
    "car": {"prefilter": "thesis-hp"},
    # cart: wheel speeds ~10 rad/s (thesis), so a low grid range
    "cart": {"prefilter": "thesis-hp", "omega_min": 2.0, "omega_max": 30.0},
}


def metrics(t, est, truth, lo=None, hi=None):
    mov = truth > 5.0
    ok = mov & np.isfinite(est)
    e = est - truth
    out = {
        "rmse": float(np.sqrt(np.mean(e[ok] ** 2))) if ok.any() else np.nan,
        "medae": float(np.median(np.abs(e[ok]))) if ok.any() else np.nan,
    }
    wrong = ok & (np.abs(e) >= 2) & ((np.abs(est - truth / 2) < 2) | (np.abs(est - 2 * truth) < 2))
    out["wrong_harm"] = float(wrong.sum() / max(ok.sum(), 1))
    # time to lock
    k0 = int(np.argmax(mov)) if mov.any() else 0
    dt = float(np.median(np.diff(t)))
    hold = int(round(1.0 / dt))
    good = np.abs(e) < 2
    lock = np.nan
    run = 0
    for k in range(k0, t.size):
        run = run + 1 if good[k] else 0
        if run >= hold:
            lock = float(t[k - hold + 1] - t[k0])
            break
    out["lock_s"] = lock
    if lo is not None:
        out["cover"] = float(np.mean(((truth >= lo) & (truth <= hi))[mov]))
    return out


def spectrogram_peak(y, dt, omega_min, omega_max, batch=200):
    """Peer: per batch, the frequency of the largest Hann-window magnitude in range."""
    out = np.full(y.size, np.nan)
    freqs = 2 * np.pi * np.fft.rfftfreq(4096, dt)
    band = (freqs >= omega_min) & (freqs <= omega_max)
    for k0 in range(0, y.size - batch + 1, batch):
        x = np.nan_to_num(y[k0 : k0 + batch])
        mag = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(batch), 4096))
        out[k0 : k0 + batch] = freqs[band][np.argmax(mag[band])]
    return out


def accuracy(seeds: int, rbpf_seeds: int, n_particles: int, scenarios: list[str]) -> None:
    from vibrospeed.estimators.common import prepare_axis

    for scen in scenarios:
        rows: dict[str, list[dict]] = {}
        times: dict[str, float] = {}
        p = SCENARIO_PARAMS[scen]
        for seed in range(seeds):
            rec = sim.simulate(scen, seed=seed)
            truth = rec["omega_true"]

            def add(name, est, lo=None, hi=None, dt_run=0.0, rec=rec, truth=truth):
                rows.setdefault(name, []).append(metrics(rec.t, est, truth, lo, hi))
                times[name] = times.get(name, 0.0) + dt_run

            t0 = time.perf_counter()
            tr = rbpmf.estimate(rec, params=p)
            add("RBPMF N=200", tr.omega, tr.omega_lo, tr.omega_hi, time.perf_counter() - t0)
            if seed < rbpf_seeds:
                t0 = time.perf_counter()
                tr = rbpf.estimate(rec, params={**p, "n_particles": n_particles, "seed": seed})
                add(f"RBPF K={n_particles}", tr.omega, tr.omega_lo, tr.omega_hi,
                    time.perf_counter() - t0)
            sp = {k: v for k, v in p.items() if k in ("prefilter", "omega_min", "omega_max")}
            if scen == "cart":
                sp["omega_min"] = 4.0  # SHS needs one period of omega_min per 2 s batch
            t0 = time.perf_counter()
            tr = shs.estimate(rec, params=sp)
            add("SHS", tr.omega, dt_run=time.perf_counter() - t0)
            try:
                from vibrospeed.estimators import ekf

                t0 = time.perf_counter()
                tr = ekf.estimate(rec)
                add("EKF (lead)", tr.omega, dt_run=time.perf_counter() - t0)
            except Exception as exc:  # noqa: BLE001 - peer is optional here
                print(f"  EKF skipped: {exc}")
            y, dt, _ = prepare_axis(rec, "y", prefilter=p["prefilter"], normalize_tau=None)
            t0 = time.perf_counter()
            est = spectrogram_peak(y, dt, p.get("omega_min", 10.0), p.get("omega_max", 120.0))
            add("spectrogram peak", est, dt_run=time.perf_counter() - t0)
        print(f"\n## {scen}: {seeds} seeds ({len(rec)} samples each)\n")
        print("| method | runs | RMSE best / median / worst | median abs err | lock s median "
              "(locked %) | wrong harmonic % | band coverage % | run time s/run |")
        print("|---|---|---|---|---|---|---|---|")
        for name, rs in rows.items():
            rm = np.array([r["rmse"] for r in rs])
            lk = np.array([r["lock_s"] for r in rs])
            cov = [r["cover"] for r in rs if "cover" in r]
            lockpct = 100 * np.mean(np.isfinite(lk) & (lk < 2.0))
            print(f"| {name} | {len(rs)} | {np.nanmin(rm):.2f} / {np.nanmedian(rm):.2f} / "
                  f"{np.nanmax(rm):.2f} | {np.nanmedian([r['medae'] for r in rs]):.2f} | "
                  f"{np.nanmedian(lk):.2f} ({lockpct:.0f} % < 2 s) | "
                  f"{100 * np.mean([r['wrong_harm'] for r in rs]):.1f} | "
                  f"{(100 * np.mean(cov)) if cov else float('nan'):.0f} | "
                  f"{times[name] / len(rs):.2f} |")


def speed() -> None:
    rng = np.random.default_rng(0)
    n = 100_000  # 1000 s at 100 Hz
    y = 0.5 * rng.normal(size=n)
    cfg = rbpmf.Config()
    rbpmf.run(cfg, y[:10])
    for N in (50, 100, 200, 400):
        c = rbpmf.Config(n_grid=N)
        rbpmf.run(c, y[:10])
        t0 = time.process_time()
        rbpmf.run(c, y[: n // 5])
        el = (time.process_time() - t0) * 5
        print(f"RBPMF N={N} M=3 band B={c.kern.B}: {el:.2f} s CPU per 1000 s of 100 Hz data "
              f"({n / el:,.0f} samples/s, {1000 / el:.0f}x real time)")
    tracemalloc.start()
    rbpmf.run(cfg, y[:20000])
    print(f"RBPMF N=200 peak traced memory over 20000 samples: "
          f"{tracemalloc.get_traced_memory()[1] / 1e6:.1f} MB")
    tracemalloc.stop()
    c = rbpf.Config(n_particles=3000)
    rbpf.run(c, y[:10], np.random.default_rng(0))
    t0 = time.process_time()
    rbpf.run(c, y[:2000], np.random.default_rng(0))
    el = time.process_time() - t0
    print(f"RBPF K=3000: {2000 / el:,.0f} samples/s")
    c = shs.Config()
    t0 = time.process_time()
    shs.run(c, y)
    el = time.process_time() - t0
    print(f"SHS batch 200: {n / el:,.0f} samples/s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["accuracy", "speed"])
    ap.add_argument("--seeds", type=int, default=15)
    ap.add_argument("--rbpf-seeds", type=int, default=15)
    ap.add_argument("--particles", type=int, default=3000)
    ap.add_argument("--scenarios", default="car,cart")
    a = ap.parse_args()
    if a.what == "accuracy":
        accuracy(a.seeds, a.rbpf_seeds, a.particles, a.scenarios.split(","))
    else:
        speed()


if __name__ == "__main__":
    main()
