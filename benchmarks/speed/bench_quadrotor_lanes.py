"""The quadrotor's physics step now against an earlier commit's, side by side (issue #34: the step
as SIMD lanes).

Loads ``methods/quadrotor/kernels.py`` as it was at ``--beside`` (default ead3753, the last scalar
kernel: one agent at a time) from git into a module of its own, beside today's, and calls both
``step_swarm`` on copies of the same random swarm: positions, velocities, attitudes and rates, a
fifth of the agents in velocity mode, TRACK references with jerk and snap (the Taylor
propagation and the flatness feed-forward run), a rotor at half health every 7th agent, and,
with ``--disturbed``, wind with a moment arm and a force per mass. First every side flies
``--steps`` physics steps from the same state, and the states must end equal to the bit (float64)
or within float32's rounding (``--float32`` adds today's step in float32, not compared); then each
side is timed over the same steps, ``--rounds`` rounds in alternation, the best round each, in CPU
time. A physics step is ``--substeps`` internal steps of 1/240 s in one call (1: the engine's
240 Hz physics, ``clock.physics_step=1/240``; 24: a 10 Hz physics step, the engine's default clock,
where ``max_step`` cuts it into 24); a round is 240 internal steps. Drone-steps per CPU second = N x
internal steps / s. One core, one thread::

    taskset -c 1 python benchmarks/speed/bench_quadrotor_lanes.py [--beside ead3753] [--float32]
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from swarmscene.methods.quadrotor import kernels
from swarmscene.methods.quadrotor.model import AIRFRAMES
from swarmscene.plugin import build_context
from swarmscene.plugins.dynamics.quadrotor import Quadrotor

ROOT = Path(__file__).resolve().parents[2]


def kernels_at(commit: str, folder: str):
    """``methods/quadrotor/kernels.py`` at ``commit``, imported as a module of its own (its numba
    cache in ``folder``)."""
    source = subprocess.run(["git", "-C", str(ROOT), "show", f"{commit}:methods/quadrotor/kernels.py"],
                            capture_output=True, text=True, check=True).stdout
    path = Path(folder) / f"kernels_{commit}.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return module


def constants(dtype: str) -> dict:
    """The kernel constants a default ``quadrotor`` (the crazyflie) built with ``dtype`` hands its
    step (``Quadrotor._constants``: the gains, limits, mixers and drag in the step's precision)."""
    return Quadrotor(Quadrotor.Params(dtype=dtype), build_context(1))._constants


def swarm(n: int, disturbed: bool, seed: int = 0) -> tuple[list[np.ndarray], dict]:
    """A random swarm's state (pos, vel, quat, omega, rotor_speed) and its held inputs."""
    rng = np.random.default_rng(seed)
    yaw = rng.uniform(-1.0, 1.0, n)
    quat = np.column_stack([np.cos(yaw / 2), np.zeros(n), np.zeros(n), np.sin(yaw / 2)])
    state = [rng.normal(size=(n, 3)), 0.3 * rng.normal(size=(n, 3)), quat, 0.1 * rng.normal(size=(n, 3)),
             np.full((n, 4), AIRFRAMES["crazyflie"].hover_rotor_speed)]
    gain = np.ones((n, 4))
    gain[::7, 1] = math.sqrt(0.5)
    held = dict(zip(("p_ref", "v_ref", "a_ref", "dv", "da", "dj", "ds"),
                    (scale * rng.normal(size=(n, 3)) for scale in (1.0, 0.3, 0.3, 0.3, 0.3, 0.1, 0.1)), strict=True))
    held.update(heading=np.column_stack([-np.sin(yaw), np.cos(yaw), np.zeros(n)]),
                position_mask=rng.uniform(size=n) > 0.2, omega_d=0.1 * rng.normal(size=(n, 3)),
                alpha_d=0.1 * rng.normal(size=(n, 3)), rotor_gain=gain, wind=rng.normal(size=(n, 3)),
                has_wind=disturbed, force=0.1 * rng.normal(size=(n, 3)), has_force=disturbed)
    return state, held


def stepper(module, held: dict, const: dict, substeps: int):
    """One physics step of ``substeps`` internal steps of 1/240 s by ``module.step_swarm``."""
    def step(state: list[np.ndarray]) -> None:
        module.step_swarm(*state, held["p_ref"], held["v_ref"], held["a_ref"], held["dv"], held["da"], held["dj"],
                          held["ds"], held["heading"], held["position_mask"], held["omega_d"], held["alpha_d"],
                          True, 0.0, 1.0 / 240.0, substeps, rotor_gain=held["rotor_gain"],
                          wind=held["wind"], has_wind=held["has_wind"], arm=type(const["mass"])(0.01),
                          force=held["force"], has_force=held["has_force"], **const)
    return step


def main() -> None:
    """Both steps side by side at every size and sub-step count, printed as a table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--beside", default="ead3753", help="the commit whose kernel is compared (ead3753)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[16, 100, 1000, 4096])
    parser.add_argument("--substeps", type=int, nargs="+", default=[1, 24])
    parser.add_argument("--steps", type=int, default=240, help="internal (240 Hz) steps per round (240)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--disturbed", action="store_true", help="wind with a moment arm, and a force")
    parser.add_argument("--float32", action="store_true", help="also today's step with dynamics.dtype=float32")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        before = kernels_at(args.beside, folder)
        sides = {args.beside: (before, "float64"), "now": (kernels, "float64")}
        if args.float32:
            sides["now float32"] = (kernels, "float32")
        print(f"drone-steps per CPU second, best of {args.rounds} alternated rounds of {args.steps} internal steps"
              f"{', wind and force' if args.disturbed else ''}")
        print(f"{'N':>6}{'sub-steps':>10}" + "".join(f"{name:>16}" for name in sides) + f"{'ratio':>8}")
        for n in args.sizes:
            for substeps in args.substeps:
                calls = max(1, args.steps // substeps)
                state, held = swarm(n, args.disturbed)
                steps = {name: stepper(module, held, constants(dtype), substeps)
                         for name, (module, dtype) in sides.items()}
                flown = {name: [a.copy() for a in state] for name in sides}
                for name, step in steps.items():
                    for _ in range(calls):
                        step(flown[name])
                assert all(np.array_equal(a, b) for a, b in zip(flown[args.beside], flown["now"], strict=True)), \
                    "the step changed the bits"
                best = dict.fromkeys(sides, np.inf)
                for _ in range(args.rounds):
                    for name, step in steps.items():
                        start = time.process_time()
                        for _ in range(calls):
                            step(flown[name])
                        best[name] = min(best[name], time.process_time() - start)
                rates = {name: n * calls * substeps / seconds for name, seconds in best.items()}
                print(f"{n:>6}{substeps:>10}" + "".join(f"{rate:>16.3g}" for rate in rates.values())
                      + f"{rates['now'] / rates[args.beside]:>8.2f}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
