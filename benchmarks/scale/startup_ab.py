"""Start-up of ``vibrospeed estimate`` on a short file: two source trees alternated.

For each tree (``--trees A/src,B/src``) in fresh processes: ``python -c "import vibrospeed"``,
``python -c "import vibrospeed.cli.app"``, ``python -m vibrospeed estimate short.csv -o
est.csv`` (the default method: fuse on this drive, which has GPS speed) and the same with
``-m grid``, each with that tree's own warm numba cache (``NUMBA_CACHE_DIR``, filled by one
untimed estimate per tree first). The trees run alternately, round by round (the order swapped
every round), so that a shared machine's load falls on both alike; CPU time (user + system of
the child, ``wait4``) and wall time, best and median over ``--rounds``. Also: the modules the
default estimate imports (``-X importtime``) and whether ``scipy.signal`` is among them, and
``python -c "import scipy.signal"`` alone on top of numpy (for reference).

    PYTHONPATH=src .venv/bin/python benchmarks/scale/startup_ab.py \
        --trees /tmp/base/src,src --rounds 8
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RUNS = {
    "import vibrospeed": ["-c", "import vibrospeed"],
    "import vibrospeed.cli.app": ["-c", "import vibrospeed.cli.app"],
    "estimate (default)": ["-m", "vibrospeed", "estimate", "{csv}", "-o", "{out}"],
    "estimate -m grid": ["-m", "vibrospeed", "estimate", "{csv}", "-o", "{out}", "-m", "grid"],
}


def _run(args: list[str], env: dict) -> tuple[float, float, bool]:
    """(CPU s, wall s, ok) of one child."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=env)
    _, status, ru = os.wait4(proc.pid, 0)
    return (ru.ru_utime + ru.ru_stime, time.perf_counter() - t0,
            os.waitstatus_to_exitcode(status) == 0)


def _imports(args: list[str], env: dict) -> tuple[int, bool]:
    """Modules imported by the child (``-X importtime`` lines) and whether scipy.signal is."""
    res = subprocess.run([sys.executable, "-X", "importtime", *args], capture_output=True,
                         text=True, env=env)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("import time:")][1:]
    names = {ln.split("|")[-1].strip() for ln in lines}
    return len(lines), any(n == "scipy.signal" or n.startswith("scipy.signal.") for n in names)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trees", required=True, help="comma-separated src directories")
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--duration", type=float, default=10.0, help="s of simulated drive")
    a = ap.parse_args()
    trees = [str(Path(t).resolve()) for t in a.trees.split(",")]
    tmp = Path(tempfile.mkdtemp())
    csv = tmp / "short.csv"
    env0 = dict(os.environ, PYTHONPATH=trees[0])
    subprocess.run([sys.executable, "-c", "import sys; from vibrospeed import io, sim; "
                    f"io.write(sim.simulate('car', seed=1, duration={a.duration}), sys.argv[1])",
                    str(csv)], check=True, env=env0)
    envs = []
    for i, t in enumerate(trees):
        env = dict(os.environ, PYTHONPATH=t, NUMBA_CACHE_DIR=str(tmp / f"numba{i}"))
        cpu, wall, ok = _run(["-m", "vibrospeed", "estimate", str(csv), "-o",
                              str(tmp / "est.csv")], env)
        print(f"tree {i} ({t}): estimate, empty numba cache: {cpu:.2f} CPU s, {wall:.2f} s wall"
              f"{'' if ok else ' (failed)'}", flush=True)
        _run(["-m", "vibrospeed", "estimate", str(csv), "-o", str(tmp / "est.csv"), "-m",
              "grid"], env)
        envs.append(env)
    res: dict[tuple[str, int], list[tuple[float, float]]] = {}
    for r in range(a.rounds):
        order = list(range(len(trees)))[:: 1 if r % 2 == 0 else -1]
        for label, args in RUNS.items():
            args = [s.format(csv=csv, out=tmp / "est.csv") for s in args]
            for i in order:
                cpu, wall, ok = _run(args, envs[i])
                if not ok:
                    print(f"{label} failed in tree {i}", file=sys.stderr)
                res.setdefault((label, i), []).append((cpu, wall))
        print(f"round {r + 1}/{a.rounds} done", flush=True)
    head = " | ".join(f"tree {i} best / median" for i in range(len(trees)))
    print(f"\n| run, CPU s (wall s) | {head} |")
    print("|---|" + "---|" * len(trees))
    for label in RUNS:
        cells = []
        for i in range(len(trees)):
            cpu = [c for c, _ in res[(label, i)]]
            wall = [w for _, w in res[(label, i)]]
            cells.append(f"{min(cpu):.2f} / {statistics.median(cpu):.2f} "
                         f"({min(wall):.2f} / {statistics.median(wall):.2f})")
        print(f"| {label} | " + " | ".join(cells) + " |")
    est = [s.format(csv=csv, out=tmp / "est.csv") for s in RUNS["estimate (default)"]]
    for i, env in enumerate(envs):
        n, sig = _imports(est, env)
        print(f"tree {i}: the default estimate imports {n} modules; scipy.signal: {sig}")
    sig = [_run(["-c", "import numpy, scipy.signal"], env0)[0] for _ in range(a.rounds)]
    base = [_run(["-c", "import numpy, scipy"], env0)[0] for _ in range(a.rounds)]
    print(f"import numpy, scipy.signal: best {min(sig):.2f} CPU s; import numpy, scipy: best "
          f"{min(base):.2f} CPU s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
