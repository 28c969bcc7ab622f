"""The multi-agent vector environment on worker processes against one process (issue #34's 2-core goal).

    python benchmarks/speed/bench_env_workers.py                 # 256 worlds, workers 1 and 2
    python benchmarks/speed/bench_env_workers.py --quick         # a check, not a measurement

The case is bench_env_protocol.py's "simulation only" column: ``SwarmMultiAgentVectorEnv`` over B
worlds of the default scenario with 6 agents a world (``swarm.n=6``, ``dynamics=double_integrator``,
the ``policy`` avoidance, the safety monitor on), uniform random actions drawn before the clock
starts, episodes ending and restarting as they come. Both environments are built in this process
and stepped in alternating blocks (a worker waits on its pipe while the other side steps), so the
machine's load falls on both alike. The unit is agent-steps per *wall* second (the workers' CPU is
not this process's); each block's pair gives a ratio, and the table gives every pair's.

One BLAS, OpenMP and numba thread a process, so that W workers use W cores.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy and numba are imported

import numpy as np  # noqa: E402

CONFIG = ["swarm.n=6", "dynamics=double_integrator"]
AGENTS = 6


def block(envs, actions: list[np.ndarray]) -> float:
    """Agent-steps per wall second over ``actions``."""
    start = time.perf_counter()
    for action in actions:
        envs.step(action)
    return actions[0].shape[0] * AGENTS * len(actions) / (time.perf_counter() - start)


def main() -> None:
    """Both environments built, warmed and stepped in alternating blocks; the rates and their ratios printed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=256, help="B, the worlds of each environment")
    parser.add_argument("--workers", type=int, default=2, help="the worker processes of the compared side")
    parser.add_argument("--steps", type=int, default=40, help="steps a block")
    parser.add_argument("--blocks", type=int, default=5, help="alternated blocks of each side")
    parser.add_argument("--quick", action="store_true", help="16 worlds, 3 steps, 1 block (a check)")
    args = parser.parse_args()
    if args.quick:
        args.worlds, args.steps, args.blocks = 16, 3, 1
    from swarmscene.env import SwarmMultiAgentVectorEnv

    sides = {w: SwarmMultiAgentVectorEnv(args.worlds, CONFIG, workers=w) for w in (1, args.workers)}
    rng = np.random.default_rng(0)
    for envs in sides.values():
        envs.reset(seed=0)
        envs.step(rng.uniform(-1, 1, envs.action_space.shape))  # compiled and warm
    rates: dict[int, list[float]] = {w: [] for w in sides}
    for k in range(args.blocks):
        actions = [rng.uniform(-1, 1, sides[1].action_space.shape) for _ in range(args.steps)]
        for w in (sides if k % 2 == 0 else reversed(list(sides))):
            rates[w].append(block(sides[w], actions))
    for envs in sides.values():
        envs.close()
    ratios = [b / a for a, b in zip(rates[1], rates[args.workers], strict=True)]
    print(f"{args.worlds} worlds x {AGENTS} agents, agent-steps per wall second, {args.blocks} alternated blocks "
          f"of {args.steps} steps (load {os.getloadavg()[0]:.2f})")
    for w, values in rates.items():
        print(f"  workers={w}: median {statistics.median(values):.3g}  ({', '.join(f'{v:.3g}' for v in values)})")
    print(f"  ratio, block by block: {', '.join(f'{r:.2f}' for r in ratios)}; median {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
