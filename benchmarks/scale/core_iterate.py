"""The grid tracker's compiled filter loop alone: CPU time of ``core._run`` per sample.

The default grid tracker's configuration (``grid.config_for``) on ``simulate("car", seed=1)``
at 100 Hz, 60 s (``--duration``), its pre-filtered tracked axis and the comb evidence rows as
the offline estimate uses them (mid-frame), the per-state log-emissions kept
(``want_gll``, as the smoother needs them). Grid sizes ``--sizes`` (``n_grid``; 200 is the
default), M = 3 harmonics. Each size: one run to compile or load the kernels, then ``--repeat``
runs of ``_run`` from the initial state, the best CPU time (``time.process_time``) reported.

``--ref REV`` also loads ``core.py`` as it is at the git revision REV (``git show``, into a
temporary module) and times it on the same inputs, the two alternated run by run (the machine
is shared: alternating spreads the load over both), and reports the largest relative
difference of their outputs (summary rows, log-emissions, final state).

``--parts``: the CPU time of the elementwise parts of one iteration of this tree's core
(measurement update; time update and packing; transition and merge), each called
``--part-calls`` times on the state the run reached at its middle sample; the rest of an
iteration (weights, the "no line" mixture, normalisation, summary row, copies of the
log-emissions) is the run's time per sample less their sum.

Usage::

    PYTHONPATH=src .venv/bin/python benchmarks/scale/core_iterate.py [--sizes 100,200,400]
        [--ref HEAD] [--parts] [--repeat 5] [--duration 60]
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def inputs(n_grid: int, duration: float):
    """(tables, initial state arrays, y, extra idx, extra values) of the default grid tracker
    with ``n_grid`` points on the car drive."""
    from vibrospeed import sim
    from vibrospeed.estimators import grid
    from vibrospeed.estimators.grid import filter as filt
    from vibrospeed.estimators.grid.method import _prepare

    rec = sim.simulate("car", seed=1, duration=duration)
    config, Y, _, _ = _prepare(rec, "y", {"n_grid": n_grid})
    y = np.ascontiguousarray(Y if Y.ndim == 1 else Y[:, 0])
    idx, vals = grid.evidence(config, Y, centre=True)
    tr = config.tracker
    st = filt.init(tr)
    tb = filt.tables(tr)
    ex_val = np.ascontiguousarray(vals, dtype=np.float64)
    if ex_val.shape[1] == n_grid:
        ex_val = np.ascontiguousarray(np.column_stack([ex_val, np.zeros(len(ex_val))]))
    return tb, st, y, np.ascontiguousarray(idx, dtype=np.int64), ex_val


def call(core, tb, st, y, idx, vals):
    """One ``_run`` from a copy of the state ``st``; returns (CPU s, outputs)."""
    lw = np.array(st.log_w, dtype=np.float64)
    lw0 = np.array([st.log_w_null], dtype=np.float64)
    mean = np.array(st.mean, dtype=np.float64)
    cov = np.array(st.cov, dtype=np.float64)
    cur = np.array([st.mode_j], dtype=np.int64)
    t0 = time.process_time()
    outs, _, glls = core._run(tb, lw, lw0, mean, cov, cur, y, idx, vals, False, True)
    dt = time.process_time() - t0
    return dt, (outs, glls, lw, lw0, mean, cov, cur)


def load_ref(rev: str, tmp: Path):
    src = subprocess.run(["git", "show", f"{rev}:src/vibrospeed/estimators/grid/core.py"],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    p = tmp / "core_ref.py"
    p.write_text(src)
    spec = importlib.util.spec_from_file_location("core_ref", p)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def rel_diff(a, b) -> float:
    worst = 0.0
    for x, y in zip(a, b, strict=True):
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if not np.array_equal(np.isfinite(x), np.isfinite(y)):
            return np.inf
        f = np.isfinite(x)
        d = np.abs(x[f] - y[f]) / np.maximum(np.abs(y[f]), 1e-300)
        d = d[np.abs(x[f] - y[f]) > 1e-13 * max(1.0, float(np.max(np.abs(y[f]), initial=0.0)))]
        if d.size:
            worst = max(worst, float(d.max()))
    return worst


def parts(core, tb, st, y, idx, vals, calls: int) -> list[tuple[str, float]]:
    """us per call of the core's three elementwise parts (:func:`core._update`,
    :func:`core._time_update`, :func:`core._merge`), each called ``calls`` times in a compiled
    loop on the state the run reached at its middle sample (a repeated measurement update
    shrinks the covariances, a repeated rotation turns the means: the work is the same)."""
    from numba import njit

    @njit
    def loop_update(k, Z, pidx, M, y, r, temper, ph, rows):
        for _ in range(k):
            core._update(Z, pidx, M, y, r, temper, ph, rows)

    @njit
    def loop_time(k, Z, X, ct, st, qd, M, B):
        for _ in range(k):
            core._time_update(Z, X, ct, st, qd, M, B)

    @njit
    def loop_merge(k, Z, X, w, kbT, B, rw, J, u, p0, n, lw, lamT, W, iv, Jp):
        for _ in range(k):
            core._merge(Z, X, w, kbT, B, rw, J, u, p0, n, lw, lamT, W, iv, Jp)

    h = y.size // 2
    _, (_, _, lw, lw0, mean, cov, cur) = call(core, tb, st, y[:h], idx[idx < h],
                                              vals[idx < h])
    N, n = mean.shape
    M = n // 2
    Z = np.empty((n + n * (n + 1) // 2, N))
    core._to_soa(mean, cov, Z)
    ct, sn, kbT = core._tables_soa(tb.cs, tb.kb)
    w, _, X, ph, rows, lamT = core._work(N, n, tb.B)
    w[:] = np.exp(lw - lw.max())
    w /= w.sum()
    rw = 1.0 - tb.eps - tb.p_off
    jobs = [("measurement update", loop_update,
             (Z.copy(), core._layout(n), M, float(y[h]), tb.r, tb.temper, ph, rows)),
            ("time update and packing", loop_time, (Z.copy(), X, ct, sn, tb.qd, M, tb.B)),
            ("transition and merge", loop_merge,
             (Z.copy(), X, w, kbT, tb.B, rw, tb.eps, tb.u, tb.p0, n, lw.copy(), lamT,
              rows[1], rows[2], rows[3]))]
    res = []
    for name, f, args in jobs:
        f(1, *args)
        best = np.inf
        for _ in range(5):
            t0 = time.process_time()
            f(calls, *args)
            best = min(best, time.process_time() - t0)
        res.append((name, 1e6 * best / calls))
    return res


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,200,400")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--ref", default=None)
    ap.add_argument("--parts", action="store_true")
    ap.add_argument("--part-calls", type=int, default=2000)
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from vibrospeed.estimators.grid import core

    with tempfile.TemporaryDirectory() as d:
        ref = load_ref(a.ref, Path(d)) if a.ref else None
        print("| N | samples | this tree: us / sample | x real time |"
              + (f" {a.ref}: us / sample | speed-up | max rel diff |" if ref else ""))
        for N in (int(s) for s in a.sizes.split(",")):
            tb, st, y, idx, vals = inputs(N, a.duration)
            fs = 1.0 / (a.duration / y.size)
            best, best_r = np.inf, np.inf
            _, o_new = call(core, tb, st, y, idx, vals)
            o_ref = call(ref, tb, st, y, idx, vals)[1] if ref else None
            for _ in range(a.repeat):
                best = min(best, call(core, tb, st, y, idx, vals)[0])
                if ref:
                    best_r = min(best_r, call(ref, tb, st, y, idx, vals)[0])
            us = 1e6 * best / y.size
            row = f"| {N} | {y.size} | {us:.2f} | {1e6 / (us * fs):.0f} |"
            if ref:
                us_r = 1e6 * best_r / y.size
                row += f" {us_r:.2f} | {us_r / us:.2f} | {rel_diff(o_new, o_ref):.1e} |"
            print(row, flush=True)
            if a.parts:
                ps = parts(core, tb, st, y, idx, vals, a.part_calls)
                for name, t in ps + [("the rest", us - sum(t for _, t in ps))]:
                    print(f"|   {name} | | {t:.2f} ({100 * t / us:.0f} %) | |", flush=True)


if __name__ == "__main__":
    main()
