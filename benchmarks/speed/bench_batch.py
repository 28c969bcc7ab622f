"""Many worlds in one step (issue #34): B worlds' physics in one batched call against the same
worlds stepped one by one, and whole batched runs against single runs.

Part 1, the physics: B worlds of N ``quadrotor`` (6-DOF rigid bodies, SE(3) control, mixer, one
RK4 step per physics step, float64) or ``double_integrator`` agents, each world's agents holding
their own points 2 m apart, physics at 240 Hz, the controller latched once per 10 Hz tick. Per
world: ``model.control`` and ``model.step(world, dt)`` for each world; ``step_batch``: the
controllers world by world, one ``Model.step_batch(models, batch, dt)``
(:class:`~swarmscene.core.state.WorldBatch`); ``+control_batch``: one
``Model.control_batch(models, batch, worlds, setpoints)`` and one ``step_batch`` (the engine's
tick), the worlds' setpoint records in a list (as formations give them); ``one batch``: the same
with the setpoints as one :class:`~swarmscene.core.setpoint.SetpointBatch` (as the ``policy``
avoidance gives an environment's actions, and as Crazyflow's users give their commands: one
array). The four sides fly the same worlds alternately, block by block, timed in CPU time;
drone-steps per CPU second of each and their ratios to the first. All end in the same state,
bit for bit (checked).

Part 2, whole runs: ``api.run_batch(data, seeds)`` against ``api.run`` once per seed from the
same composed data (every phase of every tick: events, sensing, formation, avoidance, the
monitor, the recorder; building each world), in CPU time, alternately; runs per CPU second of
each and their ratio.

Part 3, the vector environment: ``gym.make_vec`` on a swarmscene id, B worlds of the default
scenario with 6 agents (double integrator, the ``policy`` avoidance, the safety monitor), the
native vector environment (the worlds' physics batched) against Gymnasium's ``SyncVectorEnv`` of
the single environment; random actions, agent-steps per CPU second (simulation only). Then the
same worlds as multi-agent arrays: ``SwarmMultiAgentVectorEnv`` against B PettingZoo parallel
environments stepped in a loop.

One core, one thread::

    taskset -c 1 python benchmarks/speed/bench_batch.py [--quick] [--only quadrotor:4096x1 ...]

Part 4, instead of the others, with ``--threads K``: the quadrotor's batched tick on one thread and
on K (``dynamics.threads``), in wall time, at 1 x 10,000 and the grid's points of at least 1,024
agents (the sides alternate block by block and end in the same bits)::

    python benchmarks/speed/bench_batch.py --threads 2
"""

from __future__ import annotations

import argparse
import os
import sys
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    if not (_var == "NUMBA_NUM_THREADS" and "--threads" in sys.argv):  # part 4 asks numba for threads
        os.environ.setdefault(_var, "1")  # one core (before numpy and numba are imported)

import numpy as np  # noqa: E402

from swarmscene import api  # noqa: E402
from swarmscene.core.setpoint import SetpointBatch, Setpoints  # noqa: E402
from swarmscene.core.state import WorldBatch, WorldState  # noqa: E402
from swarmscene.plugin import build_context  # noqa: E402
from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator  # noqa: E402
from swarmscene.plugins.dynamics.quadrotor import Quadrotor  # noqa: E402

PHYSICS_STEP = 1.0 / 240.0
GUIDANCE_PERIOD = 0.1
SUBSTEPS = 24
"""Physics steps per guidance tick (240 Hz physics, 10 Hz guidance)."""

GRID = [(1, 100), (1, 1000), (16, 10), (64, 16), (256, 6), (4096, 1)]
"""(B worlds, N agents per world): the issue's grid points."""


def worlds(model_cls: type, b: int, n: int, **options) -> tuple[list[WorldState], list, list[Setpoints]]:
    """B worlds of N agents on a grid 2 m apart at 2 m altitude, each holding its points (the
    model built with ``options``)."""
    side = int(np.ceil(np.sqrt(n)))
    k = np.arange(n)
    pos = np.column_stack([2.0 * (k % side), 2.0 * (k // side), np.full(n, 2.0)])
    out_worlds, models, targets = [], [], []
    for _ in range(b):
        world = WorldState.at_rest(pos)
        ctx = build_context(positions=pos, guidance_period=GUIDANCE_PERIOD, physics_step=PHYSICS_STEP)
        model = model_cls(model_cls.Params(**options), ctx)
        model.initialize(world)
        out_worlds.append(world)
        models.append(model)
        targets.append(Setpoints.hold(pos.copy()))
    return out_worlds, models, targets


def tick(models: list, the_worlds: list[WorldState], targets: list[Setpoints], step, batch=None,
         control_batch: bool = False) -> None:
    """One guidance tick: every world's controller latched (world by world, or with the model's
    ``control_batch``), then ``SUBSTEPS`` physics steps."""
    if control_batch:
        type(models[0]).control_batch(models, batch, the_worlds, targets)
    else:
        for model, world, target in zip(models, the_worlds, targets, strict=True):
            model.control(world, target)
    if batch is not None:
        batch.controlled()
    for _ in range(SUBSTEPS):
        step()


def physics(model_cls: type, b: int, n: int, ticks: int, blocks: int, **options) -> tuple[float, float, float, float]:
    """Drone-steps per CPU second, per world, batched physics with the controllers world by world,
    batched physics and controllers with the worlds' setpoint records in a list (as a formation
    gives them) and with one :class:`~swarmscene.core.setpoint.SetpointBatch` (as the ``policy``
    avoidance gives an environment's actions; the best block of each); the model built with
    ``options``."""
    sides = {side: worlds(model_cls, b, n, **options) for side in ("world", "batch", "control", "stacked")}
    batches = {side: WorldBatch(sides[side][0]) for side in ("batch", "control", "stacked")}
    the_worlds, models, targets = sides["stacked"]
    sides["stacked"] = (the_worlds, models, SetpointBatch.stack(targets))

    def stepper(side: str):
        the_worlds, models, _ = sides[side]
        if side == "world":
            def per_world() -> None:
                for model, world in zip(models, the_worlds, strict=True):
                    model.step(world, PHYSICS_STEP)
            return per_world

        def batched() -> None:
            model_cls.step_batch(models, batches[side], PHYSICS_STEP)
        return batched

    def args(side: str) -> tuple:
        the_worlds, models, targets = sides[side]
        return (models, the_worlds, targets, stepper(side), batches.get(side), side in ("control", "stacked"))

    best = dict.fromkeys(sides, np.inf)
    for side in sides:  # compile and warm every side
        tick(*args(side))
    for _ in range(blocks):
        for side in sides:
            start = time.process_time()
            for _ in range(ticks):
                tick(*args(side))
            best[side] = min(best[side], time.process_time() - start)
    for side in ("batch", "control", "stacked"):
        for a, c in zip(sides["world"][0], sides[side][0], strict=True):
            assert np.array_equal(a.pos, c.pos) and np.array_equal(a.vel, c.vel), "the batch left its worlds' bits"
    steps = b * n * ticks * SUBSTEPS
    return steps / best["world"], steps / best["batch"], steps / best["control"], steps / best["stacked"]



def threads_scaling(b: int, n: int, threads: int, ticks: int, blocks: int) -> tuple[float, float]:
    """Quadrotor drone-steps per wall second of B worlds of N agents, batched (``control_batch``
    and ``step_batch``) on one thread and on ``threads`` (``dynamics.threads``), the two sides
    alternating block by block (the best block of each); both end in the same bits (checked)."""
    sides = {k: worlds(Quadrotor, b, n, threads=k) for k in (1, threads)}
    batches = {k: WorldBatch(sides[k][0]) for k in sides}

    def one_tick(k: int) -> None:
        the_worlds, models, targets = sides[k]
        tick(models, the_worlds, targets, lambda: Quadrotor.step_batch(models, batches[k], PHYSICS_STEP)
             if b > 1 else models[0].step(the_worlds[0], PHYSICS_STEP), batches[k], control_batch=b > 1)

    best = dict.fromkeys(sides, np.inf)
    for k in sides:  # compile and warm
        one_tick(k)
    for _ in range(blocks):
        for k in sides:
            start = time.perf_counter()
            for _ in range(ticks):
                one_tick(k)
            best[k] = min(best[k], time.perf_counter() - start)
    for a, c in zip(sides[1][0], sides[threads][0], strict=True):
        assert np.array_equal(a.pos, c.pos) and np.array_equal(a.quat, c.quat), "threads changed the bits"
    steps = b * n * ticks * SUBSTEPS
    return steps / best[1], steps / best[threads]


def whole_runs(config: list[str], seeds: list[int], blocks: int) -> tuple[float, float]:
    """Runs per CPU second, one by one and as one batch (the best block of each); both sides
    start from the same composed data (Hydra composes once), so the ratio is the stepping's."""
    data = api.compose(config)
    best = {"runs": np.inf, "batch": np.inf}
    api.run_batch(data, seeds[:1])  # compile and warm
    for _ in range(blocks):
        start = time.process_time()
        for seed in seeds:
            api.run({**data, "seed": seed})
        best["runs"] = min(best["runs"], time.process_time() - start)
        start = time.process_time()
        api.run_batch(data, seeds)
        best["batch"] = min(best["batch"], time.process_time() - start)
    return len(seeds) / best["runs"], len(seeds) / best["batch"]


ENV_CASE = ["swarm.n=6", "dynamics=double_integrator"]
"""Part 3's worlds: the default scenario with 6 agents on the double integrator."""


def vector_env(b: int, steps: int, blocks: int) -> tuple[float, float]:
    """Agent-steps per CPU second of B worlds x 6 agents, Gymnasium's sync vector env and ours."""
    import gymnasium as gym

    from swarmscene import env as swarm_env

    env_id = swarm_env.register_scenario("bench/default6-v0", ENV_CASE)
    rates = {}
    for mode in ("sync", "vector_entry_point"):
        envs = gym.make_vec(env_id, num_envs=b, vectorization_mode=mode)
        rng = np.random.default_rng(0)
        envs.reset(seed=0)
        best = np.inf
        for _ in range(blocks):
            actions = [rng.uniform(-1, 1, envs.action_space.shape) for _ in range(steps)]
            start = time.process_time()
            for action in actions:
                envs.step(action)
            best = min(best, time.process_time() - start)
        rates[mode] = b * 6 * steps / best
        envs.close()
    return rates["sync"], rates["vector_entry_point"]


def multi_agent_vector_env(b: int, steps: int, blocks: int) -> tuple[float, float]:
    """Agent-steps per CPU second of B worlds x 6 agents: B PettingZoo parallel environments stepped
    one after another, and ``SwarmMultiAgentVectorEnv`` (one batch, arrays (B, N, ...))."""
    from swarmscene import env as swarm_env

    rates = {}
    singles = [swarm_env.make_env(ENV_CASE) for _ in range(b)]
    batched = swarm_env.SwarmMultiAgentVectorEnv(b, ENV_CASE)
    for side in ("parallel", "batched"):
        rng = np.random.default_rng(0)
        if side == "batched":
            batched.reset(seed=0)
        else:
            for i, env in enumerate(singles):
                env.reset(seed=i)
        best = np.inf
        for _ in range(blocks):
            actions = [rng.uniform(-1, 1, (b, 6, 3)) for _ in range(steps)]
            start = time.process_time()
            for action in actions:
                if side == "batched":
                    batched.step(action)
                    continue
                for i, env in enumerate(singles):
                    if not env.agents:  # the next-step autoreset the batched side does
                        env.reset()
                        continue
                    env.step({a: action[i, int(a.rsplit("_", 1)[1])] for a in env.agents})
            best = min(best, time.process_time() - start)
        rates[side] = b * 6 * steps / best
    return rates["parallel"], rates["batched"]


def main() -> None:
    """Both parts, printed as tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer ticks and blocks (a check, not a measurement)")
    parser.add_argument("--only", nargs="*", metavar="MODEL:BxN",
                        help="the physics grid points to run (e.g. quadrotor:4096x1), and nothing else")
    parser.add_argument("--threads", type=int, default=None, metavar="K",
                        help="instead: the quadrotor batched on 1 thread and on K (dynamics.threads), wall "
                        "time, at 1 x 10,000 and the grid's points with at least 1,024 agents")
    args = parser.parse_args()
    ticks, blocks = (1, 1) if args.quick else (5, 5)
    if args.threads is not None:
        print(f"quadrotor, drone-steps per wall second, 1 thread and {args.threads} (dynamics.threads)")
        for b, n in [(1, 10_000), *((b, n) for b, n in GRID if b * n >= 1024)]:
            one, many = threads_scaling(b, n, args.threads, ticks, blocks)
            print(f"{f'{b} x {n}':>12}{one:>12.3g}{many:>12.3g}  ratio {many / one:5.2f}")
        return
    print("physics, drone-steps per CPU second (240 Hz, 10 Hz control), one core")
    print(f"{'model':<18}{'B x N':>12}{'per world':>12}{'step_batch':>12}{'+control_b':>12}{'one batch':>12}"
          f"{'ratios':>21}")
    for model_cls in (Quadrotor, DoubleIntegrator):
        for b, n in GRID:
            if args.only is not None and f"{model_cls.name}:{b}x{n}" not in args.only:
                continue
            rates = physics(model_cls, b, n, ticks, blocks)
            print(f"{model_cls.name:<18}{f'{b} x {n}':>12}" + "".join(f"{rate:>12.3g}" for rate in rates)
                  + "".join(f"{rate / rates[0]:>7.2f}" for rate in rates[1:]))
    if args.only is not None:
        return
    print("\nvector environment, agent-steps per CPU second, one core")
    for b in (16, 256):
        sync, native = vector_env(b, 3 if args.quick else 20, 1 if args.quick else 3)
        print(f"{b} worlds x 6 agents  SyncVectorEnv {sync:10.4g}  native {native:10.4g}  ratio {native / sync:5.2f}")
    print("\nmulti-agent vector environment, agent-steps per CPU second, one core")
    for b in (16, 256):
        loop, native = multi_agent_vector_env(b, 3 if args.quick else 20, 1 if args.quick else 3)
        print(f"{b} worlds x 6 agents  parallel envs in a loop {loop:10.4g}  SwarmMultiAgentVectorEnv "
              f"{native:10.4g}  ratio {native / loop:5.2f}")
    print("\nwhole runs, runs per CPU second, one core")
    seeds = list(range(4 if args.quick else 32))
    for config in (["scenario=swap", "output.summary=false"], ["output.summary=false"]):
        one, batched = whole_runs(config, seeds, 1 if args.quick else 3)
        print(f"{' '.join(config[:-1]) or 'default':<18}{len(seeds):>4} seeds  one by one {one:8.2f}  "
              f"batch {batched:8.2f}  ratio {batched / one:5.2f}")


if __name__ == "__main__":
    main()
