"""Batched quadrotor physics on a grid of B worlds x N drones: swarmscene beside Crazyflow (JAX, CPU), one core.

    taskset -c 1 python benchmarks/speed/peers/bench_crazyflow_grid.py            # the grid, 3 alternations
    taskset -c 1 python benchmarks/speed/peers/bench_crazyflow_grid.py --quick    # a check: 2 points, one pass
    taskset -c 1 python benchmarks/speed/peers/bench_crazyflow_grid.py --only 16x100 4096x10

Crazyflow runs in its own virtual environment, ``benchmarks/speed/peers/.venv-crazyflow`` (created on
first use with ``pip install crazyflow==0.4.0 "jax[cpu]"``, as bench_crazyflow.py does; git ignores
it), swarmscene in the interpreter running this script. The table is printed and written as markdown
to ``benchmarks/speed/results/crazyflow_grid.md`` (``--output``), with the time (UTC), the load
(``uptime``) before and after, the CPU (``lscpu``) and the versions.

The grid: B in {1, 16, 256, 4096} worlds x N in {1, 10, 100, 1000} drones per world, the points with
B x N <= 65,536 drones (13 points), and 64 x 16 (one of issue #34's goal points). Left out: 256 x 1000
(256,000 drones), 4096 x 100 (409,600) and 4096 x 1000 (4,096,000), over the bound, which keeps the
whole run near 30 minutes on one core.

Both sides fly every world's N drones holding their own points, the same in every world: a square
grid 2 m apart at 2 m altitude (``bench_batch.worlds``: columns of ceil(sqrt(N))), physics at 240 Hz
and the command at 10 Hz (24 physics steps per tick):

- swarmscene: ``bench_batch.physics(Quadrotor, B, N, ticks, blocks)`` from
  ``benchmarks/speed/bench_batch.py`` (imported with importlib, not copied): per 10 Hz tick one
  ``Quadrotor.control_batch`` (the SE(3) controller of every drone of every world, latched for the
  tick) then 24 ``Quadrotor.step_batch`` (the rotor mixer and one RK4 step of each 6-DOF rigid body,
  numba) over a :class:`~swarmscene.core.state.WorldBatch` of the B worlds, in float64 (the default)
  and, as a side of its own, with ``dtype="float32"`` (``dynamics.dtype=float32``). The figure is
  its ``+control_batch`` side (the engine's batched tick, the worlds' setpoint records in a list, as
  formations give them); the column "one setpoint batch" is the same tick given the setpoints as one
  :class:`~swarmscene.core.setpoint.SetpointBatch` (as the ``policy`` avoidance gives an
  environment's actions, and as Crazyflow's side is given one (B, N, 16) command array), timed
  alternately in the same process. ``physics`` also times the worlds one by one and ``step_batch``
  with the controllers world by world (kept in the JSON of ``--json``, not in the table) and checks
  that the four end in the same bits.
- Crazyflow: ``Sim(n_worlds=B, n_drones=N, control=Control.state, freq=240, state_freq=10,
  attitude_freq=240)``, its default drone (cf21B_500), first-principles dynamics with rotor
  dynamics, Mellinger state and attitude controllers, the drones placed on the points at rest; as a
  user's control loop, per 10 Hz tick ``sim.state_control(cmd)`` (the (B, N, 16) command: the point,
  level, yaw 0, re-sent every tick) then ``sim.step(24)``, nothing read back until the end of a block
  (``jax.block_until_ready``). ``default``: its own settings, the Euler integrator in float32;
  ``rk4_f64``: ``integrator=Integrator.rk4`` and ``jax_enable_x64`` (swarmscene's numerics), run
  where N < 1000 unless ``--rk4-all``: at N = 1000 Crazyflow spends 37-43 s per process building
  its MuJoCo/MJX model before the first step, and those six more processes would take the run past
  25 minutes.

The unit: drone-steps per CPU second = B x N x 24 x ticks / (CPU seconds of the block), both sides in
CPU time (``time.process_time`` of the measuring process; one core, so it is the wall time less any
time the core gave to other processes). Warm: the timed blocks come after the compilation and
warm-up: swarmscene's first tick of the process (numba's machine code loaded from its on-disk
cache), then one tick of each of ``physics``'s sides; Crazyflow's first tick (the JIT compilation
of ``step(24)``), then 3 more ticks. Cold, apart (the second table): swarmscene's import of
bench_batch (numba, swarmscene), building the B worlds and the first tick; Crazyflow's import,
``Sim(...)`` and the first tick with its JIT (no persistent compilation cache).

Ticks per timed block: 16,384 // (B x N), at least 1 and at most 400 (about 0.4 M drone-steps per
block from 100 drones up; 9,600 to 96,000 at B x N of 1 to 16), 2 blocks per process, the faster
counting. Every measurement is a fresh process pinned to one core (``taskset -c 1``, peerlib.CORE)
with one thread (OMP, OpenBLAS, MKL, numba; XLA ``--xla_cpu_multi_thread_eigen=false
intra_op_parallelism_threads=1``); at each point the sides alternate ``--repeat`` times (3) and the
fastest run of each counts.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import subprocess
import tempfile
from pathlib import Path

import bench_crazyflow
import peerlib
from peerlib import alternate, child_json

BENCH_BATCH = peerlib.ROOT / "benchmarks" / "speed" / "bench_batch.py"
RESULTS = peerlib.ROOT / "benchmarks" / "speed" / "results" / "crazyflow_grid.md"
WORLDS = (1, 16, 256, 4096)
DRONES = (1, 10, 100, 1000)
MAX_DRONES = 65_536
"""The grid's bound on B x N (all worlds' drones together)."""
GRID = sorted([(b, n) for b in WORLDS for n in DRONES if b * n <= MAX_DRONES] + [(64, 16)])
"""The grid, and 64 x 16, one of issue #34's goal points."""
LEFT_OUT = [(b, n) for b in WORLDS for n in DRONES if b * n > MAX_DRONES]
SUBSTEPS = 24
"""Physics steps per 10 Hz tick (240 Hz physics)."""
BLOCK_DRONES = 16_384
"""Ticks per timed block: BLOCK_DRONES // (B x N), within [1, MAX_TICKS]."""
MAX_TICKS = 400
BLOCKS = 2
"""Timed blocks per process (the faster counts)."""
CRAZYFLOW_WARM = 3
"""Crazyflow's ticks after the first (JIT) tick and before the timed blocks."""
VARIANTS = ("default", "rk4_f64")
OURS = {"swarmscene": "float64", "swarmscene_float32": "float32"}
"""swarmscene's sides: ``dynamics.dtype`` (the physics step's precision), each in its own processes."""


def ticks_per_block(b: int, n: int) -> int:
    """Ticks of one timed block at B worlds of N drones."""
    return max(1, min(MAX_TICKS, BLOCK_DRONES // (b * n)))


SWARMSCENE_CHILD = r"""
import importlib.util, json, sys, time
t_start = time.perf_counter()
path = sys.argv[1]
b, n, ticks, blocks = (int(a) for a in sys.argv[2:6])
options = {"dtype": sys.argv[6]}  # dynamics.dtype: the physics step's precision
spec = importlib.util.spec_from_file_location("bench_batch", path)
bench_batch = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench_batch)
Quadrotor = bench_batch.Quadrotor
t_import = time.perf_counter()
the_worlds, models, targets = bench_batch.worlds(Quadrotor, b, n, **options)
batch = bench_batch.WorldBatch(the_worlds)
t_built = time.perf_counter()
bench_batch.tick(models, the_worlds, targets, lambda: Quadrotor.step_batch(models, batch, bench_batch.PHYSICS_STEP),
                 batch, control_batch=True)
t_first = time.perf_counter()
del the_worlds, models, targets, batch
per_world, step_batch, control_batch, one_batch = bench_batch.physics(Quadrotor, b, n, ticks, blocks, **options)
print(json.dumps({"b": b, "n": n, "ticks": ticks, "blocks": blocks, "drone_steps_per_s": control_batch,
                  "per_world_drone_steps_per_s": per_world, "step_batch_drone_steps_per_s": step_batch,
                  "one_batch_drone_steps_per_s": one_batch,
                  "import_s": t_import - t_start, "build_s": t_built - t_import, "first_tick_s": t_first - t_built}))
"""

CRAZYFLOW_CHILD = r"""
import json, sys, time
t_start = time.perf_counter()
variant, points = sys.argv[1], sys.argv[2]
b, n, warm, ticks, blocks = (int(a) for a in sys.argv[3:8])
k = 240 // 10  # physics steps per command
import jax
if variant == "rk4_f64":
    jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp
import numpy as np
from crazyflow.control import Control
from crazyflow.sim import Sim
from crazyflow.sim.integration import Integrator
t_import = time.perf_counter()
grid = np.load(points)  # (N, 3) the hover points, m: bench_batch.worlds' points
assert grid.shape == (n, 3), grid.shape
sim = Sim(n_worlds=b, n_drones=n, control=Control.state, freq=240, state_freq=10, attitude_freq=240,
          integrator=Integrator.rk4 if variant == "rk4_f64" else Integrator.euler)
dtype = np.dtype(sim.data.states.pos.dtype)
start = np.ascontiguousarray(np.broadcast_to(grid, (b, n, 3)), dtype=dtype)
sim.data = sim.data.replace(states=sim.data.states.replace(pos=jnp.asarray(start)))
cmd = np.zeros((b, n, 16), dtype=dtype)
cmd[..., :3] = start
cmd[..., 12] = 1.0  # quaternion (x, y, z, w): level, yaw 0
t_built = time.perf_counter()
sim.state_control(cmd)
sim.step(k)
jax.block_until_ready(sim.data.states.pos)
t_first = time.perf_counter()
for _ in range(warm):
    sim.state_control(cmd)
    sim.step(k)
jax.block_until_ready(sim.data.states.pos)
cpu = wall = float("inf")
for _ in range(blocks):
    c0, w0 = time.process_time(), time.perf_counter()
    for _ in range(ticks):
        sim.state_control(cmd)
        sim.step(k)
    jax.block_until_ready(sim.data.states.pos)
    cpu, wall = min(cpu, time.process_time() - c0), min(wall, time.perf_counter() - w0)
steps = b * n * k * ticks
err = float(np.abs(np.asarray(sim.data.states.pos) - start).max())
print(json.dumps({"b": b, "n": n, "ticks": ticks, "blocks": blocks, "drone_steps_per_s": steps / cpu,
                  "wall_drone_steps_per_s": steps / wall, "hover_error_m": err, "dtype": str(dtype),
                  "integrator": str(sim.integrator), "import_s": t_import - t_start, "build_s": t_built - t_import,
                  "first_tick_s": t_first - t_built}))
"""

CRAZYFLOW_VERSIONS = r"""
import json
from importlib.metadata import version
print(json.dumps({p: version(p) for p in ("crazyflow", "jax", "jaxlib", "mujoco", "mujoco-mjx", "numpy")}))
"""

POINTS_CHILD = r"""
import importlib.util, sys
import numpy as np
spec = importlib.util.spec_from_file_location("bench_batch", sys.argv[1])
bench_batch = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench_batch)
the_worlds, _, _ = bench_batch.worlds(bench_batch.Quadrotor, 1, int(sys.argv[2]))
np.save(sys.argv[3], the_worlds[0].pos)
"""


def hover_points(n: int, folder: str) -> str:
    """A .npy of the N points (N, 3) every world's drones hold: bench_batch.worlds' own."""
    path = str(Path(folder) / f"points_{n}.npy")
    if not Path(path).exists():
        subprocess.run([peerlib.swarmscene_python(), "-c", POINTS_CHILD, str(BENCH_BATCH), str(n), path], check=True)
    return path


def commit() -> str:
    """The repository's HEAD, short (the tree measured: the children import swarmscene from it)."""
    return subprocess.run(["git", "-C", str(peerlib.ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True).stdout.strip()


def versions(cf: str, head: str) -> dict[str, str]:
    """The versions of both sides' packages; swarmscene's from the tree's pyproject.toml (an editable
    install's metadata may name an older version), at commit ``head``."""
    import tomllib

    import numba
    import numpy

    swarmscene_version = tomllib.loads((peerlib.ROOT / "pyproject.toml").read_text())["project"]["version"]
    cf_versions = child_json([cf, "-c", CRAZYFLOW_VERSIONS])
    return {"swarmscene": f"{swarmscene_version} (commit {head})", "numba": numba.__version__,
            "numpy": numpy.__version__, "python": platform.python_version(),
            **{f"{k} (Crazyflow venv)" if k == "numpy" else k: v for k, v in cf_versions.items()}}


def cpu_model() -> str:
    """The CPU's model name (lscpu)."""
    out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
    lines = [line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name")]
    count = [line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("CPU(s):")]
    return f"{lines[0] if lines else platform.processor()}, {count[0] if count else '?'} CPUs"


def uptime() -> str:
    """``uptime``'s line (the load averages)."""
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def measure(points: list[tuple[int, int]], repeat: int, rk4_all: bool, tick_scale: float, log=print) -> list[dict]:
    """Every point's sides, alternating ``repeat`` times in fresh pinned processes; the fastest run of each."""
    cf = str(bench_crazyflow.crazyflow_python())
    python = peerlib.swarmscene_python()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for b, n in points:
            ticks = max(1, int(ticks_per_block(b, n) * tick_scale))
            grid = hover_points(n, tmp)
            sides = {name: ([python, "-c", SWARMSCENE_CHILD, str(BENCH_BATCH), str(b), str(n), str(ticks),
                             str(BLOCKS), dtype], None) for name, dtype in OURS.items()}
            for variant in VARIANTS:
                if variant == "rk4_f64" and n >= 1000 and not rk4_all:
                    continue
                sides[f"crazyflow_{variant}"] = ([cf, "-c", CRAZYFLOW_CHILD, variant, grid, str(b), str(n),
                                                  str(CRAZYFLOW_WARM), str(ticks), str(BLOCKS)], tmp)
            best = alternate(sides, repeat, "drone_steps_per_s")
            row = {"b": b, "n": n, "ticks": ticks, **best}
            ours = best["swarmscene"].get("drone_steps_per_s")
            for variant in VARIANTS:
                peer = best.get(f"crazyflow_{variant}", {})
                if ours and "drone_steps_per_s" in peer:
                    row[f"ratio_{variant}"] = ours / peer["drone_steps_per_s"]
            peer = best.get("crazyflow_default", {})
            for ours_key, key in (("swarmscene_float32", "drone_steps_per_s"),
                                  ("swarmscene", "one_batch_drone_steps_per_s")):
                rate = best[ours_key].get(key)
                if rate and "drone_steps_per_s" in peer:
                    row[f"ratio_{ours_key}_{key}"] = rate / peer["drone_steps_per_s"]
            log(f"  {b} x {n} ({ticks} ticks): " + "; ".join(
                f"{side} FAILED: {r['error']}" if "error" in r else f"{side} {r['drone_steps_per_s']:.4g}"
                for side, r in best.items()) + "".join(
                f"; ratio {v} {row[f'ratio_{v}']:.2f}" for v in VARIANTS if f"ratio_{v}" in row), flush=True)
            rows.append(row)
    return rows


def _rate(side: dict | None, key: str = "drone_steps_per_s") -> str:
    if side is None:
        return "not run"
    return f"FAILED: {side['error']}" if "error" in side else f"{side[key]:.4g}" if key in side else "-"


def _ratio(row: dict, variant: str) -> str:
    return f"{row[f'ratio_{variant}']:.2f}" if f"ratio_{variant}" in row else "-"


def _cold(side: dict | None) -> str:
    if side is None or "error" in side:
        return "-"
    return f"{side['import_s']:.1f} / {side['build_s']:.1f} / {side['first_tick_s']:.2f}"


def tables(rows: list[dict]) -> tuple[str, str]:
    """The steady-state table and the cold-start table, markdown."""
    steady = ["| B x N | drones | ticks x 24 steps per block | swarmscene | Crazyflow default (Euler, float32) | ratio "
              "| Crazyflow rk4_f64 | ratio | swarmscene float32 | ratio to default "
              "| swarmscene, one setpoint batch | ratio to default "
              "| Crazyflow hover error default / rk4_f64 (m) |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    cold = ["| B x N | swarmscene | Crazyflow default | Crazyflow rk4_f64 |", "|---|---:|---:|---:|"]
    for row in rows:
        ours, default, rk4 = row["swarmscene"], row.get("crazyflow_default"), row.get("crazyflow_rk4_f64")
        errors = " / ".join(f"{s['hover_error_m']:.2g}" if s and "hover_error_m" in s else "-" for s in (default, rk4))
        steady.append(f"| {row['b']} x {row['n']} | {row['b'] * row['n']:,} | {row['ticks']} | {_rate(ours)} "
                      f"| {_rate(default)} | {_ratio(row, 'default')} | {_rate(rk4)} | {_ratio(row, 'rk4_f64')} "
                      f"| {_rate(row.get('swarmscene_float32'))} "
                      f"| {_ratio(row, 'swarmscene_float32_drone_steps_per_s')} "
                      f"| {_rate(ours, 'one_batch_drone_steps_per_s')} "
                      f"| {_ratio(row, 'swarmscene_one_batch_drone_steps_per_s')} | {errors} |")
        cold.append(f"| {row['b']} x {row['n']} | {_cold(ours)} | {_cold(default)} | {_cold(rk4)} |")
    return "\n".join(steady), "\n".join(cold)


def main() -> None:
    """Measure the grid, print the tables and write them as markdown."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="alternations of the sides per point (3)")
    parser.add_argument("--quick", action="store_true", help="1 x 1 and 16 x 10, one pass, a tenth of the ticks")
    parser.add_argument("--only", nargs="*", metavar="BxN", help="the grid points to run (e.g. 16x100)")
    parser.add_argument("--rk4-all", action="store_true", help="Crazyflow rk4_f64 at N = 1000 too")
    parser.add_argument("--output", type=Path, default=RESULTS, help="the markdown file written")
    parser.add_argument("--json", type=Path, default=None, help="also write every side's best run as JSON")
    args = parser.parse_args()
    points = GRID
    if args.quick:
        points = [(1, 1), (16, 10)]
    if args.only:
        points = [(b, n) for b, n in GRID if f"{b}x{n}" in args.only]
    repeat = 1 if args.quick else args.repeat
    cf = str(bench_crazyflow.crazyflow_python())
    started = datetime.datetime.now(datetime.UTC)
    head = commit()
    load_before = uptime()
    print(f"{started:%Y-%m-%d %H:%M} UTC, {load_before}", flush=True)
    rows = measure(points, repeat, args.rk4_all, 0.1 if args.quick else 1.0)
    load_after = uptime()
    finished = datetime.datetime.now(datetime.UTC)
    steady, cold = tables(rows)
    found = versions(cf, head)
    print(steady)
    print()
    print(cold)
    print(f"\nload before: {load_before}\nload after: {load_after}\n{(finished - started).total_seconds():.0f} s")
    left_out = ", ".join(f"{b} x {n} ({b * n:,})" for b, n in LEFT_OUT)
    text = f"""# Batched quadrotor physics beside Crazyflow, B worlds x N drones

Measured {started:%Y-%m-%d %H:%M} UTC to {finished:%H:%M} UTC ({(finished - started).total_seconds() / 60:.1f} min)
with `taskset -c 1 python benchmarks/speed/peers/bench_crazyflow_grid.py{' --quick' if args.quick else ''}\
{' --only ' + ' '.join(args.only) if args.only else ''}{' --rk4-all' if args.rk4_all else ''}` \
(bench_crazyflow_grid.py's docstring says what each side does).

- CPU: {cpu_model()}; every process pinned to core {peerlib.CORE}, one thread.
- Load (`uptime`) before: `{load_before}`
- Load after: `{load_after}`
- Versions: {", ".join(f"{k} {v}" for k, v in found.items())}

Drone-steps per CPU second in steady state (after JIT and warm-up), physics at 240 Hz, control at 10 Hz
(24 physics steps per tick); the fastest of {repeat} alternated fresh processes per side, each the
faster of {BLOCKS} timed blocks. swarmscene: `Quadrotor.control_batch` + `step_batch`, RK4, float64
(bench_batch.physics), the setpoints a list of the worlds' records; the same with
`dynamics.dtype=float32`; and (one setpoint batch) the float64 tick given the setpoints as one
`SetpointBatch`, alternated with the first in its processes. Crazyflow: `Sim(n_worlds=B,
n_drones=N, control=Control.state, freq=240, state_freq=10, attitude_freq=240)`, per tick
`sim.state_control(cmd)` then `sim.step(24)`; default = Euler, float32; rk4_f64 =
`integrator=Integrator.rk4` and `jax_enable_x64` (not run at N = 1000 unless `--rk4-all`: its model
build takes 37-43 s per process there). Ratio = swarmscene /
Crazyflow. Points left out (B x N > {MAX_DRONES:,}): {left_out}.

{steady}

Cold start, seconds (not in the figures above): swarmscene import of bench_batch (swarmscene, numba)
/ building the B worlds / the first tick (numba's cache on disk warm); Crazyflow import / `Sim(...)`
/ the first tick with its JIT compilation (no persistent cache).

{cold}
"""
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    print(f"wrote {args.output}")
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "versions": found, "load_before": load_before,
                                         "load_after": load_after}, indent=1))


if __name__ == "__main__":
    main()
