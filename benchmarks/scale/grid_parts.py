"""The default (offline, smoothed) grid estimate's CPU time by stage.

On ``simulate("car", seed=1)`` of each ``--lengths`` (its 6 IMU channels, as
``benchmarks/scale.py`` builds them; ``--data DIR`` reads ``car_<L>.parquet`` from there
instead), after a 10 s run that compiles or loads the kernels: the whole
``grid.estimate(rec, axis="y")``, then its stages one by one on the same inputs, each the best
of ``--repeat`` runs (``time.process_time``):

* pre-filter, whitener, running-RMS scaling (``grid.method._prepare`` as a whole, and
  ``whiten.apply`` alone);
* the comb evidence (``grid.frames.evidence``, mid-frame);
* the filter (``grid.filter.run`` with the log-emissions kept);
* the forward-backward smoother (``grid.smoother.smooth``) and the Viterbi path
  (``grid.viterbi.viterbi``);
* the Track (``grid.app.track`` minus its filter, smoother and Viterbi: columns, notes);
* the standstill detector (``grid.method.with_standstill``).

Run it with ``PYTHONPATH`` pointing at the tree to measure; to compare two trees, alternate
them in separate processes::

    PYTHONPATH=src .venv/bin/python benchmarks/scale/grid_parts.py [--lengths 60,600,3600]
        [--repeat 3] [--data DIR] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def _imu(rec):
    keep = ("ax", "ay", "az", "gx", "gy", "gz")
    return type(rec)(rec.t, {k: rec.channels[k] for k in keep}, source=rec.source,
                     wheel_radius=rec.wheel_radius)


def _best(f, repeat: int) -> float:
    ts = []
    for _ in range(repeat):
        c0 = time.process_time()
        f()
        ts.append(time.process_time() - c0)
    return min(ts)


def measure(rec, repeat: int) -> dict[str, float]:
    import vibrospeed.estimators.grid.app as app
    import vibrospeed.estimators.grid.filter as filt
    import vibrospeed.estimators.grid.method as gm
    import vibrospeed.estimators.grid.smoother as sm
    import vibrospeed.estimators.grid.viterbi as gv
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.signal import whiten

    config, Y, rms, notes = gm._prepare(rec, "y", None)
    tr = config.tracker
    idx, vals = gm.evidence(config, Y, centre=True)
    res = filt.run(tr, Y, return_grid_loglik=True, extra=(idx, vals))
    gll = res.grid_loglik
    x = rec.channel("ay")
    sos = pf.design(tr.prefilter, 1.0 / tr.model.dt, M=tr.model.M,
                    omega_range=(tr.omega_min, tr.omega_max))
    y0 = pf.apply(sos, x, level=float(x[:100].mean()))
    track = app.track(rec, tr, Y, rms, list(notes), axis="y", wheel_radius=None,
                      method="grid", extra=(idx, vals))
    out = {"estimate": _best(lambda: gm.estimate(rec, axis="y"), repeat)}
    parts = {
        "prepare (pre-filter, whitener, scaling)": lambda: gm._prepare(rec, "y", None),
        "whitener alone (whiten.apply)": lambda: whiten.apply(y0, 1.0 / tr.model.dt),
        "comb evidence": lambda: gm.evidence(config, Y, centre=True),
        "filter": lambda: filt.run(tr, Y, return_grid_loglik=True, extra=(idx, vals)),
        "smoother": lambda: sm.smooth(tr, gll),
        "Viterbi": lambda: gv.viterbi(tr, gll),
        "track (filter, smoother, Viterbi and Track)": lambda: app.track(
            rec, tr, Y, rms, list(notes), axis="y", wheel_radius=None, method="grid",
            extra=(idx, vals)),
        "standstill": lambda: gm.with_standstill(track, rec, "y", config, causal=False),
    }
    for k, f in parts.items():
        out[k] = _best(f, repeat)
    out["Track (columns, notes)"] = max(0.0, out.pop("track (filter, smoother, Viterbi and "
                                                     "Track)") - out["filter"]
                                        - out["smoother"] - out["Viterbi"])
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lengths", default="60,600,3600")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--data", default=None)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    from vibrospeed import io, sim
    from vibrospeed.estimators.grid import method as gm

    gm.estimate(_imu(sim.simulate("car", seed=1, duration=10.0)), axis="y")  # compile / load
    rows = {}
    for L in (float(v) for v in a.lengths.split(",")):
        if a.data:
            rec = io.read(Path(a.data) / f"car_{int(L)}.parquet")
        else:
            rec = _imu(sim.simulate("car", seed=1, duration=L))
        rows[L] = measure(rec, a.repeat)
        print(f"{L:g} s: " + ", ".join(f"{k} {v:.3f}" for k, v in rows[L].items()), flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
