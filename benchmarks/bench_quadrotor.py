"""Speed of the ``quadrotor`` dynamics: N rigid bodies + SE(3) control at 240 Hz physics.

Drives the plugin exactly as the kernel does (control() once per 0.1 s guidance tick, step() at
1/240 s), every agent flying its own 1 m/s circle in TRACK mode with jerk and snap feed-forward
(so the flatness path runs each tick). Prints, per swarm size: wall time, physics steps per second,
real-time factor (simulated / wall seconds; also per CPU second of this process, which is the
fairer figure on a shared machine), the first tick's time (warm-up; there is no
compilation step) and peak resident memory. Single process, single thread:

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_quadrotor.py [--seconds 10]

Goal (issue 3): >= 5x real time for 100 quadrotors, >= 1x for 1,000.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the goal says (before numpy is imported)

import numpy as np  # noqa: E402

from swarmscene.core.plugin import BuildContext  # noqa: E402
from swarmscene.core.setpoint import Mode, Setpoints  # noqa: E402
from swarmscene.core.state import WorldState  # noqa: E402
from swarmscene.plugins.dynamics.quadrotor import Quadrotor  # noqa: E402

GUIDANCE = 0.1
PHYSICS = 1.0 / 240.0


def circles(n: int, t: float, centres: np.ndarray, phase: np.ndarray) -> Setpoints:
    """Each agent on its own 1 m radius circle at 1 m/s (flat outputs up to snap)."""
    a = t + phase
    c, s, z = np.cos(a), np.sin(a), np.zeros(n)
    vec = lambda x, y, zz: np.stack([x, y, zz], axis=1)  # noqa: E731
    return Setpoints(
        mode=np.full(n, Mode.TRACK, dtype=np.int8),
        pos=centres + vec(c, s, z), vel=vec(-s, c, z), acc=vec(-c, -s, z),
        yaw=np.zeros(n), jerk=vec(s, -c, z), snap=vec(c, s, z),
    )


def bench(n: int, seconds: float, airframe: str) -> dict[str, float]:
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * 3.0
    centres = np.column_stack([grid, np.full(n, 2.0)])
    phase = np.zeros(n)
    world = WorldState.at_rest(centres + [1.0, 0.0, 0.0])
    ctx = BuildContext(n=n, guidance_period=GUIDANCE, physics_step=PHYSICS, duration=seconds,
                       separation_limit=0.3, clearance_limit=0.3, comm_range=10.0, environment=None,
                       rng=np.random.default_rng(0), initial=world)
    dyn = Quadrotor(Quadrotor.Params(airframe=airframe), ctx)
    dyn.initialize(world)
    substeps = int(round(GUIDANCE / PHYSICS))
    ticks = int(round(seconds / GUIDANCE))
    start = time.perf_counter()
    cpu_start = time.process_time()
    first = None
    for k in range(ticks):
        dyn.control(world, circles(n, world.t, centres, phase))
        for _ in range(substeps):
            dyn.step(world, PHYSICS)
        world.t = (k + 1) * GUIDANCE
        if first is None:
            first = time.perf_counter() - start
    wall = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
    err = np.linalg.norm(world.pos - circles(n, world.t, centres, phase).pos, axis=1)
    return {
        "n": n, "sim_s": seconds, "wall_s": wall, "steps_per_s": ticks * substeps / wall,
        "rtf": seconds / wall, "cpu_rtf": seconds / cpu, "first_tick_s": first, "max_err_m": float(err.max()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000])
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per size")
    ap.add_argument("--airframe", default="crazyflie")
    args = ap.parse_args()
    print(f"{'N':>6} {'sim s':>6} {'wall s':>8} {'steps/s':>9} {'RTF':>7} {'CPU RTF':>8} {'1st tick s':>10} "
          f"{'max err m':>10}")
    for n in args.sizes:
        r = bench(n, args.seconds, args.airframe)
        print(f"{r['n']:>6} {r['sim_s']:>6.1f} {r['wall_s']:>8.2f} {r['steps_per_s']:>9.0f} "
              f"{r['rtf']:>6.1f}x {r['cpu_rtf']:>7.1f}x {r['first_tick_s']:>10.3f} {r['max_err_m']:>10.4f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"peak resident memory: {peak:.0f} MB; physics {1 / PHYSICS:.0f} Hz, guidance "
          f"{1 / GUIDANCE:.0f} Hz, airframe {args.airframe}")


if __name__ == "__main__":
    main()
