"""Speed of the ``quadrotor`` dynamics: N rigid bodies + SE(3) control at 240 Hz physics, the
compiled kernels (the plugin) against the numpy step they replaced (tests/oracles/quadrotor.py).

Drives the plugin exactly as the engine does: every agent flies its own 1 m/s circle in TRACK mode
with jerk and snap feed-forward (so the flatness path runs each tick), physics at 1/240 s, and
guidance either at 10 Hz (control() once per 24 steps) or at 240 Hz (control() before every step,
as the whole-engine benchmark runs it). The kernel and the oracle fly the same flight side by side
in one process, alternating tick by tick, and are timed separately in CPU time (process_time:
the machine is shared, and a preempted tick would otherwise be charged to whichever ran). Prints,
per swarm size and guidance rate: drone-steps per CPU second of each, their ratio, the kernel's
real-time factor (simulated / CPU seconds) and the largest kernel - oracle position difference at
the end; then the physics step alone (best of 7 blocks, per CPU second); then, each in a fresh
interpreter, the CPU time of importing the kernels (numba) and of the first control() + step()
with an empty numba cache (compile) and with the cache it wrote (load). Single core, single thread:

    taskset -c 1 python benchmarks/speed/bench_quadrotor.py [--seconds 2] [--sizes 1 100 1000]

Goal (issue 3): >= 5x real time for 100 quadrotors, >= 1x for 1,000.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the goal says (before numpy is imported)

import numpy as np  # noqa: E402

from swarmscene.core.plugin import BuildContext  # noqa: E402
from swarmscene.core.setpoint import Mode, Setpoints  # noqa: E402
from swarmscene.core.state import WorldState  # noqa: E402
from swarmscene.plugins.dynamics.quadrotor import Quadrotor  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from oracles.quadrotor import QuadrotorOracle  # noqa: E402

PHYSICS = 1.0 / 240.0


def circles(n: int, t: float, centres: np.ndarray) -> Setpoints:
    """Each agent on its own 1 m radius circle at 1 m/s (flat outputs up to snap)."""
    c, s, z = np.cos(t), np.sin(t), np.zeros(n)
    vec = lambda x, y, zz: np.stack([x + z, y + z, zz], axis=1)  # noqa: E731
    return Setpoints(
        mode=np.full(n, Mode.TRACK, dtype=np.int8),
        pos=centres + vec(c, s, z), vel=vec(-s, c, z), acc=vec(-c, -s, z),
        yaw=np.zeros(n), jerk=vec(s, -c, z), snap=vec(c, s, z),
    )


def build(cls, n: int, guidance: float):
    """A ``cls`` dynamics for ``n`` quadrotors on a 3 m grid, initialised: (dynamics, world, circle centres)."""
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * 3.0
    centres = np.column_stack([grid, np.full(n, 2.0)])
    world = WorldState.at_rest(centres + [1.0, 0.0, 0.0])
    world.vel[:, 1] = 1.0
    ctx = BuildContext(n=n, guidance_period=guidance, physics_step=PHYSICS, duration=1.0,
                       separation_limit=0.3, clearance_limit=0.3, comm_range=10.0, environment=None,
                       rng=np.random.default_rng(0), initial=world)
    dyn = cls(Quadrotor.Params(), ctx)
    dyn.initialize(world)
    return dyn, world, centres


def tick(dyn, world, centres, substeps: int, k: int, guidance: float) -> float:
    """One guidance tick (control + its physics steps); returns its CPU time (the setpoints are
    made before the clock starts: they are the formation's cost, not the dynamics')."""
    sp = circles(world.n, world.t, centres)
    start = time.process_time()
    dyn.control(world, sp)
    for _ in range(substeps):
        dyn.step(world, PHYSICS)
    cpu = time.process_time() - start
    world.t = (k + 1) * guidance
    return cpu


def compare(n: int, seconds: float, guidance: float) -> dict[str, float]:
    """The same flight with the kernel and with the oracle, alternating tick by tick."""
    substeps = int(round(guidance / PHYSICS))
    runs = {"kernel": build(Quadrotor, n, guidance), "oracle": build(QuadrotorOracle, n, guidance)}
    for dyn, world, centres in runs.values():  # warm-up tick (kernels loaded / compiled)
        tick(dyn, world, centres, substeps, 0, guidance)
    cpu = {"kernel": 0.0, "oracle": 0.0}
    ticks = int(round(seconds / guidance))
    for k in range(1, ticks + 1):
        for name, (dyn, world, centres) in runs.items():
            cpu[name] += tick(dyn, world, centres, substeps, k, guidance)
    steps = ticks * substeps
    wk, wo = runs["kernel"][1], runs["oracle"][1]
    err = np.linalg.norm(wk.pos - circles(n, wk.t, runs["kernel"][2]).pos, axis=1)
    return {
        "kernel": n * steps / cpu["kernel"], "oracle": n * steps / cpu["oracle"],
        "ratio": cpu["oracle"] / cpu["kernel"], "rtf": steps * PHYSICS / cpu["kernel"],
        "diff": float(np.abs(wk.pos - wo.pos).max()), "track_err": float(err.max()),
    }


def step_only(n: int, repeats: int = 7) -> dict[str, float]:
    """Physics steps alone (control() once before): best-of-``repeats`` CPU time per step of the
    kernel and the oracle, alternating blocks of steps; returns drone-steps per CPU second."""
    runs = {"kernel": build(Quadrotor, n, 0.1), "oracle": build(QuadrotorOracle, n, 0.1)}
    block = max(5, 20_000 // n)
    best = {}
    for dyn, world, centres in runs.values():
        dyn.control(world, circles(n, 0.0, centres))
        dyn.step(world, PHYSICS)
    for _ in range(repeats):
        for name, (dyn, world, _) in runs.items():
            start = time.process_time()
            for _ in range(block):
                dyn.step(world, PHYSICS)
            best[name] = min(best.get(name, np.inf), (time.process_time() - start) / block)
    return {name: n / t for name, t in best.items()}


_FIRST_CALL = """
import time
t0 = time.process_time()
from swarmscene.methods.quadrotor import kernels
t1 = time.process_time()
import numpy as np
from swarmscene.core.plugin import BuildContext
from swarmscene.core.state import WorldState
from swarmscene.plugins.dynamics.quadrotor import Quadrotor
world = WorldState.at_rest(np.zeros((4, 3)))
ctx = BuildContext(n=4, guidance_period=0.1, physics_step=1 / 240, duration=1.0, separation_limit=0.3,
                   clearance_limit=0.3, comm_range=10.0, environment=None,
                   rng=np.random.default_rng(0), initial=world)
dyn = Quadrotor(Quadrotor.Params(), ctx)
t2 = time.process_time()
dyn.initialize(world)  # first control(): latch_references
dyn.step(world, 1 / 240)  # first step(): step_swarm
t3 = time.process_time()
print(t1 - t0, t3 - t2)
"""


def first_call() -> dict[str, float]:
    """Import time of the kernels module (numba) and the first control() + step() in a fresh
    interpreter, with an empty numba cache (compile) and then with the cache it wrote (load)."""
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "warm"):
            text = subprocess.run([sys.executable, "-c", _FIRST_CALL], env=env, check=True,
                                  capture_output=True, text=True).stdout
            out[f"import_{label}"], out[f"first_{label}"] = map(float, text.split())
    return out


def main() -> None:
    """Print the kernel and oracle rates per size and guidance rate, the step alone, and the first call's cost."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 100, 1000])
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per size and rate")
    args = ap.parse_args()
    print(f"{'N':>6} {'guidance':>8} {'kernel steps/CPU s':>19} {'oracle steps/CPU s':>19} "
          f"{'ratio':>7} {'kernel RTF':>10} {'max |dp| m':>11} {'track err m':>11}")
    for n in args.sizes:
        for guidance in (0.1, PHYSICS):
            r = compare(n, args.seconds, guidance)
            print(f"{n:>6} {1 / guidance:>6.0f}Hz {r['kernel']:>19.3e} {r['oracle']:>19.3e} "
                  f"{r['ratio']:>6.1f}x {r['rtf']:>9.1f}x {r['diff']:>11.1e} {r['track_err']:>11.4f}")
    print(f"{'N':>6} {'step only, best of 7: kernel':>30} {'oracle drone-steps/s':>21} {'ratio':>7}")
    for n in args.sizes:
        r = step_only(n)
        print(f"{n:>6} {r['kernel']:>30.3e} {r['oracle']:>21.3e} {r['kernel'] / r['oracle']:>6.1f}x")
    fc = first_call()
    print(f"first call (fresh interpreter, N = 4, CPU s): import kernels (numba) {fc['import_cold']:.2f}; "
          f"first control + step {fc['first_cold']:.2f} with an empty cache (compile), "
          f"{fc['first_warm']:.2f} with a warm cache (load; import {fc['import_warm']:.2f})")
    print(f"drone-steps per CPU second; physics {1 / PHYSICS:.0f} Hz, airframe crazyflie, "
          f"{args.seconds:g} simulated s per row, kernel and oracle alternating tick by tick")


if __name__ == "__main__":
    main()
