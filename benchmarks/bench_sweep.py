"""Sweep speed-up: the same sweep with Hydra's basic launcher (sequential) and the joblib launcher
on 2 workers (the joblib extra), in fresh processes, wall time measured around the whole command.

    python benchmarks/bench_sweep.py [--seeds 4] [--jobs 2]

The sweep is the thesis corridor (scenario indoor_corridor, N = 30, ~3 s of computing per run):
widths 0.7 and 0.8 m x ``--seeds`` seeds. Goal (issue 8): on 2 cores the joblib sweep is at least
1.8x faster than the sequential one. The metrics of both sweeps are also compared (they must be
identical apart from wall-clock figures). Nothing here is asserted in the test suite.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TIMING = {"wall_time", "realtime_factor", "step_ms_median"}
GOAL = 1.8


def sweep(directory: Path, seeds: int, launcher: list[str]) -> float:
    args = [
        sys.executable, "-c", "from swarmscene.cli import main; main()", "--multirun",
        "scenario=indoor_corridor", "environment=indoor_corridor_w070,indoor_corridor_w080",
        f"seed=range(0,{seeds})", f"hydra.sweep.dir={directory}", *launcher,
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    start = time.perf_counter()
    subprocess.run(args, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def table(directory: Path) -> list[dict[str, str]]:
    with open(directory / "summary.csv", newline="") as fh:
        return [{k: v for k, v in row.items() if k not in TIMING} for row in csv.DictReader(fh)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        basic = sweep(root / "basic", args.seeds, [])
        joblib = sweep(root / "joblib", args.seeds, ["hydra/launcher=joblib", f"hydra.launcher.n_jobs={args.jobs}"])
        same = table(root / "basic") == table(root / "joblib")
        jobs = len(table(root / "basic"))
    speedup = basic / joblib
    print(f"sweep of {jobs} jobs (indoor_corridor, 2 widths x {args.seeds} seeds), {os.cpu_count()} cores")
    print(f"  basic launcher (sequential): {basic:6.1f} s")
    print(f"  joblib launcher, {args.jobs} workers: {joblib:6.1f} s")
    print(f"  speed-up {speedup:.2f}x (goal >= {GOAL}x: {'met' if speedup >= GOAL else 'NOT met'}); "
          f"metrics identical: {same}")


if __name__ == "__main__":
    main()
