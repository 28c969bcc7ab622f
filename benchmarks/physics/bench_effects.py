"""The cost of the five physics effects of issue #37 at N = 1,000, beside the bare physics step.

1,000 Crazyflies (``quadrotor`` dynamics, the SE(3) controller, physics step 20 ms in internal steps
of 1/240 s) hold a 32 x 32 grid 1 m apart at 2 m over a floor at z = 0; no avoidance, no events.
The tick is timed (``Simulation.step``: sense/communicate, the controller and the physics
sub-steps) without disturbances ("bare") and with all five (``downwash``, ``ground_effect``,
``drag``, ``battery``, ``radio``), in pairs in one process: each round runs ``--ticks`` bare ticks
and right after them ``--ticks`` ticks of the case (the machine's load drifts alike on both), after
a warm-up; a pair's ratio is its case's median tick over its bare median, and the figure is the
median of the pairs' ratios over ``--rounds`` rounds. Also per effect alone.

    OMP_NUM_THREADS=1 python benchmarks/physics/bench_effects.py [--rounds 7] [--ticks 20]

Not a timed test: read the ratio, measured side by side (the goal is <= 1.3).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

EFFECTS = ("downwash", "ground_effect", "drag", "battery", "radio")


def build(effects: tuple[str, ...], n: int):
    """A hovering swarm of ``n`` quadrotors with the named physics effects declared, built."""
    import numpy as np

    from swarmscene import api
    from swarmscene.core.setpoint import Setpoints

    side = int(np.ceil(np.sqrt(n)))
    k = np.arange(n)
    start = np.column_stack([k % side - side / 2, k // side - side / 2, np.full(n, 2.0)]).tolist()
    overrides = ["scenario=default", "environment=open", f"swarm.n={n}", "swarm.leader=null",
                 "swarm.start.layout=explicit",
                 f"swarm.start.positions={start}", "avoidance=none", "dynamics=quadrotor", "events=none",
                 "environment.floor=0", "clock.physics_step=0.02", "clock.guidance_period=0.1",
                 "clock.duration=1000", "output.summary=false", "output.progress=off", "comm.range=5",
                 "safety.separation_limit=0.5"]
    if effects:
        overrides.append(f"disturbances=[{','.join(effects)}]")
    sim = api.build(overrides)
    target = sim.world.pos.copy()
    sim.formation.setpoints = lambda world, sensing: Setpoints.hold(target)
    return sim


def tick_times(sim, ticks: int) -> list[float]:
    """Wall time of each of ``ticks`` guidance ticks of ``sim``, s."""
    out = []
    for _ in range(ticks):
        t0 = time.perf_counter()
        sim.step()
        out.append(time.perf_counter() - t0)
    return out


def main() -> None:
    """Time the bare tick against each effect and all five, pairs alternately, and print the ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--ticks", type=int, default=20)
    args = parser.parse_args()
    cases = {"bare": (), "all five": EFFECTS, **{name: (name,) for name in EFFECTS}}
    sims = {label: build(effects, args.n) for label, effects in cases.items()}
    for sim in sims.values():  # warm-up: compile and fill caches
        tick_times(sim, 3)
    ratios: dict[str, list[float]] = {label: [] for label in cases if label != "bare"}
    medians: dict[str, list[float]] = {label: [] for label in cases}
    for _ in range(args.rounds):  # pairs: bare, then the case, right after each other
        for label in ratios:
            bare = statistics.median(tick_times(sims["bare"], args.ticks))
            case = statistics.median(tick_times(sims[label], args.ticks))
            ratios[label].append(case / bare)
            medians["bare"].append(bare)
            medians[label].append(case)
    print(f"N = {args.n}, {args.rounds} rounds of pairs (bare, case) x {args.ticks} ticks each; median tick (ms) "
          "and the median over rounds of each pair's ratio of medians:")
    print(f"  {'bare':14s} {statistics.median(medians['bare']) * 1e3:8.3f} ms")
    for label in ratios:
        median, ratio = statistics.median(medians[label]), statistics.median(ratios[label])
        print(f"  {label:14s} {median * 1e3:8.3f} ms  x{ratio:.3f}")


if __name__ == "__main__":
    main()
