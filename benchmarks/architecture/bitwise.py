"""Every estimator's output on the demo drives, saved, and compared bitwise with an earlier run.

The refactors of the estimators must not change a number. This script runs every method of
:data:`vibrospeed.estimators.METHODS` through ``estimators.get(m).estimate(...)`` on the demo
drives (``simulate --scenario cart --seed 1 --set ticks=on``, ``--scenario car --seed 1``,
``--scenario random --seed 3``) with the arguments the Makefile demo uses (``ekf`` with
``--init-omega 10``, ``gps-riss`` on axis x, ``algebraic`` with ``L1=1.2``) plus a few
variants (``method:variant``), and saves every output array (omega, omega_std, band, speed and
every numeric extra, e.g. ``has_signal``) to an ``.npz``. With
``--compare OLD.npz`` it checks bitwise equality column by column (NaN == NaN at the same
places) and exits 1 on any difference. A method that raises on a drive (e.g. no GPS channel)
stores its one-line error, which must also stay the same. ``--time`` prints each run's wall
time (the default grid on the random drive is the speed check of the refactor).

    python benchmarks/architecture/bitwise.py -o /tmp/bitwise_before.npz
    python benchmarks/architecture/bitwise.py -o /tmp/bitwise_after.npz \
        --compare /tmp/bitwise_before.npz
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from vibrospeed import estimators, sim
from vibrospeed.config import parse_params

DRIVES = {
    "cart": ("cart", 1, ["ticks=on"]),
    "car": ("car", 1, []),
    "random": ("random", 3, []),
}

# the Makefile demo's arguments per method (others: defaults)
ARGS: dict[str, dict] = {
    "ekf": {"params": {"omega0": "10"}},
    "gps-riss": {"axis": "x"},
    "algebraic": {"params": {"L1": "1.2"}},
    # variants that reach code the defaults do not: "method:variant"
    "grid:causal": {"params": {"smooth": "none"}},
    "grid:fb-fit": {"params": {"smooth": "fb", "fit": "q_omega,q_amp,r"}},
    "rbpmf:fb": {"params": {"smooth": "fb"}},
    "aided:grid": {"params": {"tracker": "grid"}},
}


def _columns(track) -> dict[str, np.ndarray]:
    out = {"t": track.t, "omega": track.omega}
    for name in ("omega_std", "omega_lo", "omega_hi", "speed", "speed_std", "speed_lo",
                 "speed_hi"):
        out[name] = np.asarray(getattr(track, name))
    for k, v in sorted(track.extras.items()):
        arr = np.asarray(v)
        if arr.dtype.kind in "fiub":
            out[f"extra.{k}"] = arr
    return out


def run_all(methods: list[str], drives: list[str], timing: bool) -> dict[str, np.ndarray]:
    res: dict[str, np.ndarray] = {}
    for dname in drives:
        scen, seed, sets = DRIVES[dname]
        rec = sim.simulate(scen, seed=seed, **parse_params(sets))
        for m in methods:
            mod = estimators.get(m.split(":")[0])
            kw = ARGS.get(m, {})
            t0 = time.perf_counter()
            try:
                track = mod.estimate(rec, **{k: (dict(v) if isinstance(v, dict) else v)
                                             for k, v in kw.items()})
            except Exception as exc:  # noqa: BLE001 - the error itself is the output
                res[f"{dname}/{m}/error"] = np.array(f"{type(exc).__name__}: {exc}")
                print(f"{dname:7s} {m:10s} error: {exc}", file=sys.stderr)
                continue
            wall = time.perf_counter() - t0
            for col, arr in _columns(track).items():
                res[f"{dname}/{m}/{col}"] = arr
            if timing:
                print(f"{dname:7s} {m:10s} {wall:8.2f} s  ({len(track)} samples)", file=sys.stderr)
    return res


def compare(new: dict[str, np.ndarray], old_path: str, runs: set[str]) -> int:
    """Columns of the runs ``runs`` ("drive/method") in ``new`` vs the file ``old_path``."""
    old = {k: v for k, v in np.load(old_path, allow_pickle=False).items()
           if "/".join(k.split("/")[:2]) in runs}
    bad = 0
    for k in sorted(set(old) | set(new)):
        if k not in old or k not in new:
            print(f"{k}: only in {'new' if k in new else 'old'}")
            bad += 1
            continue
        a, b = old[k], new[k]
        if a.shape != b.shape or a.dtype != b.dtype:
            print(f"{k}: shape/dtype {a.shape} {a.dtype} -> {b.shape} {b.dtype}")
            bad += 1
        elif a.dtype.kind == "f":
            same = np.array_equal(a.view(np.uint64 if a.itemsize == 8 else np.uint32),
                                  b.view(np.uint64 if b.itemsize == 8 else np.uint32))
            if not same:
                diff = np.nanmax(np.abs(a - b)) if a.size else 0.0
                print(f"{k}: differs (max |diff| {diff:.3g}, "
                      f"{int(np.sum(~((a == b) | (np.isnan(a) & np.isnan(b)))))} samples)")
                bad += 1
        elif not np.array_equal(a, b):
            print(f"{k}: differs")
            bad += 1
    print(f"{len(set(old) | set(new))} columns compared, {bad} differ")
    return 1 if bad else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", required=True, help="the .npz to write (outside the repo)")
    ap.add_argument("--compare", help="an earlier .npz to compare with bitwise")
    ap.add_argument("--methods", help="comma-separated methods (default: all)")
    ap.add_argument("--drives", help="comma-separated drives: cart,car,random (default: all)")
    ap.add_argument("--time", action="store_true", help="print each run's wall time")
    a = ap.parse_args()
    methods = (a.methods.split(",") if a.methods
               else estimators.available() + [k for k in ARGS if ":" in k])
    drives = a.drives.split(",") if a.drives else list(DRIVES)
    res = run_all(methods, drives, a.time)
    np.savez(a.output, **res)
    print(f"wrote {a.output}: {len(res)} columns")
    runs = {f"{d}/{m}" for d in drives for m in methods}
    return compare(res, a.compare, runs) if a.compare else 0


if __name__ == "__main__":
    sys.exit(main())
