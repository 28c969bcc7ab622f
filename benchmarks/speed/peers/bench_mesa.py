"""Side by side: Mesa's BoidFlockers against swarmscene's ``reynolds_flocking``, same N, same start.

    python benchmarks/speed/peers/bench_mesa.py              # N = 100 and N = 1,000
    python benchmarks/speed/peers/bench_mesa.py 100 300      # N = 100 and 300 (steps: --steps 200)

Mesa runs in its own virtual environment, ``benchmarks/speed/peers/.venv-mesa`` (created on first use
with ``pip install "mesa>=3.1,<4" networkx`` from PyPI; git ignores it), swarmscene in the interpreter
running this script. Both models get Mesa's default parameters (100 x 100 torus, speed 1 per step,
vision 10, separation 2, cohere 0.03, separate 0.015, match 0.05) and the same initial positions and
headings (drawn here, written into both models after they are built), then run the same number of
steps, each timed per step (the first ``WARM`` = 3 left out) in a fresh process pinned to one core
(``taskset -c 0`` when available; ``peerlib``); the two alternate ``--repeat`` times (default 3) and
the fastest run of each counts (the machine is shared: the fastest run is the least disturbed one).
One Mesa step is one swarmscene guidance tick of 1 s (``params_from_mesa``).

What differs, on purpose: Mesa moves its boids one at a time in random order, each seeing the ones
already moved (``shuffle_do``); swarmscene moves all boids at once from one snapshot; and swarmscene
also runs its safety monitor (min separation, connectivity) every tick, which Mesa does not have.
The final polarization |mean unit heading| of each is printed to show both flocks did the same work.
Nothing from Mesa is copied here: the Mesa side imports ``mesa.examples.basic.boid_flockers``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import peerlib
from peerlib import child_json, ensure_venv

WARM = 3
"""steps left out of the rate"""
MESA_REQUIREMENTS = ["mesa>=3.1,<4", "networkx"]  # mesa.examples imports networkx
MESA = dict(width=100.0, height=100.0, speed=1.0, vision=10.0, separation=2.0, cohere=0.03,
            separate=0.015, match=0.05)

MESA_CHILD = r"""
import json, sys, time
import numpy as np
import mesa
from mesa.examples.basic.boid_flockers.model import BoidFlockers
start = np.load(sys.argv[1]); steps = int(sys.argv[2]); params = json.loads(sys.argv[3])
n = len(start["pos"])
model = BoidFlockers(population_size=n, seed=0, **params)
for agent, p, d in zip(model.agents, start["pos"], start["dir"]):
    agent.position = p.copy()
    agent.direction = d.copy()
seconds = []
t0 = time.perf_counter()
for _ in range(steps):
    t = time.perf_counter()
    model.step()
    seconds.append(time.perf_counter() - t)
wall = time.perf_counter() - t0
d = np.array([a.direction for a in model.agents])
u = d / np.linalg.norm(d, axis=1, keepdims=True)
print(json.dumps({"wall": wall, "step_seconds": seconds, "polarization": float(np.linalg.norm(u.mean(axis=0))),
                  "version": mesa.__version__}))
"""

SWARMSCENE_CHILD = r"""
import json, sys, time, warnings
import numpy as np
from swarmscene import api
start = np.load(sys.argv[1]); steps = int(sys.argv[2]); params = json.loads(sys.argv[3])
n = len(start["pos"])
data = api.compose(["scenario=flocking", f"swarm.n={n}", f"clock.duration={steps}",
                    "output.trajectory=false", "output.summary=false"])
data["swarm"]["start"] = {"layout": "explicit", "positions": np.column_stack(
    [start["pos"], np.full(n, 2.0)]).tolist()}
data["safety"]["start_overlap"] = "warn"  # Mesa's start is uniform random: some boids start close
data["comm"]["range"] = params["vision"]
from swarmscene.plugins.formation.reynolds_flocking import params_from_mesa
data["formation"].update(params_from_mesa(**params, guidance_period=1.0).model_dump())
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    sim = api.build(data)
sim.formation.heading = np.column_stack([start["dir"], np.zeros(n)])
t0 = time.perf_counter()
result = sim.run()
wall = time.perf_counter() - t0
assert result.metrics["steps"] == steps
print(json.dumps({"wall": wall, "step_seconds": sim.step_seconds.tolist(),
                  "polarization": result.metrics["flocking.polarization"]}))
"""


def mesa_python() -> Path:
    """The Mesa environment's interpreter, creating the environment on first use."""
    return ensure_venv("mesa", MESA_REQUIREMENTS)


def run_child(python: str | Path, code: str, start: Path, steps: int, params: dict | None = None) -> dict:
    """One run in a fresh process pinned to one core (``peerlib.CORE``), one thread."""
    return child_json([str(python), "-c", code, str(start), str(steps), json.dumps(params or MESA)])


def steady_rate(run: dict, warm: int = WARM) -> float:
    """Steps per second over the steps after the first ``warm`` (lazy imports, compiled kernels
    loaded from their cache on first use)."""
    seconds = run["step_seconds"][warm:]
    return len(seconds) / sum(seconds)


def initial_state(n: int, seed: int) -> dict[str, np.ndarray]:
    """Mesa's own draws: positions uniform in the box, heading components uniform in [-1, 1]."""
    rng = np.random.default_rng(seed)
    return {
        "pos": rng.random((n, 2)) * [MESA["width"], MESA["height"]],
        "dir": rng.uniform(-1.0, 1.0, size=(n, 2)),
    }


def main() -> None:
    """Print Mesa's and swarmscene's steps/s and polarization per size, alternated from the same start."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="*", type=int, default=[100, 1000], help="swarm sizes")
    parser.add_argument("--steps", type=int, default=0, help="steps per run (default: by N)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; the fastest counts")
    args = parser.parse_args()
    peerlib.CORE = 0
    python = mesa_python()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average (1 min) at start: {load:.2f}")
    print(f"{'N':>6} {'steps':>6} {'Mesa steps/s':>13} {'swarmscene steps/s':>19} {'ratio':>7} "
          f"{'polarization Mesa / ours':>26}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.n:
            steps = args.steps or (200 if n <= 300 else 50)
            start = Path(tmp) / f"start_{n}.npz"
            np.savez(start, **initial_state(n, args.seed))
            # Alternate the two so a burst of load on this shared machine hits both alike.
            runs = [(run_child(python, MESA_CHILD, start, steps),
                     run_child(sys.executable, SWARMSCENE_CHILD, start, steps)) for _ in range(args.repeat)]
            mesa = max((m for m, _ in runs), key=steady_rate)
            ours = max((o for _, o in runs), key=steady_rate)
            m_rate, s_rate = steady_rate(mesa), steady_rate(ours)
            print(f"{n:6d} {steps:6d} {m_rate:13.1f} {s_rate:19.1f} {s_rate / m_rate:6.1f}x "
                  f"{mesa['polarization']:12.2f} / {ours['polarization']:.2f}", flush=True)
    print(f"Mesa {mesa['version']}; goal (issue 9): >= 20x at N = 1,000")


if __name__ == "__main__":
    main()
