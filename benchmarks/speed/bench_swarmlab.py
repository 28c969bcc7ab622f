"""The cost of the ``swarmlab`` observer (issue #38): a flocking run at N = 100 with and without it.

The flocking preset (100 boids in Mesa's 100 m torus, 300 ticks) runs alternately without and with
``observers=[swarmlab]`` (SwarmLab's defaults: r = 150 m, max_neig = 10, so each tick lists every
agent's ten nearest and takes lambda_2 of a 100-node graph), ``--rounds`` pairs in one process after
a warm-up pair. Printed: the median wall time of the stepping loop (the ``wall_time`` metric) of
each, their ratio and the observer's share, against the goal (<= 10 % of the run); and the same
for the straightforward transcription of the definition (all pairs, a dense neighbourhood matrix,
every eigenvalue: tests/oracles/swarmlab.py) computed over the same recorded states, per tick.
The observer's own per-tick cost is also timed directly, less exposed to the machine's load than
the difference of two runs' wall times: its samples inside the 'with' runs (the hook wrapped in a
timer), and its sample alone over a recorded run's states (``--rounds`` passes; the tick's k-d tree
built when asked for, as the engine does), each against the run's stepping loop without it.

Two readings of "a run": its stepping loop (above, in one process), and the whole run as a user
starts it, ``swarmscene scenario=flocking`` from the process's start to its exit (the reading of
issue #39's goal for the MCAP bag, "of the run's wall time"): ``--rounds`` pairs of the command
without and with the observer, alternated after a warm-up pair, each pair's ratio of wall and of
CPU time (the children's user + system). ``--no-whole`` leaves the second reading out.

    OMP_NUM_THREADS=1 python benchmarks/speed/bench_swarmlab.py [--rounds 7] [--n 100] [--no-whole]

Not a timed test: numbers depend on the machine; read the ratio of medians, measured in one run.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[2]
GOAL = 0.10


def main() -> None:
    """Time flocking runs with and without the observer, pairs alternately, and the definition transcribed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7, help="pairs of runs (without, with), alternating")
    parser.add_argument("--n", type=int, default=100, help="boids")
    parser.add_argument("--whole", action=argparse.BooleanOptionalAction, default=True,
                        help="also time the whole run, the swarmscene command (default: on)")
    args = parser.parse_args()
    import warnings

    import numpy as np

    from swarmscene import api

    warnings.simplefilter("ignore")
    base = ["scenario=flocking", f"swarm.n={args.n}", "output.summary=false", "output.progress=off"]
    cases = {"without": base, "with": [*base, "observers=[swarmlab]"]}
    for overrides in cases.values():  # warm-up: numba's cache, scipy's submodules
        api.run(overrides)
    walls: dict[str, list[float]] = {k: [] for k in cases}
    inside: list[float] = []  # each 'with' run's time in the observer's measuring calls, s
    # a run's time: its stepping loop's, and the observer's run_end (its last held states), which follows it
    for _ in range(args.rounds):
        for name, overrides in cases.items():
            with _timed_samples() as (spent, after):
                walls[name].append(api.run(overrides).metrics["wall_time"] + sum(after))
            if name == "with":
                inside.append(sum(spent) + sum(after))
    without, with_it = statistics.median(walls["without"]), statistics.median(walls["with"])
    share = with_it / without - 1.0
    load = os.getloadavg()
    print(f"flocking, N = {args.n}, 300 ticks, {args.rounds} alternating pairs; load {load[0]:.2f} {load[1]:.2f}")
    listed = {name: ", ".join(f"{w:.3f}" for w in times) for name, times in walls.items()}
    print(f"  stepping loop without the observer: median {without:.3f} s ({listed['without']})")
    print(f"  with observers=[swarmlab]:          median {with_it:.3f} s ({listed['with']})")
    print(f"  ratio {with_it / without:.3f}: the observer costs {100 * share:.1f} % of the stepping loop "
          f"(goal <= {100 * GOAL:.0f} % read as the loop's: {'met' if share <= GOAL else 'NOT met'})")
    spent_in = statistics.median(inside)
    print(f"  inside the 'with' runs, the observer's samples took median {spent_in:.3f} s, "
          f"{1e6 * spent_in / 301:.0f} us per sample: {100 * spent_in / without:.1f} % of the run without it")
    # the definition, transcribed, over the same states (one run's trajectory)
    sys.path.insert(0, str(ROOT / "tests"))
    from oracles.swarmlab import swarm_performance

    from swarmscene.plugins.observer.swarmlab import SwarmLab

    traj = api.run(base).trajectory
    p = SwarmLab.Params()
    start = time.perf_counter()
    for k in range(len(traj["t"])):
        swarm_performance(np.asarray(traj["pos"][k]), np.asarray(traj["vel"][k]), p.r, p.max_neig, p.r_coll)
    per_tick = (time.perf_counter() - start) / len(traj["t"])
    ticks = len(traj["t"])
    per_sample = _observer_per_tick(traj, args.rounds)
    print(f"  the observer's sample alone over the run's {ticks} recorded states: "
          f"mean {1e6 * per_sample.mean():.0f} us, least {1e6 * per_sample.min():.0f} us per tick "
          f"({args.rounds} passes); against the run's {1e3 * without / ticks:.2f} ms tick: "
          f"{100 * per_sample.mean() * ticks / without:.1f} %")
    print(f"  the definition transcribed (all pairs, dense matrices, every eigenvalue): {1e3 * per_tick:.2f} ms "
          f"per tick, {per_tick * ticks:.3f} s over the run's {ticks} states; the observer: "
          f"{1e3 * (with_it - without) / ticks:.2f} ms per tick")
    lists = _lists_alone(traj, args.rounds)
    print(f"  of the observer's sample, the neighbour lists alone (kernels.neighbour_lists, the definition's "
          f"ten nearest of every agent): {1e6 * lists:.0f} us per tick, {100 * lists * ticks / without:.1f} % of "
          f"the stepping loop")
    if args.whole:
        _whole_runs(args.n, args.rounds, per_tick * ticks)


def _lists_alone(traj: dict, rounds: int) -> float:
    """Seconds per recorded state of the compiled neighbour lists alone (each state's lists cut by
    the previous state's, as in a run): the least over ``rounds`` passes after a warm-up pass."""
    import numpy as np

    from swarmscene.methods.swarmlab import kernels
    from swarmscene.methods.swarmlab.metrics import WarmStart, swarm_metrics
    from swarmscene.plugins.observer.swarmlab import SwarmLab

    p = SwarmLab.Params()
    pos, vel = np.asarray(traj["pos"], dtype=float), np.asarray(traj["vel"], dtype=float)
    n = pos.shape[1]
    coords, row, dist = np.empty((pos.shape[2], n)), np.empty(n), np.empty(n)
    listed, bins = np.empty(n, dtype=np.int64), np.empty(kernels.TIGHTEN_BINS, dtype=np.int64)
    best = np.inf
    for _ in range(rounds + 1):
        state = WarmStart()
        swarm_metrics(pos[0], vel[0], p.r, p.max_neig, p.r_coll, state)  # the first sample's lists
        start = time.perf_counter()
        for k in range(1, len(pos)):
            kernels.neighbour_lists(pos[k], p.r, p.r_coll, state.nbr, state.count, True, coords, row, listed, dist,
                                    bins)
        best = min(best, (time.perf_counter() - start) / (len(pos) - 1))
    return best


def _whole_runs(n: int, rounds: int, definition: float) -> None:
    """The whole run's reading: ``swarmscene scenario=flocking`` without and with the observer,
    ``rounds`` alternated pairs after a warm-up pair, each a fresh process; the median of the
    pairs' ratios (wall, and CPU: the children's user + system). ``definition``: the seconds the
    transcribed definition took over one run's states, set against the whole run without it."""
    import resource
    import shutil
    import subprocess
    import tempfile

    # the console script beside this interpreter (a virtual environment's), else the one on PATH
    beside = Path(sys.executable).with_name("swarmscene")
    command = str(beside) if beside.exists() else shutil.which("swarmscene")
    if command is None:
        sys.exit("bench_swarmlab: no swarmscene command beside this Python or on PATH (pip install -e .); "
                 "--no-whole leaves the whole run out")
    base = [command, "scenario=flocking", f"swarm.n={n}", "output.progress=off"]
    with tempfile.TemporaryDirectory() as tmp:
        def timed(extra: list[str], name: str) -> tuple[float, float]:
            usage = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run([*base, *extra, f"hydra.run.dir={tmp}/{name}"], check=True, stdout=subprocess.DEVNULL)
            wall = time.perf_counter() - start
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            return wall, (after.ru_utime - usage.ru_utime) + (after.ru_stime - usage.ru_stime)

        pairs = [(timed([], "without"), timed(["observers=[swarmlab]"], "with")) for _ in range(rounds + 1)][1:]
    wall = [b[0] / a[0] for a, b in pairs]
    cpu = [b[1] / a[1] for a, b in pairs]
    print(f"  the whole run (`swarmscene scenario=flocking`, process start to exit), {rounds} alternated pairs: "
          f"without median {statistics.median(a[0] for a, _ in pairs):.3f} s wall, "
          f"with {statistics.median(b[0] for _, b in pairs):.3f} s; ratio of each pair, median wall "
          f"{statistics.median(wall):.3f} ({min(wall):.3f}-{max(wall):.3f}), CPU {statistics.median(cpu):.3f} "
          f"({min(cpu):.3f}-{max(cpu):.3f}): the observer costs {100 * (statistics.median(wall) - 1):.1f} % "
          f"of the run's wall time (goal <= {100 * GOAL:.0f} %: "
          f"{'met' if statistics.median(wall) - 1 <= GOAL else 'NOT met'}); the definition transcribed would "
          f"add about {100 * definition / statistics.median(a[0] for a, _ in pairs):.0f} % to it")


@contextmanager
def _timed_samples() -> Iterator[tuple[list[float], list[float]]]:
    """While the block runs: the seconds of each of the observer's samples (``_sample`` at a tick,
    which holds the state and measures the held ones every ``CHUNK``-th), and of its ``run_end``
    hook, which measures the last held states after the stepping loop's ``wall_time`` was taken."""
    from swarmscene.plugins.observer.swarmlab import SwarmLab

    spent: list[float] = []
    after: list[float] = []
    originals = {name: getattr(SwarmLab, name) for name in ("_sample", "swarmscene_run_end")}

    def timed(method, into):  # type: ignore[no-untyped-def]
        @functools.wraps(method)  # with its hookimpl marking
        def call(*args, **kwargs):  # type: ignore[no-untyped-def]
            start = time.perf_counter()
            method(*args, **kwargs)
            into.append(time.perf_counter() - start)
        return call

    SwarmLab._sample = timed(originals["_sample"], spent)  # type: ignore[method-assign]
    SwarmLab.swarmscene_run_end = timed(originals["swarmscene_run_end"], after)  # type: ignore[method-assign]
    try:
        yield spent, after
    finally:
        for name, method in originals.items():
            setattr(SwarmLab, name, method)


def _observer_per_tick(traj: dict, rounds: int):
    """Seconds of the observer per recorded state in each of ``rounds`` passes: its ``_sample`` at
    every state and the measuring of the states still held at the end (``series``), over the states."""
    from functools import cached_property
    from types import SimpleNamespace

    import numpy as np
    from scipy.spatial import cKDTree

    from swarmscene.plugins.observer.swarmlab import SwarmLab

    class Sensing:  # the engine's lazy per-tick tree
        def __init__(self, pos):
            self.pos = pos

        @cached_property
        def tree(self):
            return cKDTree(self.pos)

    pos, vel = np.asarray(traj["pos"], dtype=float), np.asarray(traj["vel"], dtype=float)
    views = [SimpleNamespace(world=SimpleNamespace(pos=pos[k], vel=vel[k], t=float(traj["t"][k])),
                             t=float(traj["t"][k]), step_count=k) for k in range(len(pos))]
    setup = SimpleNamespace(config=SimpleNamespace(observers={"swarmlab": SwarmLab.Params()}),
                            environment=SimpleNamespace(obstacles=[]))
    times = np.zeros(rounds + 1)
    for round_ in range(rounds + 1):  # the first pass warms up (compiles, fills caches) and is dropped
        observer = SwarmLab(setup)
        for view in views:
            view.sensing = Sensing(view.world.pos)
        start = time.perf_counter()
        for view in views:
            observer._sample(view)
        observer.series()
        times[round_] = (time.perf_counter() - start) / len(views)
    return times[1:]


if __name__ == "__main__":
    main()
