"""The multi-agent vector environment in the batched peers' protocol (issue #34): three columns and memory.

    taskset -c 1 python benchmarks/speed/bench_env_protocol.py            # B = 16, 256 worlds
    taskset -c 1 python benchmarks/speed/bench_env_protocol.py --quick    # a check, not a measurement
    python benchmarks/speed/bench_env_protocol.py --workers 2             # all cores: wall time

The case is the issue's: ``SwarmMultiAgentVectorEnv`` over B worlds of the default scenario with 6
agents a world (``swarm.n=6``, ``dynamics=double_integrator``, the ``policy`` avoidance the
environment drives, the safety monitor on), stepped as one batch. The unit is agent-steps (one
agent, one 10 Hz guidance tick) per CPU second of this process (one core, one BLAS thread):

- **simulation only**: uniform random actions drawn before the clock starts;
- **+ a fixed MLP policy**: the actions of a fixed two-layer perceptron (D -> 64 -> 64 -> 3, tanh,
  NumPy, random weights) on the (B, N, D) observations, inside the timed loop;
- **+ training**: the loop of ``docs/examples/train_cmaes_vector.py`` with one CMA-ES generation
  per episode: ``es.ask()`` (B / 2 candidates of the example's linear policy on normalised
  observations), one episode of ``clock.duration=2`` (20 ticks) of every world, each candidate from
  the same two starts, ``es.tell``; agent-steps of the episodes per CPU second of the whole loop.

Each column is the best of ``--blocks`` blocks (the first block of each also warms the caches).
With ``--workers W`` (W > 1) the environments step their worlds on W worker processes
(``workers=W``, docs/rl.md) and the unit is agent-steps per *wall* second (the workers' CPU is not
this process's): the protocol's "all cores" row.
Memory: the resident set (``VmRSS``) of a fresh process after importing swarmscene and stepping one
world once (the compiled kernels loaded), after building the B worlds' environment and after 20
steps; the table gives the growth over the first, in MiB and per world.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core (before numpy and numba are imported)

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ["swarm.n=6", "dynamics=double_integrator"]
AGENTS = 6
EPISODE = ["clock.duration=2"]
"""The training column's episodes: 20 ticks."""


def mlp(obs: np.ndarray, layers: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """The fixed perceptron's actions (B, N, 3) of observations (B, N, D)."""
    x = obs
    for weights, bias in layers:
        x = np.tanh(x @ weights + bias)
    return x


def clock(workers: int) -> Callable[[], float]:
    """This process's CPU time on one core; the wall time when workers step the worlds."""
    return time.process_time if workers == 1 else time.perf_counter


def simulation(b: int, steps: int, blocks: int, with_mlp: bool, workers: int = 1) -> float:
    """Agent-steps per CPU (or wall) second of the batch, random actions or the fixed MLP's."""
    from swarmscene.env import SwarmMultiAgentVectorEnv

    envs = SwarmMultiAgentVectorEnv(b, CONFIG, workers=workers)
    now = clock(workers)
    rng = np.random.default_rng(0)
    d = envs.single_agent_observation_space.shape[0]
    layers = [(rng.normal(0, 1 / np.sqrt(m), (m, k)), np.zeros(k)) for m, k in ((d, 64), (64, 64), (64, 3))]
    obs, _ = envs.reset(seed=0)
    best = np.inf
    for _ in range(blocks):
        actions = [rng.uniform(-1, 1, envs.action_space.shape) for _ in range(steps)]
        start = now()
        for action in actions:
            obs = envs.step(mlp(obs, layers) if with_mlp else action)[0]
        best = min(best, now() - start)
    envs.close()
    return b * AGENTS * steps / best


def training(b: int, generations: int, blocks: int, workers: int = 1) -> float:
    """Agent-steps per CPU (or wall) second of the CMA-ES example's loop, one generation per 20-tick episode."""
    import cma

    path = ROOT / "docs" / "examples" / "train_cmaes_vector.py"
    spec = importlib.util.spec_from_file_location("train_cmaes_vector", path)
    example = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = example  # its dataclass looks its module up
    spec.loader.exec_module(example)
    envs = example.SwarmMultiAgentVectorEnv(b, [*CONFIG, *EPISODE], workers=workers)
    now = clock(workers)
    policy = example.LinearPolicy(envs.single_agent_observation_space.shape[0])
    es = cma.CMAEvolutionStrategy(np.zeros(policy.size), example.SIGMA0,
                                  {"seed": 1, "verbose": -9, "popsize": b // 2})
    best, ticks = np.inf, 20
    for block in range(blocks):
        start = now()
        for generation in range(generations):
            candidates = np.array(es.ask())
            first = 2 * (block * generations + generation)
            weights = np.repeat(candidates, 2, axis=0)
            flown = example.fly(envs, lambda obs, w=weights: policy.act(w, obs), [first, first + 1] * (b // 2))
            es.tell(list(candidates), (-flown.reshape(-1, 2).mean(axis=1)).tolist())
        best = min(best, now() - start)
    envs.close()
    return b * AGENTS * ticks * generations / best


def resident() -> float:
    """This process's resident set now, MiB (Linux: ``VmRSS`` of /proc/self/status)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status (the memory column needs Linux)")


def memory(b: int) -> dict[str, float]:
    """The resident set (MiB) of this process after the import and one world's first steps (the
    compiled kernels loaded), after building the B worlds, after 20 steps of them."""
    from swarmscene.env import SwarmMultiAgentVectorEnv

    one = SwarmMultiAgentVectorEnv(1, CONFIG)
    one.reset(seed=0)
    one.step(np.zeros(one.action_space.shape))
    one.close()
    marks = {"imported": resident()}
    envs = SwarmMultiAgentVectorEnv(b, CONFIG)
    envs.reset(seed=0)
    marks["built"] = resident()
    zero = np.zeros(envs.action_space.shape)
    for _ in range(20):
        envs.step(zero)
    marks["stepped"] = resident()
    return marks


def main() -> None:
    """The three columns and the memory, for B = 16 and 256, printed as a table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and blocks (a check, not a measurement)")
    parser.add_argument("--blocks", type=int, default=3, help="timed blocks per column (the best counts)")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes of the environments (> 1: wall time, no memory column)")
    parser.add_argument("--memory", type=int, default=None, help=argparse.SUPPRESS)  # the child's side
    args = parser.parse_args()
    if args.memory is not None:
        print(json.dumps(memory(args.memory)))
        return
    sizes, steps, blocks, generations = ((16,), 3, 1, 1) if args.quick else ((16, 256), 20, args.blocks, 2)
    workers = args.workers
    unit = "per CPU second, one core" if workers == 1 else f"per wall second, {workers} workers"
    print(f"agent-steps {unit}; B worlds x 6 agents")
    print(f"{'B':>5}{'simulation':>12}{'+ MLP':>12}{'+ training':>12}{'memory MiB':>12}{'per world':>11}")
    for b in (size for size in sizes if size >= workers):
        sim = simulation(b, steps, blocks, with_mlp=False, workers=workers)
        with_mlp = simulation(b, steps, blocks, with_mlp=True, workers=workers)
        trained = training(b, generations, blocks, workers=workers)
        if workers > 1:  # the workers' resident sets are theirs: the one-process row has the memory
            print(f"{b:>5}{sim:>12.4g}{with_mlp:>12.4g}{trained:>12.4g}{'-':>12}{'-':>11}")
            continue
        child = subprocess.run([sys.executable, __file__, "--memory", str(b)], capture_output=True,
                               text=True, check=True, cwd=ROOT)
        marks = json.loads(child.stdout.strip().splitlines()[-1])
        grown = marks["stepped"] - marks["imported"]
        print(f"{b:>5}{sim:>12.4g}{with_mlp:>12.4g}{trained:>12.4g}{grown:>12.1f}{grown / b:>11.3f}")


if __name__ == "__main__":
    main()
