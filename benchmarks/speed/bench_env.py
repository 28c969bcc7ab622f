"""Environment steps per second of swarmscene.env at N = 10, 100, 1,000 agents.

    python benchmarks/speed/bench_env.py                  # both environments, N = 10, 100, 1,000
    python benchmarks/speed/bench_env.py 100 --steps 300  # chosen sizes and steps
    python benchmarks/speed/bench_env.py --json parallel 100 200   # one measurement, as JSON (for peers)

The case: ``swarm=grid`` (agents 2 m apart), ``environment=open``, ``formation=static_shape`` with
``shape=grid`` (the task: each agent's slot, observed as its reference), the default dynamics
(double integrator under the thesis controllers), ``avoidance=policy`` driven by the environment
(k = 4 neighbours within ``comm.range`` = 20 m), the safety monitor on every tick, no trajectory.
Actions are uniform random in [-1, 1]^3, drawn before the clock starts. ``parallel`` is the
PettingZoo ParallelEnv (dicts of N agents in and out), ``gym`` the Gymnasium env for centralised
control (arrays). Each measurement runs in a fresh process pinned to one core (``taskset -c 0``
where available, one BLAS thread), timed from the first step to the last after ``reset``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

SIZES = [10, 100, 1_000]


def overrides(n: int, steps: int) -> list[str]:
    """The overrides of a grid of ``n`` agents on the open map that lasts ``steps`` environment steps."""
    return ["swarm=grid", f"swarm.n={n}", "environment=open", "formation=static_shape",
            "formation.shape=grid", f"clock.duration={(steps + 1) * 0.1:.1f}"]


WARM = 5
"""untimed steps after reset: the first ticks load the compiled kernels (numba) once per process"""


def measure(kind: str, n: int, steps: int) -> dict:
    """Wall time of ``steps`` environment steps of ``kind`` at ``n`` agents (after reset and
    ``WARM`` untimed steps)."""
    import numpy as np

    from swarmscene.env import make_env, make_gym_env

    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.0, 1.0, size=(WARM + steps, n, 3)).astype(np.float32)
    if kind == "parallel":
        env = make_env(overrides(n, WARM + steps))
        env.reset(seed=0)
        names = list(env.possible_agents)
        batches = [dict(zip(names, a, strict=True)) for a in actions]
        step = env.step
    else:
        env = make_gym_env(overrides(n, WARM + steps))
        env.reset(seed=0)
        batches = list(actions)
        step = env.step
    for batch in batches[:WARM]:
        step(batch)
    t0 = time.perf_counter()
    for batch in batches[WARM:]:
        step(batch)
    wall = time.perf_counter() - t0
    return {"kind": kind, "n": n, "steps": steps, "wall": wall, "steps_per_s": steps / wall}


def pinned(cmd: list[str]) -> list[str]:
    """``cmd`` pinned to core 0 with taskset, where taskset is installed."""
    has_taskset = subprocess.run(["which", "taskset"], capture_output=True).returncode == 0
    return ["taskset", "-c", "0", *cmd] if has_taskset else cmd


ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def run_child(kind: str, n: int, steps: int) -> dict:
    """One measurement in a fresh pinned process."""
    out = subprocess.run(
        pinned([sys.executable, __file__, "--json", kind, str(n), str(steps)]),
        check=True, capture_output=True, text=True,
        env={**os.environ, **ONE_THREAD, "PYTHONWARNINGS": "ignore"},
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def default_steps(n: int) -> int:
    """Steps per run for ``n`` agents: fewer for larger swarms, so each size takes a similar time."""
    return 500 if n <= 10 else 200 if n <= 100 else 50


def main() -> None:
    """Print the best steps/s of ParallelEnv and Gymnasium per size (or one ``--json`` measurement)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="*", type=int, default=SIZES)
    parser.add_argument("--steps", type=int, default=0, help="steps per run (default: by N)")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; the fastest counts")
    parser.add_argument("--json", nargs=3, metavar=("KIND", "N", "STEPS"), help="one measurement, as JSON")
    args = parser.parse_args()
    if args.json:
        kind, n, steps = args.json
        print(json.dumps(measure(kind, int(n), int(steps))))
        return
    print(f"{'N':>6} {'steps':>6} {'ParallelEnv steps/s':>20} {'Gymnasium steps/s':>18}")
    for n in args.n:
        steps = args.steps or default_steps(n)
        best = {kind: max(run_child(kind, n, steps)["steps_per_s"] for _ in range(args.repeat))
                for kind in ("parallel", "gym")}
        print(f"{n:6d} {steps:6d} {best['parallel']:20.1f} {best['gym']:18.1f}", flush=True)


if __name__ == "__main__":
    main()
