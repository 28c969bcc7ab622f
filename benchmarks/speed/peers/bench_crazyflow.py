"""Quadrotor swarms hovering, physics at 240 Hz: swarmscene's whole engine tick against Crazyflow (JAX, CPU).

    python benchmarks/speed/peers/bench_crazyflow.py            # N = 1, 100, 1,000 and the start-up times
    python benchmarks/speed/peers/bench_crazyflow.py --quick    # fewer steps, one pass
    python benchmarks/speed/peers/bench_crazyflow.py --sizes 100 1000 --rates 10 --avoidance potential orca \
        --steady-only                                           # avoidance on, against Crazyflow with nothing on

Crazyflow runs in its own virtual environment, ``benchmarks/speed/peers/.venv-crazyflow`` (created on
first use with ``pip install crazyflow==0.4.0 "jax[cpu]"`` from PyPI; git ignores it), swarmscene in
the interpreter running this script. Both sides fly N drones from the same points, each holding
its own point under state control, physics at 240 Hz and the position command at 10 Hz (the
engine's default guidance period, T_s = 0.1 s, and Crazyflow stepping 24 physics steps per
command) and at 240 Hz (a command every physics step): the slots of ``static_shape``'s
grid, 2 m apart at 2 m altitude (:func:`hover_points`; for N = 1 and 100 the points of
``swarm=grid``, at N = 1,000 its 32-column grid with the short row on the other side, so the start
is given explicitly: from ``swarm=grid`` the agents of the short row would cross the swarm to
their slots):

- swarmscene: ``swarmscene.api`` with :func:`hover_overrides` (``dynamics=quadrotor``: 6-DOF rigid
  bodies, SE(3) controller and rotor mixer every physics step, one RK4 step in float64;
  ``formation=static_shape`` holding the grid, ``environment=open``, ``avoidance=none``); the
  whole tick is timed by the engine (``Simulation.step_seconds``): events, sensing, formation,
  avoidance, control, physics, the safety monitor (separation, connectivity) and the
  hooks;
- Crazyflow: ``Sim(n_worlds=1, n_drones=N, control=Control.state, freq=240, state_freq=R,
  attitude_freq=240)`` for a command rate R of 10 or 240 Hz: its default drone (cf21B_500),
  first-principles dynamics with rotor dynamics, Mellinger state and attitude controllers;
  ``default`` keeps its Euler integrator and float32, ``rk4_f64`` sets ``integrator=Integrator.rk4``
  and ``jax_enable_x64`` (the numerics swarmscene uses). Per tick, as a user's control loop:
  ``sim.state_control(cmd)`` then ``sim.step(240 // R)`` (Crazyflow's own
  ``sim.step(sim.freq // sim.control_freq)``), the command re-sent every tick, nothing read back;
  ``fused`` is the same simulation advanced K physics steps in one jitted ``sim.step(K)`` with the
  command held (Crazyflow at its fastest, no per-tick guidance).

Steady state: each side runs ``warm`` ticks first (JIT compilation, caches, the drones settling),
then ``steps`` timed physics steps; drone-steps/s = N x physics steps / s. Every measurement is a fresh process
pinned to one core with one thread (BLAS, OpenMP; XLA: ``--xla_cpu_multi_thread_eigen=false
intra_op_parallelism_threads=1``); the sides alternate ``repeat`` times and the fastest run of
each counts.

Time from command to first result, N = 1,000: the wall time of a fresh process until it exits
after its first simulated step. swarmscene: the ``swarmscene`` command with the hover overrides and
``clock.duration`` = one tick (from ``swarm=grid``, as a user types it; the run directory written,
then exit), with the numba cache warm
(as after any earlier run) and cold (``NUMBA_CACHE_DIR`` an empty temporary folder); Crazyflow: a
``python -c`` that imports it, builds the ``Sim``, sends the command and runs ``sim.step(1)`` to
completion (JIT included), with its default settings (no persistent cache) and with its own
``crazyflow.utils.enable_cache`` persistent JAX cache warm.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import peerlib
from peerlib import alternate, ensure_venv, timed_process

REQUIREMENTS = ["crazyflow==0.4.0", "jax[cpu]"]
HZ = 240
PERIOD = 1.0 / HZ  # 0.004166666666666667 s: the physics step
COMMAND_HZ = (10, 240)
"""Command (guidance) rates compared: the engine's default T_s = 0.1 s, and every physics step."""
SIZES = [1, 100, 1000]
FIRST_N = 1000
VARIANTS = ("default", "rk4_f64")


AVOIDANCE = ("potential", "orca")
"""The avoidance methods of the ``--avoidance`` sides: swarmscene with neighbour sensing and
avoidance on, against Crazyflow with nothing on (the issue's second physics goal)."""


def hover_overrides(n: int, command_hz: int = HZ, avoidance: str = "none") -> list[str]:
    """The swarmscene scenario: N quadrotors holding the grid they start on, physics at 240 Hz,
    guidance at ``command_hz``, no trajectory; ``avoidance`` on top of the formation's references
    (``none``: the bare hover)."""
    return [
        "dynamics=quadrotor", "environment=open", "swarm=grid", f"swarm.n={n}",
        "formation=static_shape", "formation.shape=grid", "formation.spacing=2.0",
        "formation.waypoints=[[0.0,0.0,2.0]]", "formation.rotate_with_heading=false",
        f"avoidance={avoidance}", "events=none",
        f"clock.guidance_period={1.0 / command_hz!r}", f"clock.physics_step={PERIOD!r}",
        "output.trajectory=false", "termination.on_complete=false",
    ]


SWARMSCENE_CHILD = r"""
import json, sys
import numpy as np
from swarmscene import api
overrides, warm, steps, period = json.loads(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
data = api.compose(overrides)
ticks = lambda physics_steps: physics_steps * period / data["clock"]["guidance_period"]
warm, steps = int(round(ticks(warm))), int(round(ticks(steps)))  # guidance ticks
data = api.compose(overrides + [f"clock.duration={(warm + steps) * data['clock']['guidance_period']!r}",
                                "output.summary=false"])
data["swarm"]["start"] = {"layout": "explicit", "positions": np.load(sys.argv[5]).tolist()}
sim = api.build(data)
result = sim.run()
assert result.metrics["steps"] == warm + steps, result.metrics
seconds = float(sim.step_seconds[warm:].sum())
n = sim.world.n
steps *= sim.substeps  # physics steps
slots = sim.formation._last_slots
print(json.dumps({"n": n, "steps": steps, "seconds": seconds, "steps_per_s": steps / seconds,
                  "drone_steps_per_s": n * steps / seconds, "first_tick_s": float(sim.step_seconds[0]),
                  "hover_error_m": float(np.abs(sim.world.pos - slots).max()),
                  "dtype": str(sim.world.pos.dtype), "monitor_min_separation": result.metrics["min_separation"]}))
"""

CRAZYFLOW_CHILD = r"""
import json, sys, time
mode, variant, positions, cache = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[6]
warm, steps = int(sys.argv[4]), int(sys.argv[5])
command_hz = int(sys.argv[7]) if len(sys.argv) > 7 else 240
k = 240 // command_hz  # physics steps per command
t_start = time.perf_counter()
import jax
if variant == "rk4_f64":
    jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp
import numpy as np
import crazyflow
from crazyflow.control import Control
from crazyflow.sim import Sim
from crazyflow.sim.integration import Integrator
if cache:
    from crazyflow.utils import enable_cache
    enable_cache(cache_path=__import__("pathlib").Path(cache))
t_import = time.perf_counter()
grid = np.load(positions)  # (N, 3) the hover points, m: swarmscene's grid slots
n = len(grid)
sim = Sim(n_worlds=1, n_drones=n, control=Control.state, freq=240, state_freq=command_hz, attitude_freq=240,
          integrator=Integrator.rk4 if variant == "rk4_f64" else Integrator.euler)
dtype = np.dtype(sim.data.states.pos.dtype)
sim.data = sim.data.replace(states=sim.data.states.replace(pos=jnp.asarray(grid[None], dtype=dtype)))
cmd = np.zeros((1, n, 16), dtype=dtype)
cmd[..., :3] = grid
cmd[..., 12] = 1.0  # quaternion (x, y, z, w): level, yaw 0
t_built = time.perf_counter()
sim.state_control(cmd)
sim.step(1)
jax.block_until_ready(sim.data.states.pos)
t_first = time.perf_counter()
out = {"import_s": t_import - t_start, "build_s": t_built - t_import, "first_step_s": t_first - t_built,
       "version": crazyflow.__version__ if hasattr(crazyflow, "__version__") else None,
       "jax": jax.__version__, "dtype": str(dtype), "integrator": str(sim.integrator)}
if mode == "steady":
    for _ in range(warm // k):
        sim.state_control(cmd)
        sim.step(k)
    jax.block_until_ready(sim.data.states.pos)
    t0 = time.perf_counter()
    for _ in range(steps // k):
        sim.state_control(cmd)
        sim.step(k)
    jax.block_until_ready(sim.data.states.pos)
    loop = time.perf_counter() - t0
    err = float(np.abs(np.asarray(sim.data.states.pos)[0] - grid).max())
    sim.step(steps)  # compiles the K-step scan
    jax.block_until_ready(sim.data.states.pos)
    t0 = time.perf_counter()
    sim.step(steps)
    jax.block_until_ready(sim.data.states.pos)
    fused = time.perf_counter() - t0
    out.update(n=n, steps=steps, seconds=loop, steps_per_s=steps / loop, drone_steps_per_s=n * steps / loop,
               fused_drone_steps_per_s=n * steps / fused, hover_error_m=err)
print(json.dumps(out))
"""


def crazyflow_python() -> Path:
    """The interpreter of Crazyflow's own virtual environment (built on first use)."""
    return ensure_venv("crazyflow", REQUIREMENTS)


HOVER_POINTS_CHILD = r"""
import sys
import numpy as np
from swarmscene.methods.shapes import shape_offsets
n = int(sys.argv[1])
np.save(sys.argv[2], np.array([0.0, 0.0, 2.0]) + shape_offsets("grid", n, 2.0))
"""


def hover_points(n: int, folder: str) -> str:
    """A .npy of the N hover points (N, 3): ``static_shape``'s grid slots, 2 m apart, centred on (0, 0, 2) m."""
    path = str(Path(folder) / f"hover_{n}.npy")
    subprocess.run([peerlib.swarmscene_python(), "-c", HOVER_POINTS_CHILD, str(n), path], check=True)
    return path


def steady(quick: bool = False, repeat: int = 3, sizes: list[int] = SIZES, log=print,
           rates: tuple[int, ...] = COMMAND_HZ, avoidance: tuple[str, ...] = ()) -> dict:
    """Steady-state drone-steps/s of swarmscene and both Crazyflow variants, alternating, at each
    command rate; with ``avoidance``, also swarmscene with each of those avoidance methods on
    (sides ``swarmscene_<method>``, ratios ``ratio_<method>_default`` to Crazyflow's default)."""
    cf = str(crazyflow_python())
    python = peerlib.swarmscene_python()
    warm = 48 if quick else 240
    steps = 240 if quick else 960
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n, hz in [(n, hz) for hz in rates for n in sizes]:
            points = hover_points(n, tmp)
            sides = {("swarmscene" if method == "none" else f"swarmscene_{method}"):
                     ([python, "-c", SWARMSCENE_CHILD, json.dumps(hover_overrides(n, hz, method)), str(warm),
                       str(steps), repr(PERIOD), points], None) for method in ("none", *avoidance)}
            for variant in VARIANTS:  # in the temporary folder: MuJoCo may write its MUJOCO_LOG.TXT
                sides[f"crazyflow_{variant}"] = ([cf, "-c", CRAZYFLOW_CHILD, "steady", variant, points, str(warm),
                                                  str(steps), "", str(hz)], tmp)
            best = alternate(sides, repeat, "drone_steps_per_s")
            row = {"n": n, "command_hz": hz, "warm": warm, "steps": steps, **best}
            ours = best["swarmscene"].get("drone_steps_per_s")
            for variant in VARIANTS:
                peer = best[f"crazyflow_{variant}"]
                if ours and "drone_steps_per_s" in peer:
                    row[f"ratio_{variant}"] = ours / peer["drone_steps_per_s"]
                    row[f"ratio_{variant}_fused"] = ours / peer["fused_drone_steps_per_s"]
            for method in avoidance:
                ours_on, peer = best[f"swarmscene_{method}"].get("drone_steps_per_s"), best["crazyflow_default"]
                if ours_on and "drone_steps_per_s" in peer:
                    row[f"ratio_{method}_default"] = ours_on / peer["drone_steps_per_s"]
            log(f"  hover N = {n:,}, command {hz} Hz: " + "; ".join(
                f"{side} {r['drone_steps_per_s']:.3g} drone-steps/s"
                + (f" (fused {r['fused_drone_steps_per_s']:.3g})" if "fused_drone_steps_per_s" in r else "")
                + f", hover error {r['hover_error_m']:.2g} m" if "error" not in r else f"{side} FAILED: {r['error']}"
                for side, r in best.items()))
            rows.append(row)
    return {"rows": rows, "repeat": repeat, "hz": HZ, "command_hz": list(rates)}


def swarmscene_command(n: int, run_dir: str) -> list[str]:
    """The command line timed for the first result: one tick of the hover scenario."""
    exe = Path(sys.executable).parent / "swarmscene"
    return [str(exe), *hover_overrides(n), f"clock.duration={PERIOD!r}", f"hydra.run.dir={run_dir}"]


def first_result(quick: bool = False, repeat: int = 3, n: int = FIRST_N, log=print) -> dict:
    """Wall seconds from the command to the first simulated result, fresh processes, alternating."""
    cf = str(crazyflow_python())
    best: dict[str, float] = {}
    detail: dict[str, dict] = {}
    errors: dict[str, str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        points = hover_points(n, tmp)
        jax_cache = str(Path(tmp) / "jax_cache")
        run_dir = str(Path(tmp) / "run")
        cf_first = [cf, "-c", CRAZYFLOW_CHILD, "first", "default", points, "0", "0"]
        for warm_up in (swarmscene_command(n, run_dir), cf_first + [jax_cache]):
            try:  # the numba cache beside the package; Crazyflow's persistent JAX cache
                timed_process(warm_up, cwd=tmp)
            except RuntimeError:
                pass  # the timed run of the same command reports it
        for _ in range(repeat):  # alternate, so a burst of load hits every case alike
            cases = {
                "swarmscene_warm": (swarmscene_command(n, run_dir), None),
                "swarmscene_cold": (swarmscene_command(n, run_dir), {"NUMBA_CACHE_DIR": tempfile.mkdtemp(dir=tmp)}),
                "crazyflow_default": (cf_first + [""], None),
                "crazyflow_cached": (cf_first + [jax_cache], None),
            }
            for name, (cmd, env) in cases.items():
                if name in errors:
                    continue
                try:
                    wall, out = timed_process(cmd, env, cwd=tmp)
                except RuntimeError as exc:
                    errors[name] = str(exc).splitlines()[-1]
                    continue
                if name not in best or wall < best[name]:
                    best[name] = wall
                    if name.startswith("crazyflow"):
                        detail[name] = json.loads(out.strip().splitlines()[-1])
    log(f"  first result N = {n:,}: " + ", ".join(f"{k} {v:.2f} s" for k, v in best.items()))
    shown = [a if "[" not in a else f"'{a}'" for a in swarmscene_command(n, "...")[1:-1]]
    return {"n": n, "repeat": repeat, "seconds": best, "crazyflow_detail": detail, "errors": errors,
            "swarmscene_command": "swarmscene " + " ".join(shown)}


def main() -> None:
    """Print the steady-state and first-result comparisons with Crazyflow as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sizes", type=int, nargs="+", default=SIZES, help="the swarm sizes N (1 100 1000)")
    parser.add_argument("--rates", type=int, nargs="+", default=list(COMMAND_HZ),
                        help="the command rates, Hz (10 240)")
    parser.add_argument("--avoidance", nargs="*", default=[], metavar="METHOD",
                        help=f"also swarmscene with these avoidance methods on (e.g. {' '.join(AVOIDANCE)})")
    parser.add_argument("--steady-only", action="store_true", help="leave out the first-result times")
    args = parser.parse_args()
    repeat = 1 if args.quick else args.repeat
    out = {"steady": steady(args.quick, repeat, args.sizes, rates=tuple(args.rates), avoidance=tuple(args.avoidance))}
    if not args.steady_only:
        out["first"] = first_result(args.quick, repeat)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
