"""EKF throughput: samples per second on one core for M = 2 and M = 3 (issue 2 target: 1000 s of
100 Hz data, 100 000 samples, in under 0.5 s).

Run: ``.venv/bin/python benchmarks/ekf_throughput.py``.
"""

from __future__ import annotations

import time

import numpy as np

from vibrospeed.estimators import ekf
from vibrospeed.models.harmonic import HarmonicModel


def main(n: int = 100_000, repeats: int = 5) -> None:
    rng = np.random.default_rng(0)
    t = np.arange(n) / 100.0
    y = np.cos(9.11 * t) + 0.6 * np.cos(2 * 9.11 * t) + 0.05 * rng.normal(size=n)
    print(f"{'M':>3} {'best time [s]':>14} {'samples/s':>12} {'x real time':>12}")
    for M in (1, 2, 3, 4):
        cfg = ekf.Config(HarmonicModel.from_thesis(M=M))
        ekf.run(cfg, y[:100])  # compile / load cache
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            ekf.run(cfg, y)
            best = min(best, time.perf_counter() - t0)
        print(f"{M:>3} {best:>14.3f} {n / best:>12.3g} {n / 100.0 / best:>12.0f}")
    # streaming step() from Python (per-sample call overhead)
    cfg = ekf.Config(HarmonicModel.from_thesis(M=2))
    st = ekf.init(cfg)
    m = 20_000
    t0 = time.perf_counter()
    for v in y[:m]:
        st, _ = ekf.step(cfg, st, v)
    dt = time.perf_counter() - t0
    print(f"step() from Python, M=2: {m / dt:.3g} samples/s ({dt / m * 1e6:.1f} us per sample)")


if __name__ == "__main__":
    main()
