"""Where a batch's time goes (issue #34): B worlds of one composition flown as one batch, each
phase of the engine's tick timed (wall time, one process), and building the worlds.

    python benchmarks/speed/batch_phases.py [--worlds 64] [overrides ...]   # e.g. scenario=swap

Phases: ``build`` (``api.build`` of every world), ``perceived`` (events and sensing, world by
world), ``formation`` (batched where the formation has ``setpoints_batch``), ``adjust`` (the
avoidance, batched where the method has ``adjust_batch``), ``control``
(the controllers, batched where the model has ``control_batch``), ``physics`` (the dynamics' steps),
``observers`` (``swarmscene_step_end``: the safety monitor, the recorder...), of which ``monitor``,
and ``finish`` (each world's metrics). Printed in seconds and as a share of the flight (the build
as a share of build plus flight). The timers cost about a microsecond a call.
"""

from __future__ import annotations

import argparse
import collections
import time
from collections.abc import Callable
from typing import Any

from swarmscene import api
from swarmscene.core import batch as batch_module
from swarmscene.core import monitors, simulation


def timed(owner: Any, name: str, label: str, spent: collections.Counter) -> None:
    """Wrap ``owner.name`` so that its calls add their wall time to ``spent[label]``."""
    real: Callable[..., Any] = getattr(owner, name)

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return real(*args, **kwargs)
        finally:
            spent[label] += time.perf_counter() - start

    setattr(owner, name, wrapper)


def main() -> None:
    """Fly the batch once to warm up, then again timed; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=64, help="B, the worlds of the batch (seeds 0 ... B - 1)")
    parser.add_argument("overrides", nargs="*", help="the scenario's overrides")
    args = parser.parse_args()
    data = api.compose(args.overrides)
    api.run_batch(data, list(range(min(4, args.worlds))))  # compile and warm
    spent: collections.Counter = collections.Counter()
    for owner, name, label in ((simulation.Simulation, "perceived", "perceived"),
                               (batch_module, "_formation", "formation"), (batch_module, "_adjust", "adjust"),
                               (batch_module, "_control", "control"), (batch_module, "_physics", "physics"),
                               (simulation.Simulation, "observe", "observers"),
                               (monitors.SafetyMonitor, "_observe", "  monitor"),
                               (simulation.Simulation, "finish", "finish")):
        timed(owner, name, label, spent)
    start = time.perf_counter()
    sims = [api.build({**data, "seed": seed}) for seed in range(args.worlds)]
    build = time.perf_counter() - start
    start = time.perf_counter()
    batch_module.BatchSimulation(sims).run()
    flight = time.perf_counter() - start
    print(f"{args.worlds} worlds of {' '.join(args.overrides) or 'the default scenario'}: build {build:.3f} s "
          f"({100 * build / (build + flight):.0f} % of build + flight), flight {flight:.3f} s")
    for label in ("perceived", "formation", "adjust", "control", "physics", "observers", "  monitor", "finish"):
        print(f"  {label:<12}{spent[label]:8.3f} s {100 * spent[label] / flight:5.0f} %")


if __name__ == "__main__":
    main()
