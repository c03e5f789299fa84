"""The causal grid ``OnlineTracker``'s CPU time per sample, whole and by part.

The tracker of ``benchmarks/scale.py online`` (``grid.config_for(simulate("car", seed=1),
smooth="none")``, fed the drive's ay sample by sample, 3000 samples after 300): the whole
``update`` (best of ``--repeat`` runs, ``time.process_time``), then the same stages replayed
one by one with a ``time.perf_counter`` mark between them (best of ``--repeat`` per part; the
marks cost ~0.05 us each, so the parts add up to a little more than the whole):

* pre-filter (``prefilter.step``), whitener (``whiten.step``, the adaptive pre-filter), scaling
  (``normalize.step`` and the target RMS);
* comb evidence (``grid.frames.step_evidence``: a frame's spectrum every ``hop_len`` samples,
  0.25 s; the figure is per sample, averaged over the frames' samples);
* the grid filter's ``step`` (``grid.filter.step``, the compiled iteration and its Python);
* the rest of the grid method's step and the outputs (the frame ring buffer's copy, the
  method's State, reading ``omega`` off the Estimate).

Then the filter ``step`` alone from one state, repeated (its compiled call and its Python),
and ``filter.run`` over the same 3000 samples (the compiled loop without a step's conversion
and call overhead). Run it with ``PYTHONPATH`` pointing at the tree to measure; to compare
two trees, alternate them in separate processes.

Usage::

    PYTHONPATH=src .venv/bin/python benchmarks/scale/online_parts.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    from vibrospeed import sim
    from vibrospeed.estimators import grid
    from vibrospeed.estimators.common import start_level
    from vibrospeed.estimators.grid import filter as gf
    from vibrospeed.estimators.grid import method as gm
    from vibrospeed.estimators.grid.frames import frame_ends_at, step_evidence
    from vibrospeed.estimators.online import OnlineTracker
    from vibrospeed.signal import normalize as nz
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.signal import whiten as wh

    rec = sim.simulate("car", seed=1, duration=60)
    ay = rec["ay"]
    cfg = grid.config_for(rec, axis="y", params={"smooth": "none"})
    lvl = start_level(ay, rec.dt)
    xs = [float(v) for v in ay[300:3300]]
    K = len(xs)

    def warm():
        trk = OnlineTracker(grid, cfg, level=lvl)
        for v in ay[:300]:
            trk.update(float(v))
        return trk

    whole = np.inf
    for _ in range(a.repeat):
        trk = warm()
        t0 = time.process_time()
        for v in xs:
            trk.update(v)
        whole = min(whole, (time.process_time() - t0) / K * 1e6)
    trk = warm()
    (front0,), es0 = trk.state
    names = ("pre-filter", "whitener", "scaling", "comb evidence", "grid filter step",
             "method state and outputs")
    best = dict.fromkeys(names, np.inf)
    pc = time.perf_counter
    for _ in range(a.repeat):
        acc = dict.fromkeys(names, 0.0)
        fs, ns, ws = front0
        es = es0
        for v in xs:
            t0 = pc()
            fs, y = pf.step(trk.sos, fs, v)
            t1 = pc()
            ws, y = wh.step(ws, y, trk.fs)
            t2 = pc()
            ns, y = nz.step(ns, y, trk.dt, trk.tau)
            y = trk.target * y
            t3 = pc()
            buf, count = es.buf, es.count
            ex = (step_evidence(cfg, buf, count, np.array([y])) if frame_ends_at(cfg, count)
                  else None)
            t4 = pc()
            g, est = gf.step(cfg.tracker, es.grid, y, extra=ex)
            t5 = pc()
            nxt = buf.copy()
            nxt[count % nxt.shape[0]] = y
            es = gm.State(g, nxt, count + 1)
            _ = est.omega
            t6 = pc()
            for nm, d in zip(names, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t6 - t5),
                             strict=True):
                acc[nm] += d
        for nm in names:
            best[nm] = min(best[nm], acc[nm] / K * 1e6)
    tr = cfg.tracker
    st = es0.grid
    alone = np.inf
    for _ in range(a.repeat):
        t0 = time.process_time()
        for _ in range(K):
            gf.step(tr, st, 0.3)
        alone = min(alone, (time.process_time() - t0) / K * 1e6)
    y_scaled = np.array(xs)
    y_scaled = (y_scaled - y_scaled.mean()) / y_scaled.std()
    run = np.inf
    for _ in range(a.repeat):
        t0 = time.process_time()
        gf.run(tr, y_scaled, st)
        run = min(run, (time.process_time() - t0) / K * 1e6)
    print("| what | CPU us per sample |")
    print("|---|---|")
    print(f"| OnlineTracker grid (causal), whole | {whole:.1f} |")
    for nm in names:
        print(f"| {nm} | {best[nm]:.2f} |")
    print(f"| (sum of the parts) | {sum(best.values()):.1f} |")
    print(f"| grid filter step alone, one state repeated | {alone:.2f} |")
    print(f"| grid filter run over the same samples | {run:.2f} |")


if __name__ == "__main__":
    main()
