"""Scale: cost per guidance step and memory per agent for N = 100 ... 100,000, safety monitors on.

    python benchmarks/speed/bench_scale.py                 # the table, N = 100 ... 100,000
    python benchmarks/speed/bench_scale.py 10000 100000    # chosen sizes
    python benchmarks/speed/bench_scale.py --recorder      # 100,000 agents recording every frame to disk

The case is ``scenario=flocking`` (Reynolds boids, single integrator, no avoidance) at Mesa's
BoidFlockers density (one boid per 100 m^2: a square box of side 10 sqrt(N) m, boids starting on
a 10 m grid), in a ``bounded`` box so that the flock's neighbours come from the tick's one shared
k-d tree, with ``comm.range`` equal to the vision radius (10 m) so the connectivity check reuses the
same pair list. The safety monitor (min separation, connectivity) runs every tick, as it always does;
the trajectory recorder is off except in ``--recorder``.

Each size runs in a fresh process pinned to one core (``taskset -c 0`` where available, BLAS
threads 1). Reported per size: guidance steps/s over the run and from the median tick ("median": the
typical tick, less disturbed by other load on a shared machine), ms per median tick, agent-steps/s, the mean
number of neighbours within vision at the end (the work per agent grows with it), and memory:
  state B/agent     WorldState arrays (pos, vel, healthy, comm_ok, role) / N (exact, nbytes);
  scratch B/agent   plugin state kept between ticks (flocking heading, dynamics command) / N;
  tick peak B/agent peak of Python-traced allocations during a tick (tracemalloc; numpy arrays,
                    the pair lists and the k-d tree queries' outputs) / N;
  RSS MiB           peak resident set of the process (interpreter and libraries included).
Nothing here is asserted in the test suite; the goals of issue 9 are printed beside the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

SIZES = [100, 300, 1_000, 3_000, 10_000, 30_000, 100_000]
GOALS = {10_000: 50.0, 100_000: 3.0}  # steps/s, issue 9
STEPS = 60

CHILD = r"""
import json, math, resource, sys, time, tracemalloc
import numpy as np
from swarmscene import api
n, steps, record = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "1"
side = 10.0 * math.sqrt(n)
overrides = [
    "scenario=flocking", f"swarm.n={n}", "swarm.start.layout=grid", "swarm.start.spacing=10",
    f"swarm.start.center=[{side / 2},{side / 2},2]", "formation.space=bounded",
    f"formation.box_max=[{side},{side},{side}]", "comm.range=10", f"clock.duration={steps}",
    "output.summary=false",
]
overrides += ["output.trajectory=true", "output.float32=true", "output.trajectory_buffer_mb=64"] if record \
    else ["output.trajectory=false"]
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
sim = api.build(overrides)
start = time.perf_counter()
result = sim.run()
wall = time.perf_counter() - start
m = result.metrics
world = sim.world
state = sum(a.nbytes for a in (world.pos, world.vel, world.healthy, world.comm_ok, world.role))
scratch = sim.formation.heading.nbytes + sim.dynamics.u.nbytes
out = {"n": n, "steps": m["steps"], "wall": wall, "median_ms": m["step_ms_median"],
       "neighbours": m["flocking.mean_neighbours"], "state": state / n, "scratch": scratch / n,
       "min_separation": m["min_separation"],
       "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "rss0": rss0,
       "collisions": m["collisions"]}
if record:
    rec = result.recorder
    out.update(frames=rec.count, buffer_mib=rec.buffer_bytes() / 2**20, streaming=bool(rec.streaming),
               spill_mib=sum(f.path.stat().st_size for f in rec.files.values()) / 2**20)
else:  # a few more ticks under tracemalloc: the peak of what one tick allocates
    sim.total_steps += 3
    sim.step_seconds = np.zeros(sim.total_steps)
    for obs in sim.observers:  # room for three more monitor samples
        if hasattr(obs, "min_separation") and isinstance(obs.min_separation, np.ndarray):
            for key in ("t", "min_separation", "min_clearance", "connected"):
                arr = getattr(obs, key)
                setattr(obs, key, np.concatenate([arr, np.zeros(3, dtype=arr.dtype)]))
    sim.step()
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    for _ in range(2):
        sim.step()
    out["tick_peak"] = (tracemalloc.get_traced_memory()[1] - base) / n
    tracemalloc.stop()
print(json.dumps(out))
"""


def steps_for(n: int) -> int:
    """The same simulated minute for every N: the flock has condensed alike (same neighbours)."""
    return STEPS


def run_case(n: int, steps: int, record: bool = False) -> dict:
    """One size's figures, measured in a fresh child process (pinned to core 0, one thread)."""
    cmd = [sys.executable, "-c", CHILD, str(n), str(steps), "1" if record else "0"]
    if subprocess.run(["which", "taskset"], capture_output=True).returncode == 0:
        cmd = ["taskset", "-c", "0", *cmd]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
    return json.loads(out.strip().splitlines()[-1])


def table(sizes: list[int]) -> None:
    """Print one row per swarm size: step rates, memory per agent and the goal's verdict."""
    print(f"{'N':>7} {'steps':>5} {'steps/s':>8} {'median':>8} {'ms/step':>8} {'agent-steps/s':>13} {'neighbours':>10} "
          f"{'state B/ag':>10} {'scratch B/ag':>12} {'tick peak B/ag':>14} {'RSS MiB':>8}  goal")
    for n in sizes:
        r = run_case(n, steps_for(n))
        rate = r["steps"] / r["wall"]
        typical = 1e3 / r["median_ms"]
        goal = GOALS.get(n)
        verdict = f">= {goal:g} steps/s: {'met' if min(rate, typical) >= goal else 'NOT met'}" if goal else ""
        print(f"{n:7d} {r['steps']:5d} {rate:8.1f} {typical:8.1f} {r['median_ms']:8.2f} {rate * n:13.3g} "
              f"{r['neighbours']:10.1f} {r['state']:10.0f} {r['scratch']:12.0f} {r['tick_peak']:14.0f} "
              f"{r['rss']:8.0f}  {verdict}",
              flush=True)


def recorder_case(n: int = 100_000, steps: int = 200) -> None:
    """Record every frame of a large run: the in-memory buffer stays put, the rest goes to disk."""
    print(f"recorder: N = {n}, {steps} steps, every frame, float32, 64 MiB buffer")
    for s in (steps // 4, steps):
        r = run_case(n, s, record=True)
        print(f"  {r['frames']:5d} frames: streamed={r['streaming']} buffer {r['buffer_mib']:.1f} MiB, "
              f"spilled {r['spill_mib']:.0f} MiB, peak RSS {r['rss']:.0f} MiB, {r['steps'] / r['wall']:.2f} steps/s, "
              f"{r['collisions']} distinct pairs under min_separation held by the monitor")
    frame = n * (3 * 4 + 3 * 4 + 1) / 2**30
    print(f"  100,000 agents x 10,000 frames would spill {frame * 10_001:.1f} GiB with the same buffer")


def main() -> None:
    """Print the load average, then the table of sizes (or the streaming recorder case, ``--recorder``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="*", type=int, default=SIZES)
    parser.add_argument("--recorder", action="store_true", help="the streaming recorder case only")
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average (1 min) at start: {load:.2f}")
    if args.recorder:
        recorder_case()
    else:
        table(args.n)


if __name__ == "__main__":
    main()
