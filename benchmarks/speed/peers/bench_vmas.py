"""Side by side: VMAS environment steps against swarmscene.env, N = 10, 100, 1,000 agents, CPU.

    python benchmarks/speed/peers/bench_vmas.py               # N = 10, 100, 1,000
    python benchmarks/speed/peers/bench_vmas.py 100 --steps 300

VMAS runs in its own virtual environment, ``benchmarks/speed/peers/.venv-vmas`` (created on first use
with ``pip install torch==2.13.0 vmas==1.5.2``: on this machine pip takes torch 2.13.0's CPU build
from the local disk; the folder holds a ``.gitignore`` of its own so git ignores it; ``peerlib``), swarmscene in
the interpreter running this script. Every measurement runs in a fresh process pinned to one core
(``taskset -c 0`` where available) with one thread (``torch.set_num_threads(1)``, BLAS threads 1),
and times the same number of steps from the first to the last after a reset; the cases alternate
``--repeat`` times (default 3) and the fastest run of each counts (the machine is shared).
VMAS steps one environment (``num_envs=1``): what a single-environment user of either sees
(VMAS's strength, many environments batched in one tensor step, is not what is measured here).

Cases, each stepped with uniform random actions drawn before the clock starts:
  VMAS simple      VMAS's ``simple`` scenario (MPE: a point agent going to a landmark, no
                   collisions) with N agents instead of one around its landmark (``SimpleN``
                   below: VMAS's own classes, Simple's reset, reward and observation); the cost of
                   VMAS's engine step
  VMAS navigation  VMAS's ``navigation`` scenario with ``n_agents=N`` (agent collisions, 12 lidar
                   rays per agent, goals), spawning in a square of side sqrt(N) m (its default 2 m
                   square cannot place 40 agents: the spawning loop never ends); defaults otherwise
  ours ParallelEnv swarmscene.env ``make_env`` on benchmarks/speed/bench_env.py's case (grid of agents
                   flying their grid slots in the open, double integrator, k = 4 neighbours observed
                   within 20 m, the safety monitor every tick)
  ours Gymnasium   the same through ``make_gym_env`` (one centralised agent, arrays)
What differs, on purpose: VMAS is 2-D with force-based physics in torch; swarmscene is 3-D with
the thesis' digital controllers and its safety monitor (min separation, connectivity) on every tick.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import peerlib
from peerlib import ROOT, child_json, ensure_venv

VMAS_REQUIREMENTS = ["torch==2.13.0", "vmas==1.5.2"]
NAMES = {"simple": "VMAS simple", "navigation": "VMAS navigation", "parallel": "ours ParallelEnv",
         "gym": "ours Gymnasium"}

VMAS_CHILD = r"""
import json, sys, time
import torch
torch.set_num_threads(1)
import vmas
from vmas.simulator.core import Agent, Landmark, World
from vmas.scenarios.mpe.simple import Scenario as Simple

class SimpleN(Simple):
    # VMAS's simple scenario with n agents instead of one, around its one landmark; reset,
    # reward (-|p - landmark|^2) and observation (velocity, landmark offset) are Simple's own.
    def make_world(self, batch_dim, device, n_agents=1):
        world = World(batch_dim, device)
        for i in range(n_agents):
            world.add_agent(Agent(name=f"agent_{i}", collide=False))
        world.add_landmark(Landmark(name="landmark 0", collide=False))
        return world

case, n, steps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
if case == "simple":
    env = vmas.make_env(SimpleN(), num_envs=1, device="cpu", continuous_actions=True, seed=0, n_agents=n)
else:  # agents and goals spawn in a square of side sqrt(N) m (the default 2 m square fits ~30)
    half = max(1.0, 0.5 * n ** 0.5)
    env = vmas.make_env("navigation", num_envs=1, device="cpu", continuous_actions=True, seed=0, n_agents=n,
                        world_spawning_x=half, world_spawning_y=half)
env.reset()
gen = torch.Generator().manual_seed(0)
actions = [[torch.rand((1, env.get_agent_action_size(a)), generator=gen) * 2 - 1 for a in env.agents]
           for _ in range(steps)]
t0 = time.perf_counter()
for step_actions in actions:
    env.step(step_actions)
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "steps_per_s": steps / wall, "version": vmas.__version__,
                  "torch": torch.__version__}))
"""


def vmas_python() -> Path:
    """The VMAS environment's interpreter, creating the environment on first use."""
    return ensure_venv("vmas", VMAS_REQUIREMENTS)


def measure(n: int, steps: int, repeat: int, chosen: set[str]) -> tuple[dict[str, float], str]:
    """Best steps/s of each chosen case (keys of ``NAMES``) at ``n`` agents, the cases alternating
    ``repeat`` times, each run a fresh process pinned to one core (``peerlib.CORE``); and VMAS's version."""
    python = vmas_python()
    bench_env = str(ROOT / "benchmarks" / "speed" / "bench_env.py")
    commands = {
        "simple": [str(python), "-c", VMAS_CHILD, "simple", str(n), str(steps)],
        "navigation": [str(python), "-c", VMAS_CHILD, "navigation", str(n), str(steps)],
        "parallel": [sys.executable, bench_env, "--json", "parallel", str(n), str(steps)],
        "gym": [sys.executable, bench_env, "--json", "gym", str(n), str(steps)],
    }
    best: dict[str, float] = {}
    version = "?"
    for _ in range(repeat):  # alternate, so a burst of load hits every case alike
        for key in (k for k in commands if k in chosen):
            result = child_json(commands[key])
            best[key] = max(best.get(key, 0.0), result["steps_per_s"])
            version = result.get("version", version)
    return best, version


def _rate(value: float) -> str:
    """Steps/s with one decimal, or three significant digits below 10 (VMAS at N = 1,000)."""
    return f"{value:.1f}" if not value < 10 else f"{value:.3g}"


def default_steps(n: int) -> int:
    """Steps per run for ``n`` agents: fewer for larger swarms, so each size takes a similar time."""
    return 500 if n <= 10 else 200 if n <= 100 else 50


def main() -> None:
    """Print the best steps/s of each chosen case (VMAS's and swarmscene's environments) per swarm size."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="*", type=int, default=[10, 100, 1000], help="swarm sizes")
    parser.add_argument("--steps", type=int, default=0, help="steps per run (default: by N)")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; the fastest counts")
    parser.add_argument("--cases", default="simple,navigation,parallel,gym",
                        help="comma-separated subset of: simple, navigation, parallel, gym")
    args = parser.parse_args()
    peerlib.CORE = 0
    chosen = set(args.cases.split(","))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average (1 min) at start: {load:.2f}")
    names = list(NAMES.values())
    print(f"{'N':>6} {'steps':>6} " + " ".join(f"{name + ' steps/s':>24}" for name in names))
    vmas_version = "?"
    for n in args.n:
        steps = args.steps or default_steps(n)
        best, vmas_version = measure(n, steps, args.repeat, chosen)
        print(f"{n:6d} {steps:6d} " + " ".join(f"{_rate(best.get(key, float('nan'))):>24}" for key in NAMES),
              flush=True)
    print(f"VMAS {vmas_version}, torch {VMAS_REQUIREMENTS[0].split('==')[1]} (CPU), one thread each")


if __name__ == "__main__":
    main()
