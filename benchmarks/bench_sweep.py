"""Sweep speed-up: the same sweep with Hydra's basic launcher (sequential) and the joblib launcher
on 2 workers (the joblib extra), in fresh processes, wall time measured around the whole command.

    python benchmarks/bench_sweep.py [--seeds 30] [--jobs 2]

The sweep is the thesis' Fig. 5.13 corridor sweep (preset ``+sweep=indoor_corridor``: N = 30,
widths 0.5 ... 0.9 m x ``--seeds`` seeds, ~2 s of computing per job; the default is the full
150-job sweep, about 8 minutes for both launchers). Goal (issue 8): on 2 cores the joblib sweep is
at least 1.8x faster than the sequential one. Both launchers pay a serial part in the main process
that no launcher can spread: the configs composed up front to fail early (Hydra's basic sweeper
composes every job, about 0.1 s each, hydra#1324; swarmscene's sweeper, which the preset selects,
composes one config per distinct set of config-group overrides and validates every distinct value
once, see docs/sweeps.md), the workers' start-up and the summary written at the end. The
time from the command's start to its first job's start is printed. The metrics of both sweeps are also compared (they must be
identical apart from wall-clock figures). The cores each command actually got (CPU time / wall
time) are printed too: on a machine shared with other work the speed-up is bounded by them.
Nothing here is asserted in the test suite.
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TIMING = {"wall_time", "realtime_factor", "step_ms_median"}
GOAL = 1.8


def sweep(directory: Path, seeds: int, launcher: list[str]) -> tuple[float, float, float]:
    """(wall time, CPU time of the command and all its worker processes, time to the first job's
    start), s."""
    args = [
        sys.executable, "-c", "from swarmscene.cli import main; main()", "--multirun",
        "+sweep=indoor_corridor", f"seed=range(0,{seeds})", f"hydra.sweep.dir={directory}", *launcher,
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    epoch, start = time.time(), time.perf_counter()
    subprocess.run(args, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    # A job's .hydra/config.yaml is the first file Hydra writes for it.
    first = min(p.stat().st_mtime for p in directory.glob("*/.hydra/config.yaml")) - epoch
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), first


def table(directory: Path) -> list[dict[str, str]]:
    with open(directory / "summary.csv", newline="") as fh:
        return [{k: v for k, v in row.items() if k not in TIMING} for row in csv.DictReader(fh)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30, help="seeds per width (30: the thesis' sweep)")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        basic, basic_cpu, basic_first = sweep(root / "basic", args.seeds, [])
        joblib, joblib_cpu, joblib_first = sweep(root / "joblib", args.seeds, ["hydra/launcher=joblib", f"hydra.launcher.n_jobs={args.jobs}"])
        same = table(root / "basic") == table(root / "joblib")
        jobs = len(table(root / "basic"))
    speedup = basic / joblib
    print(f"sweep of {jobs} jobs (+sweep=indoor_corridor, 5 widths x {args.seeds} seeds), {os.cpu_count()} cores")
    # CPU / wall = cores the command actually got: well under 1 (basic) or under the worker count
    # (joblib) means other processes were competing for the cores and the speed-up is not meaningful.
    print(f"  basic launcher (sequential): {basic:6.1f} s wall, {basic_cpu / basic:.2f} cores used, "
          f"first job started after {basic_first:.1f} s")
    print(f"  joblib launcher, {args.jobs} workers: {joblib:6.1f} s wall, {joblib_cpu / joblib:.2f} cores used, "
          f"first job started after {joblib_first:.1f} s")
    print(f"  load average at the end: {os.getloadavg()[0]:.2f}")
    print(f"  speed-up {speedup:.2f}x (goal >= {GOAL}x: {'met' if speedup >= GOAL else 'NOT met'}); "
          f"metrics identical: {same}")


if __name__ == "__main__":
    main()
