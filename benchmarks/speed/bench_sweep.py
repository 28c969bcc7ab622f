"""Sweep speed: the main process's cost per job, the workers' fixed cost per job, full paper sweeps,
the speed-up over the cores of the machine it runs on (issue 25's goals), and the batch launcher
beside the pool (issue 34).

    python benchmarks/speed/bench_sweep.py                    # every part below, small sizes (~4 min)
    python benchmarks/speed/bench_sweep.py --part main        # one part: main, fixed, cem, scaling, cold, batch
    python benchmarks/speed/bench_sweep.py --part cem --seeds 1000
    python benchmarks/speed/bench_sweep.py --part cem --rounds 3   # pool and joblib alternated, 3 rounds
    python benchmarks/speed/bench_sweep.py --part fixed --jobs-per-task 1   # job by job (the ratio's baseline)
    python benchmarks/speed/bench_sweep.py --part batch --seeds 1000 --rounds 3   # pool against batch

Every command runs in a fresh process with its wall time measured around it; a job's start is the
time its ``.hydra/overrides.yaml`` appears (the first file a sweep job writes).

- ``main``: the time from the command to its first job's start for grids of 100, 1,000 and 10,000
  seeds (the command is ended once the first job started), and the main process's work per job
  (the grid expanded, checked and recorded), measured in-process. Goal: <= 2 ms per job and the
  first job of a 10,000-job grid <= 2 s after the command.
- ``fixed``: jobs of one tick (``scenario=cem_six_vehicle clock.duration=0.01``), one at a time
  (basic launcher): the per-job fixed cost is (wall - the empty command's wall) / jobs; and the
  issue's 200 jobs of 50 ticks on 2 workers of each launcher. Goal: <= 25 ms per job, 200 jobs
  <= 10 s.
- ``cem``: ``--seeds`` (100) seeds of the full ``cem_six_vehicle`` on 2 workers of each launcher,
  the launchers alternated for ``--rounds`` rounds (medians, and the wall-time ratio pair by pair).
  Goal: 100 seeds <= 8 s, 1,000 seeds <= 75 s.
- ``scaling``: the same sweep (``--scaling-jobs`` jobs of ``cem_six_vehicle clock.duration=6``,
  by default 240 per core of the machine) on 1, 2, 4, ... and all cores, for each launcher: speed-up against 1 worker
  and parallel efficiency (speed-up / workers), and the tables compared (identical apart from
  wall-clock metrics). Goal: >= 90 % on 2 cores, >= 80 % at 16.

- ``cold``: 8 full ``cem_six_vehicle`` seeds on 2 workers with an empty numba cache (a fresh node
  that skipped ``swarmscene-compile``): the pool compiles the kernels once, in its fork server;
  joblib's workers each compile them.
- ``batch``: ``--seeds`` seeds of ``swap`` and of the default scenario (full length) on 2 workers of
  the pool launcher and of the batch launcher (``hydra/launcher=batch``, its default ``batch_size``),
  alternated for ``--rounds`` rounds: medians, the pool / batch wall-time ratio pair by pair, and
  whether the two tables are identical apart from wall-clock metrics. Goal (issue 34): 1,000 seeds of
  each, batch >= 5x faster than pool. ``--launchers`` is not read here (always pool and batch).

The launchers (``--launchers``, default ``pool,joblib``): ``pool``, swarmscene's launcher of warm
workers (``hydra/launcher=pool``), and ``joblib``, Hydra's. The CPU time counts the command and
every process it started, the pool's fork server included (this process adopts their orphans).
The cores each command got (CPU time / wall time) and the load average are printed: on a machine
shared with other work the figures are bounded by them. Nothing here is asserted in the test suite.
"""

from __future__ import annotations

import argparse
import csv
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
TIMING = {"wall_time", "realtime_factor", "step_ms_median", "cem.step_ms_median"}
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
ENV.pop("HYDRA_FULL_ERROR", None)


def launcher(name: str, workers: int) -> list[str]:
    """The overrides of ``workers`` workers of launcher ``name`` (pool or joblib)."""
    return [f"hydra/launcher={name}", f"hydra.launcher.n_jobs={workers}"]


def adopt_orphans() -> None:
    """Make this process the reaper of its descendants' orphans (Linux), so that the pool
    launcher's fork server and its workers, which outlive the command by a moment and are not its
    waited children, count in :func:`run`'s CPU time."""
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
    except (OSError, AttributeError):  # not Linux: the fork server's CPU is not counted
        pass


def reap() -> None:
    """Wait for every orphan adopted (:func:`adopt_orphans`): their CPU time is then counted."""
    while True:
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return


LAUNCHERS: list[str] = ["pool", "joblib"]
"""The launchers each part measures (``--launchers``)."""
PER_TASK: list[str] = []
"""``hydra/sweeper=swarmscene hydra.sweeper.jobs_per_task=K`` when ``--jobs-per-task`` is given (default: the
sweeper's auto)."""


def run(args: list[str], directory: Path) -> tuple[float, float]:
    """(wall time, CPU time of the command and its workers), s, of ``swarmscene --multirun args``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([*EXE, "--multirun", *args, *PER_TASK, f"hydra.sweep.dir={directory}"], check=True, env=ENV,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    reap()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def first_start(args: list[str], directory: Path, limit: float = 600.0) -> float:
    """Seconds from the command to its first job's start; the command is then ended."""
    epoch = time.time()
    proc = subprocess.Popen([*EXE, "--multirun", *args, *PER_TASK, f"hydra.sweep.dir={directory}"], env=ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    marker = directory / "0" / ".hydra" / "overrides.yaml"
    try:
        while not marker.exists():
            if proc.poll() is not None or time.time() - epoch > limit:
                raise RuntimeError(f"no job started ({' '.join(args)})")
            time.sleep(0.005)
        return marker.stat().st_mtime - epoch
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def main_process_work(jobs: int) -> float:
    """Seconds per job of the sweeper's work in the main process (expand, check, record), in-process."""
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.types import RunMode

    from swarmscene.composition.searchpath import register_search_path
    from swarmscene.sweeps.compose import GroupCachingLoader
    from swarmscene.sweeps.grid import GridCheck, JobCheck, expand
    from swarmscene.sweeps.records import check_grid_owner, record_grid

    register_search_path()
    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"), \
            tempfile.TemporaryDirectory() as tmp:
        loader = GroupCachingLoader(GlobalHydra.instance().config_loader(), command=["bench"])
        master = loader.load_configuration("config", [f"hydra.sweep.dir={tmp}"], RunMode.MULTIRUN)
        start = time.perf_counter()
        grid, job_list = expand({}, ["scenario=cem_six_vehicle", f"seed=range(0,{jobs})"],
                                OverridesParser.create(config_loader=loader))
        check_grid_owner(Path(tmp), grid, job_list)
        GridCheck(JobCheck(loader, master), job_list).check(0, len(job_list))
        record_grid(Path(tmp), grid, job_list)
        return (time.perf_counter() - start) / jobs


def table(directory: Path) -> list[dict[str, str]]:
    """A sweep's summary.csv rows without the wall-clock columns and overrides (to compare across runs)."""
    with open(directory / "summary.csv", newline="") as fh:
        return [{k: v for k, v in row.items() if k not in TIMING and k != "overrides"} for row in csv.DictReader(fh)]


def verdict(ok: bool) -> str:
    """``met`` or ``NOT met``, for the printed goals."""
    return "met" if ok else "NOT met"


def part_main(root: Path) -> None:
    """Print the main process's work per job and the first job's start for grids of 100 to 10,000 seeds."""
    print("main process")
    for jobs in (100, 1_000, 10_000):
        per_job = main_process_work(jobs)
        first = first_start(["scenario=cem_six_vehicle", f"seed=range(0,{jobs})"], root / f"main{jobs}")
        goal = f"; first job <= 2 s: {verdict(first <= 2.0)}" if jobs == 10_000 else ""
        print(f"  {jobs:6d} jobs: {1e3 * per_job:5.2f} ms per job in the main process "
              f"(<= 2 ms: {verdict(per_job <= 2e-3)}), first job started {first:5.2f} s after the command{goal}")


def part_fixed(root: Path) -> None:
    """Print the per-job fixed cost (one-tick jobs, job by job), then 200 jobs of 50 ticks per launcher."""
    print("per-job fixed cost")
    jobs = 100
    empty, empty_cpu = run(["scenario=cem_six_vehicle", "clock.duration=0.01", "seed=0"], root / "empty")
    wall, cpu = run(["scenario=cem_six_vehicle", "clock.duration=0.01", f"seed=range(0,{jobs})"], root / "one_tick")
    fixed = (wall - empty) / (jobs - 1)
    # CPU time per job: what a job costs whatever else the machine runs (wall time is not).
    fixed_cpu = (cpu - empty_cpu) / (jobs - 1)
    print(f"  {jobs} jobs of one tick, basic launcher: {wall:.1f} s (one job: {empty:.1f} s): "
          f"{1e3 * fixed:.0f} ms per job (<= 25 ms: {verdict(fixed <= 0.025)}), {1e3 * fixed_cpu:.0f} ms of CPU "
          f"per job, {cpu / wall:.2f} cores used")
    for name in LAUNCHERS:
        wall, cpu = run(["scenario=cem_six_vehicle", "clock.duration=0.5", "seed=range(0,200)", *launcher(name, 2)],
                        root / f"fifty_{name}")
        print(f"  200 jobs of 50 ticks, {name} 2 workers: {wall:.1f} s (<= 10 s: {verdict(wall <= 10)}), "
              f"{cpu:.1f} s of CPU, {cpu / wall:.2f} cores used")


def part_cem(root: Path, seeds: int, rounds: int) -> None:
    """Print each launcher's median wall time of the full cem_six_vehicle sweep, alternated, and their ratio."""
    goal = 8.0 if seeds <= 100 else 75.0 * seeds / 1000
    print(f"full cem_six_vehicle, {seeds} seeds, 2 workers ({', '.join(LAUNCHERS)} alternated, {rounds} rounds)")
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in LAUNCHERS}
    for i in range(rounds):
        for name in LAUNCHERS:
            times[name].append(run(["scenario=cem_six_vehicle", f"seed=range(0,{seeds})", *launcher(name, 2)],
                                   root / f"cem{seeds}_{name}_{i}"))
    for name, runs in times.items():
        wall, cpu = sorted(runs)[len(runs) // 2]
        print(f"  {name}: median {wall:.1f} s of {[round(w, 1) for w, _ in runs]} (goal <= {goal:g} s: "
              f"{verdict(wall <= goal)}), {cpu:.1f} s of CPU, {cpu / wall:.2f} cores used")
    if len(times) == 2:
        (a, ra), (b, rb) = times.items()
        ratios = sorted(wa / wb for (wa, _), (wb, _) in zip(ra, rb, strict=True))
        print(f"  {a} / {b} wall, pair by pair: median {ratios[len(ratios) // 2]:.2f} "
              f"of {[round(r, 2) for r in ratios]}")


def part_scaling(root: Path, jobs: int) -> None:
    """Print each launcher's speed-up and efficiency from 1 worker to every core, tables compared."""
    cores = os.cpu_count() or 1
    counts = sorted({1, *[2**k for k in range(1, 8) if 2**k < cores], cores})
    args = ["scenario=cem_six_vehicle", "clock.duration=6", f"seed=range(0,{jobs})"]
    for name in LAUNCHERS:
        print(f"scaling: {jobs} jobs of cem_six_vehicle clock.duration=6, {name}, {cores} cores")
        base = None
        reference = None
        for workers in counts:
            wall, cpu = run([*args, *launcher(name, workers)], root / f"scale_{name}{workers}")
            base = base or wall
            rows = table(root / f"scale_{name}{workers}")
            reference = reference or rows
            speedup = base / wall
            print(f"  {workers:3d} workers: {wall:6.1f} s, speed-up {speedup:5.2f}x, efficiency "
                  f"{100 * speedup / workers:5.1f} %, {cpu:.1f} s of CPU, {cpu / wall:.2f} cores used, "
                  f"table identical to 1 worker's: {rows == reference}")


def part_cold(root: Path) -> None:
    """A machine whose numba cache is empty (a fresh node or image without ``swarmscene-compile``):
    8 full ``cem_six_vehicle`` seeds on 2 workers, each launcher with a cache of its own."""
    print("cold numba cache: 8 seeds of cem_six_vehicle, 2 workers")
    for name in LAUNCHERS:
        with tempfile.TemporaryDirectory() as cache:
            ENV["NUMBA_CACHE_DIR"] = cache
            try:
                wall, cpu = run(["scenario=cem_six_vehicle", "seed=range(0,8)", *launcher(name, 2)],
                                root / f"cold_{name}")
            finally:
                ENV.pop("NUMBA_CACHE_DIR")
        print(f"  {name}: {wall:.1f} s, {cpu:.1f} s of CPU (the kernels compiled in each worker, or once)")


def same_runs(a: Path, b: Path, jobs: int) -> bool:
    """Whether every job of two sweep directories has the same metrics (wall-clock ones aside) and
    the same trajectory arrays, bit for bit."""
    from swarmscene.runs.rundir import RunDir

    for job in map(str, range(jobs)):
        left, right = RunDir(a / job), RunDir(b / job)
        if ({k: v for k, v in left.metrics().items() if k not in TIMING}
                != {k: v for k, v in right.metrics().items() if k not in TIMING}):
            return False
        t1, t2 = left.trajectory(), right.trajectory()
        if t1.keys() != t2.keys() or any(t1[k].dtype != t2[k].dtype or t1[k].tobytes() != t2[k].tobytes() for k in t1):
            return False
    return True


BATCH_SCENARIOS = ("swap", "default")
"""The scenarios of the ``batch`` part (issue 34's goal names them)."""


def part_batch(root: Path, seeds: int, rounds: int) -> None:
    """Print, for each of :data:`BATCH_SCENARIOS`, the pool's and the batch launcher's median wall
    time over ``seeds`` seeds on 2 workers (alternated, ``rounds`` rounds), their ratio pair by pair,
    and whether their tables are identical (wall-clock metrics aside)."""
    names = ("pool", "batch")
    for scenario in BATCH_SCENARIOS:
        print(f"{scenario}, {seeds} seeds, 2 workers (pool and batch alternated, {rounds} rounds)")
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in names}
        same = True
        for i in range(rounds):
            order = names if i % 2 == 0 else names[::-1]  # each launcher first in every other round
            for name in order:
                directory = root / f"batch_{scenario}{seeds}_{name}_{i}"
                times[name].append(run([f"scenario={scenario}", f"seed=range(0,{seeds})", *launcher(name, 2)],
                                       directory))
            pool_dir, batch_dir = (root / f"batch_{scenario}{seeds}_{name}_{i}" for name in names)
            same &= table(pool_dir) == table(batch_dir) and same_runs(pool_dir, batch_dir, seeds)
            for directory in (pool_dir, batch_dir):
                shutil.rmtree(directory)
        for name, runs in times.items():
            wall, cpu = sorted(runs)[len(runs) // 2]
            print(f"  {name}: median {wall:.1f} s of {[round(w, 1) for w, _ in runs]}, {cpu:.1f} s of CPU, "
                  f"{cpu / wall:.2f} cores used, {1e3 * wall / seeds:.1f} ms per job")
        ratios = sorted(wp / wb for (wp, _), (wb, _) in zip(times["pool"], times["batch"], strict=True))
        median = ratios[len(ratios) // 2]
        print(f"  pool / batch wall, pair by pair: median {median:.2f} of {[round(r, 2) for r in ratios]} "
              f"(>= 5x: {verdict(median >= 5.0)}); tables identical apart from wall-clock metrics: {same}")


def main() -> None:
    """Run the chosen parts (``--part``) in a temporary directory, then print the load average."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("main", "fixed", "cem", "scaling", "cold", "batch", "all"), default="all")
    parser.add_argument("--seeds", type=int, default=100,
                        help="seeds of the full cem_six_vehicle sweep (cem) and of swap and default (batch)")
    parser.add_argument("--scaling-jobs", type=int, default=None,
                        help="jobs of the scaling sweep (default 240 per core: ~20 s of jobs per core, so the "
                             "command's serial start, ~2 s, stays a small part of it at every worker count)")
    parser.add_argument("--launchers", default="pool,joblib",
                        help="the launchers measured, in turn (pool: swarmscene's warm pool; joblib: Hydra's)")
    parser.add_argument("--rounds", type=int, default=1,
                        help="rounds of the cem and batch parts, the launchers alternated")
    parser.add_argument("--jobs-per-task", default=None,
                        help="hydra.sweeper.jobs_per_task of every sweep (default: the sweeper's, auto); "
                             "1 launches job by job, as before launcher tasks, for a side-by-side ratio")
    args = parser.parse_args()
    LAUNCHERS[:] = args.launchers.split(",")
    adopt_orphans()
    if args.jobs_per_task is not None:
        # In place, as LAUNCHERS above: run() and first_start() read the module's list (``PER_TASK += ...``
        # here made the name local to main, and the flag raised UnboundLocalError).
        PER_TASK[:] = ["hydra/sweeper=swarmscene", f"hydra.sweeper.jobs_per_task={args.jobs_per_task}"]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if args.part in ("main", "all"):
            part_main(root)
        if args.part in ("fixed", "all"):
            part_fixed(root)
        if args.part in ("cem", "all"):
            part_cem(root, args.seeds, args.rounds)
        if args.part in ("cold", "all"):
            part_cold(root)
        if args.part in ("batch", "all"):
            part_batch(root, args.seeds, args.rounds)
        if args.part in ("scaling", "all"):
            part_scaling(root, args.scaling_jobs or 240 * (os.cpu_count() or 1))
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
