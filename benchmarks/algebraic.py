"""Benchmark of the algebraic differentiators and the algebraic Vx / Vy estimator.

Run by hand (about a minute on one core)::

    PYTHONPATH=src .venv/bin/python benchmarks/algebraic.py

Writes the tables into ``benchmarks/algebraic/RESULTS.md`` between the RESULTS markers. Sections:

1. differentiation of noisy test signals: algebraic kernels (causal, causal at the exact point,
   centred) against scipy's Savitzky-Golay (centred and causal), same window; PyNumDiff is
   optional and only used if importable;
2. Vx / Vy RMSE on the two-track simulator for mu = 0.5 / 0.7 / 0.9, several seeds, against
   ``r * mean(omega)`` and pure integration of the body-frame kinematics (seed eq. 5), without
   and with small sensor biases;
3. comma2k19 segment 40: Vx against the CAN wheel-speed truth and the fused pose speed, and the
   consistency ``a_y ~ Vx * yaw rate``;
4. F1/10 FrictionMaps DS1-DS5: Vx against the particle-filter speed;
5. uncertainty: coverage of the 98 % bands of Vx and Vy on the simulator;
6. slip-onset backtracking: Vx RMSE against the backtracking depth at mu = 0.5.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy import signal as sps

from vibrospeed.estimators import algebraic as A
from vibrospeed.io.comma2k19 import read_comma2k19
from vibrospeed.io.f1tenth import read_f1tenth
from vibrospeed.models.kinematics import integrate_velocity
from vibrospeed.signal import differentiation as dif
from vibrospeed.sim import vehicle as sim
from vibrospeed.types import WHEEL_CHANNELS

ROOT = Path(__file__).resolve().parents[1]
DATA = Path("/work/shared/datasets")
DOC = ROOT / "benchmarks" / "algebraic" / "RESULTS.md"


def _rmse(a, b, m=None):
    a = np.asarray(a)
    b = np.asarray(b)
    ok = np.isfinite(a) & np.isfinite(b)
    if m is not None:
        ok &= m
    return float(np.sqrt(np.mean((a[ok] - b[ok]) ** 2))) if ok.any() else float("nan")


def bench_differentiation() -> str:
    dt, L = 0.01, 41
    t = np.arange(4000) * dt
    f = lambda t: np.sin(2 * np.pi * 0.3 * t) + 0.5 * np.sin(2 * np.pi * 0.8 * t + 1)  # noqa: E731
    df = lambda t: (2 * np.pi * 0.3 * np.cos(2 * np.pi * 0.3 * t)  # noqa: E731
                    + 0.5 * 2 * np.pi * 0.8 * np.cos(2 * np.pi * 0.8 * t + 1))
    rng = np.random.default_rng(0)
    sigma = 0.1
    x = f(t) + sigma * rng.standard_normal(t.size)
    rows = []
    k = slice(200, -200)
    for n, ref in ((0, f), (1, df)):
        cands = []
        for label, kw in (
            ("algebraic N=1 causal xi=0 (seed)", dict(N=1, xi=0.0)),
            ("algebraic N=1 causal xi*", dict(N=1, xi=dif.exact_point(n, 1))),
            ("algebraic N=2 causal xi=0", dict(N=2, xi=0.0)),
            ("algebraic N=2 centred", dict(N=2, xi=0.5, mode="centred")),
            ("algebraic N=2 kappa=mu=1 centred", dict(N=2, xi=0.5, mode="centred", kappa=1.0,
                                                      mu=1.0)),
        ):
            cfg = dif.Config(n=n, L=L, dt=dt, **kw)
            y = dif.apply(cfg, x)
            delay = cfg.delay
            cands.append((label, y, delay, dif.noise_gain(cfg)))
        for pos, label in ((L // 2, "Savitzky-Golay order 2 centred"),
                           (L - 1, "Savitzky-Golay order 2 causal (end point)")):
            c = sps.savgol_coeffs(L, 2, deriv=n, delta=dt, pos=pos, use="dot")
            # 'dot' coefficients act on the window in time order: full[i] uses x[i-L+1 .. i]
            y = np.convolve(x, c[::-1], mode="full")[: x.size]
            if pos == L // 2:
                y = np.concatenate([y[L // 2:], np.full(L // 2, np.nan)])
            cands.append((label, y, 0.0, float(np.linalg.norm(c))))
        try:  # optional
            import pynumdiff  # noqa: F401
            cands.append(("PyNumDiff (installed)", np.full_like(x, np.nan), 0.0, np.nan))
        except ImportError:
            pass
        for label, y, delay, gain in cands:
            e = _rmse(y[k], ref(t[k] - delay))
            e_now = _rmse(y[k], ref(t[k]))
            rows.append(f"| {n} | {label} | {delay * 1e3:.0f} | {gain:.3g} | {e:.4f} "
                        f"| {e_now:.4f} |")
    head = (f"Signal: sin(2 pi 0.3 t) + 0.5 sin(2 pi 0.8 t + 1) + white noise sd {sigma}, "
            f"fs = 100 Hz, window L = {L} samples (0.4 s). RMSE against the true value at the "
            "stated delay and at zero delay; noise gain = ||taps||_2 (output sd per unit input "
            "sd, in 1/s for n = 1). PyNumDiff was not installed (optional).\n\n"
            "| n | method | delay ms | noise gain | RMSE at delay | RMSE at t |\n"
            "|---|---|---|---|---|---|\n")
    return head + "\n".join(rows)


def _velocity_runs(mu, name, seeds, bias=False):
    cfg = sim.Config(mu=mu, bias_ax=0.1 if bias else 0.0, bias_gz=0.005 if bias else 0.0,
                     bias_ay=0.1 if bias else 0.0)
    res = []
    for seed in seeds:
        rec = sim.simulate(cfg, np.random.default_rng(seed), name=name)
        tr = A.estimate(rec)
        vx, vy = rec["speed_true"], rec["vy_true"]
        slip = np.abs(rec.meta["slip"]).max(axis=1) > 0.05
        w = np.mean([rec[c] for c in WHEEL_CHANNELS], axis=0) * cfg.R
        pix, piy = integrate_velocity(vx[0], vy[0], rec["gz"], rec["ax"], rec["ay"], cfg.dt)
        res.append([
            _rmse(tr.speed, vx), _rmse(w, vx), _rmse(pix, vx),
            _rmse(tr.speed, vx, slip), _rmse(w, vx, slip), _rmse(pix, vx, slip),
            _rmse(tr.extras["vy"], vy), _rmse(np.zeros_like(vy), vy), _rmse(piy, vy),
            float(np.corrcoef(tr.extras["vy"], vy)[0, 1]) if vy.std() > 1e-3 else np.nan,
            slip.mean(),
        ])
    arr = np.array(res)
    return np.array([np.nanmean(c) if np.isfinite(c).any() else np.nan for c in arr.T])


def bench_velocity(seeds=range(5)) -> str:
    out = []
    for bias in (False, True):
        out.append("\n**With biases** a_x, a_y +0.1 m/s^2, yaw rate +0.005 rad/s:\n" if bias
                    else "**White noise only** (as the seed):\n")
        out.append("| scenario | mu | Vx alg | Vx r*mean(omega) | Vx pure int. | Vx alg (slip) | "
                   "r*mean(omega) (slip) | pure int. (slip) | ratio r*w/alg (slip) | Vy alg | "
                   "Vy = 0 | Vy pure int. | corr(Vy alg, Vy) | slip fraction |")
        out.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for name in ("braking", "combined"):
            for mu in (0.5, 0.7, 0.9):
                r = _velocity_runs(mu, name, seeds, bias)
                out.append(
                    f"| {name} | {mu} | {r[0]:.3f} | {r[1]:.3f} | {r[2]:.3f} | {r[3]:.3f} | "
                    f"{r[4]:.3f} | {r[5]:.3f} | {r[4] / r[3]:.1f} | {r[6]:.3f} | {r[7]:.3f} | "
                    f"{r[8]:.3f} | {r[9]:.2f} | {r[10]:.2f} |")
    head = (f"RMSE in m/s, mean over seeds {list(seeds)}; 'slip' = samples where some wheel's "
            "|slip| > 0.05. Pure integration starts from the true velocity. Default "
            "parameters of `estimators.algebraic.Config`.\n\n")
    return head + "\n".join(out)


def _smooth(x, n):
    k = np.ones(n) / n
    return np.convolve(x, k, mode="same")


def bench_comma() -> str:
    rec = read_comma2k19(DATA / "comma2k19_example" / "segment_40")
    tr = A.estimate(rec)
    vx = tr.speed
    x = tr.extras
    ok = np.isfinite(vx)
    lines = [
        "| quantity | value |", "|---|---|",
        f"| samples, rate | {len(rec)}, {rec.fs:.1f} Hz (CAN wheel-speed stamps), "
        f"{rec.duration:.1f} s, speed {np.nanmin(rec['speed_true']):.1f}-"
        f"{np.nanmax(rec['speed_true']):.1f} m/s |",
        f"| Vx RMSE vs CAN wheel-speed truth | {_rmse(vx, rec['speed_true']):.4f} m/s |",
        f"| Vx RMSE vs fused pose speed | {_rmse(vx, rec['speed_pose']):.3f} m/s "
        f"(CAN wheel speed vs pose: {_rmse(rec['speed_true'], rec['speed_pose']):.3f}) |",
        f"| 98 % band of Vx covers the CAN truth | "
        f"{np.mean((np.abs(vx - rec['speed_true']) <= Z98 * tr.speed_std)[ok]):.3f} "
        f"(median sd {np.nanmedian(tr.speed_std):.3f} m/s) |",
        f"| fraction in integration (slip) mode | {np.nanmean(x['slip_mode']):.3f} |",
        f"| fraction with Vy integrated (turn mode) | {np.nanmean(x['turn_mode']):.3f} |",
    ]
    ay = rec["ay"]
    pred = vx * rec["gz"]
    for n, label in ((1, "raw"), (90, "1 s mean")):
        m = ok & np.isfinite(ay) & np.isfinite(pred)
        a = _smooth(ay[m], n)
        p = _smooth(pred[m], n)
        slope, off = np.polyfit(p, a, 1)
        lines.append(f"| a_y vs Vx * yaw rate ({label}) | corr {np.corrcoef(a, p)[0, 1]:.3f}, "
                     f"RMSE {_rmse(a, p):.3f} m/s^2, fit a_y = {slope:.3f} Vx r + {off:.3f} |")
    af = x["ay"]
    pf_ = vx * x["yaw_rate"]
    m = np.isfinite(af) & np.isfinite(pf_)
    lines.append(f"| same with the algebraically filtered a_y, yaw rate | corr "
                 f"{np.corrcoef(af[m], pf_[m])[0, 1]:.3f}, RMSE {_rmse(af[m], pf_[m]):.3f} m/s^2 |")
    return "\n".join(lines)


Z98 = 2.3263


def bench_uncertainty(seeds=range(5)) -> str:
    lines = ["| sensors | scenario | mu | Vx coverage | Vx RMSE | median sd(Vx) | Vy coverage | "
             "Vy RMSE | median sd(Vy) |", "|---|---|---|---|---|---|---|---|---|"]
    total = {}
    for label, bias, params in (("white noise", False, {}),
                                ("biased (0.1 m/s^2, 0.005 rad/s)", True, {}),
                                ("biased, acc_bias_sd = 0.1, gyro_bias_sd = 0.005", True,
                                 {"acc_bias_sd": 0.1, "gyro_bias_sd": 0.005})):
        cfg_b = dict(bias_ax=0.1, bias_ay=0.1, bias_gz=0.005) if bias else {}
        cx_all, cy_all = [], []
        for name in ("braking", "combined"):
            for mu in (0.5, 0.7, 0.9):
                cx, cy, rx, ry, sx, sy = [], [], [], [], [], []
                for seed in seeds:
                    rec = sim.simulate(sim.Config(mu=mu, **cfg_b), np.random.default_rng(seed),
                                       name=name)
                    tr = A.estimate(rec, params=params)
                    ex = tr.speed - rec["speed_true"]
                    ey = tr.extras["vy"] - rec["vy_true"]
                    cx.append(np.mean(np.abs(ex) <= Z98 * tr.speed_std))
                    cy.append(np.mean(np.abs(ey) <= Z98 * tr.extras["vy_std"]))
                    rx.append(_rmse(ex, 0 * ex))
                    ry.append(_rmse(ey, 0 * ey))
                    sx.append(np.median(tr.speed_std))
                    sy.append(np.median(tr.extras["vy_std"]))
                cx_all += cx
                cy_all += cy
                lines.append(f"| {label} | {name} | {mu} | {np.mean(cx):.3f} | {np.mean(rx):.3f} "
                             f"| {np.mean(sx):.3f} | {np.mean(cy):.3f} | {np.mean(ry):.3f} | "
                             f"{np.mean(sy):.3f} |")
        total[label] = (np.mean(cx_all), np.mean(cy_all))
    summary = "; ".join(f"{k}: Vx {v[0]:.3f}, Vy {v[1]:.3f}" for k, v in total.items())
    return (f"Fraction of samples with |error| <= 2.326 sd (98 % band), mean over seeds "
            f"{list(seeds)}; default parameters unless stated. Overall: {summary}.\n\n"
            + "\n".join(lines))


def bench_backtrack(seeds=range(10)) -> str:
    depths = (0, 5, 10, 20, 40)
    lines = ["| scenario | sensors | " + " | ".join(f"backtrack {b}" for b in depths) + " |",
             "|---|---|" + "---|" * len(depths)]
    for name in ("braking", "combined"):
        for bias in (False, True):
            cfg = sim.Config(mu=0.5, bias_ax=0.1 if bias else 0.0,
                             bias_ay=0.1 if bias else 0.0, bias_gz=0.005 if bias else 0.0)
            res = {b: [] for b in depths}
            for seed in seeds:
                rec = sim.simulate(cfg, np.random.default_rng(seed), name=name)
                slip = np.abs(rec.meta["slip"]).max(axis=1) > 0.05
                for b in depths:
                    tr = A.estimate(rec, params={"backtrack": b, "detect": "seed"})
                    res[b].append((_rmse(tr.speed, rec["speed_true"]),
                                   _rmse(tr.speed, rec["speed_true"], slip)))
            cells = [f"{np.mean([a for a, _ in res[b]]):.3f} / "
                     f"{np.mean([c for _, c in res[b]]):.3f}" for b in depths]
            lines.append(f"| {name} | {'biased' if bias else 'white'} | " + " | ".join(cells)
                         + " |")
    return (f"mu = 0.5, Vx RMSE all samples / slip samples (m/s), mean over seeds {list(seeds)}; "
            "the default is backtrack = alpha = 20 samples, limited to the preceding wheel-mode "
            "run (seed rule, `detect = 'seed'`; the window detection restarts a window back).\n\n"
            + "\n".join(lines))


def bench_f1tenth() -> str:
    tuned = {"eps_k": 3.0, "max_int": 0.5}
    lines = ["| run | duration s | median rate Hz | Vx alg (default) | Vx alg (seed rule, "
             "eps_k = 3, max_int = 0.5 s) | Vx alg (eps_k = 3, max_int = 0.5 s) | odometry | "
             "98 % coverage (eps_k, max_int) | integration fraction (default / eps_k, max_int) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for ds in ("DS1", "DS2", "DS3", "DS4", "DS5"):
        rec = read_f1tenth(DATA / "f1tenth_frictionmaps" / ds)
        t0 = A.estimate(rec)
        t1 = A.estimate(rec, params={"detect": "seed", **tuned})
        t2 = A.estimate(rec, params=tuned)
        v = rec["speed_true"]
        ok = np.isfinite(v) & np.isfinite(t2.speed)
        cov = np.mean(np.abs(t2.speed - v)[ok] <= Z98 * t2.speed_std[ok])
        lines.append(
            f"| {ds} | {rec.duration:.0f} | {rec.fs:.1f} | {_rmse(t0.speed, v):.3f} | "
            f"{_rmse(t1.speed, v):.3f} | {_rmse(t2.speed, v):.3f} | "
            f"{_rmse(rec['speed_odom'], v):.3f} | {cov:.3f} | "
            f"{np.nanmean(t0.extras['slip_mode']):.2f} / "
            f"{np.nanmean(t2.extras['slip_mode']):.2f} |")
    return ("RMSE in m/s against the particle-filter speed (pose differences over +-6 samples). "
            "The time line is irregular (18-44 Hz): the estimator resamples it to its median "
            "period. L1 = 0.159 m (F1TENTH gym default).\n\n" + "\n".join(lines))


def main() -> None:
    parts = [
        "### 1. Differentiation accuracy and noise attenuation\n\n" + bench_differentiation(),
        "### 2. Vx / Vy on the two-track simulator\n\n" + bench_velocity(),
        "### 3. comma2k19 segment 40 (2018 RAV4, highway)\n\n" + bench_comma(),
        "### 4. F1/10 FrictionMaps (drifting RC car)\n\n" + bench_f1tenth(),
        "### 5. Uncertainty: 98 % band coverage on the simulator\n\n" + bench_uncertainty(),
        "### 6. Slip-onset backtracking at mu = 0.5\n\n" + bench_backtrack(),
    ]
    text = "\n\n".join(parts)
    print(text)
    doc = DOC.read_text() if DOC.exists() else ""
    a, b = "<!-- RESULTS START -->", "<!-- RESULTS END -->"
    if a in doc and b in doc:
        doc = doc[: doc.index(a) + len(a)] + "\n" + text + "\n" + doc[doc.index(b):]
        DOC.write_text(doc)
    else:
        print(f"(markers not found in {DOC}; tables printed only)", file=sys.stderr)


if __name__ == "__main__":
    main()
