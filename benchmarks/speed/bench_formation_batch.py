"""A batch's whole tick with the formation planned world by world and as one batch (issue #34).

    taskset -c 1 python benchmarks/speed/bench_formation_batch.py [--grid 256x1 1024x1 64x16] [--rounds 5]

B worlds x N quadrotors of the default scenario with ``avoidance=none`` (``static_shape``, the
safety monitor and the recorder on), stepped by ``lockstep`` (the engine's tick of a batch,
core/batch.py) on one core. Two copies of the same worlds, alternating in rounds of 10 ticks
(the order flipped every round), CPU time: one with ``static_shape``'s and ``none``'s batched
forms as shipped (the formation's ``SetpointBatch`` reaches the quadrotor's ``control_batch``
whole), one with those two batched forms taken away for the round (each world's ``setpoints`` and
``adjust``, the records stacked by the controller), which is how the engine flew these worlds
before. Printed: milliseconds per tick (median of the rounds) and their ratio. The two copies end
in the same bits (checked).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core (before numpy and numba are imported)

import numpy as np  # noqa: E402

from swarmscene import api  # noqa: E402
from swarmscene.core.batch import lockstep  # noqa: E402
from swarmscene.core.plugin import Avoidance, Formation  # noqa: E402
from swarmscene.core.simulation import Simulation  # noqa: E402
from swarmscene.core.state import WorldBatch  # noqa: E402
from swarmscene.plugins.avoidance.none import NoAvoidance  # noqa: E402
from swarmscene.plugins.formation.static_shape import StaticShape  # noqa: E402

TICKS = 10
"""Ticks per timed round."""
BATCHED = {StaticShape: ("setpoints_batch", vars(StaticShape)["setpoints_batch"]),
           NoAvoidance: ("adjust_batch", vars(NoAvoidance)["adjust_batch"])}
"""The two batched forms the per-world side takes away, as shipped."""
DEFAULTS = {StaticShape: vars(Formation)["setpoints_batch"], NoAvoidance: vars(Avoidance)["adjust_batch"]}
"""What the per-world side puts in their place: the defaults, which return ``NotImplemented``."""


def worlds(b: int, n: int) -> tuple[list[Simulation], WorldBatch]:
    """B worlds (seeds 0 ... B - 1) of N quadrotors, started, and their batch."""
    data = api.compose(["dynamics=quadrotor", "avoidance=none", f"swarm.n={n}", "clock.duration=1000",
                        "output.summary=false"])
    sims = [api.build({**data, "seed": seed}) for seed in range(b)]
    for sim in sims:
        sim.hook.swarmscene_run_start(sim=sim.view)
    return sims, WorldBatch([sim.world for sim in sims])


def batched(on: bool) -> None:
    """Give ``static_shape`` and ``none`` their batched forms, or the defaults."""
    for cls, (name, form) in BATCHED.items():
        setattr(cls, name, form if on else DEFAULTS[cls])


def compare(b: int, n: int, rounds: int) -> tuple[float, float]:
    """Milliseconds per tick (median of the rounds), world by world and as one batch."""
    sides = {False: worlds(b, n), True: worlds(b, n)}
    spent: dict[bool, list[float]] = {False: [], True: []}
    try:
        for side, (sims, batch) in sides.items():  # compile and warm
            batched(side)
            lockstep(sims, batch)
        for r in range(rounds):
            for side in ((False, True) if r % 2 == 0 else (True, False)):
                batched(side)
                start = time.process_time()
                for _ in range(TICKS):
                    lockstep(*sides[side])
                spent[side].append((time.process_time() - start) / TICKS * 1e3)
    finally:
        batched(True)
    for one, other in zip(sides[False][0], sides[True][0], strict=True):
        assert np.array_equal(one.world.pos, other.world.pos), "the batched formation left its worlds' bits"
    return statistics.median(spent[False]), statistics.median(spent[True])


def main() -> None:
    """Compare the two sides at each point of the grid; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", nargs="*", default=["256x1", "1024x1", "64x16"], help="B x N points")
    parser.add_argument("--rounds", type=int, default=5, help="alternated rounds of 10 ticks per side (5)")
    args = parser.parse_args()
    print(f"{'B x N':>10}{'world by world':>16}{'one batch':>12}{'ratio':>8}   (ms per tick, CPU, one core)")
    for point in args.grid:
        b, n = (int(v) for v in point.split("x"))
        alone, together = compare(b, n, args.rounds)
        print(f"{f'{b} x {n}':>10}{alone:>16.2f}{together:>12.2f}{alone / together:>8.2f}", flush=True)


if __name__ == "__main__":
    main()
