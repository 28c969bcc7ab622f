"""SetpointBatch: B worlds' setpoints as one stacked record, read whole by the quadrotor's
batched controller (the same bits as its records stacked), handed from the ``policy``
avoidance's batched form to the controllers by the engine."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene import env as swarm_env
from swarmscene.core.setpoint import Mode, SetpointBatch, Setpoints
from swarmscene.core.state import WorldBatch, WorldState
from swarmscene.plugin import build_context
from swarmscene.plugins.dynamics.quadrotor import Quadrotor

from .test_batch import assert_single_runs

B, N, SUBSTEPS, DT = 3, 4, 24, 1 / 240
SEEDS = [0, 1, 2]


def stacked_record(rows: int, seed: int = 0, feedforward: bool = False) -> Setpoints:
    """``rows`` agents' setpoints in every mode, moving references, headings of their own."""
    rng = np.random.default_rng(seed)
    mode = rng.permutation(np.resize(np.array([int(m) for m in Mode], dtype=np.int8), rows))
    pos = rng.uniform(-1, 1, (rows, 3)) + [0.0, 0.0, 2.0]
    jerk, snap = (rng.normal(0, 0.1, (rows, 3)), rng.normal(0, 0.1, (rows, 3))) if feedforward else (None, None)
    return Setpoints(mode, pos, rng.normal(0, 0.5, (rows, 3)), rng.normal(0, 0.2, (rows, 3)),
                     rng.uniform(-np.pi, np.pi, rows), jerk, snap)


def test_a_world_of_a_setpoint_batch_is_its_rows_of_the_stacked_record():
    whole = stacked_record(B * N, feedforward=True)
    batch = SetpointBatch(whole, B)
    assert len(batch) == B
    for b in range(B):
        rows = slice(b * N, (b + 1) * N)
        for field in ("mode", "pos", "vel", "acc", "yaw", "jerk", "snap"):
            np.testing.assert_array_equal(getattr(batch[b], field), getattr(whole, field)[rows])
            assert np.shares_memory(getattr(batch[b], field), getattr(whole, field)), field
    assert batch[1] is batch[1] and batch[-1] is batch[B - 1] and list(batch)[0] is batch[0]
    assert batch[1:] == [batch[1], batch[2]]
    batch[1].pos[0] = 9.0  # an edit in place is the stacked record's
    np.testing.assert_array_equal(whole.pos[N], [9.0, 9.0, 9.0])
    assert batch.whole() is whole
    with pytest.raises(IndexError, match="world 3 of a setpoint batch of 3"):
        batch[3]


def test_a_replaced_attribute_of_a_world_withholds_the_whole_record():
    batch = SetpointBatch(stacked_record(B * N), B)
    batch[2].vel = np.zeros((N, 3))
    assert batch.whole() is None
    assert np.array_equal(batch[2].vel, np.zeros((N, 3)))  # the world's record keeps what it was given


@pytest.mark.parametrize("worlds", [0, 5])
def test_a_setpoint_batch_of_unequal_worlds_is_refused_in_one_line(worlds):
    with pytest.raises(ValueError, match=f"a setpoint batch of 12 agents cannot hold {worlds} worlds of equal size"):
        SetpointBatch(stacked_record(B * N), worlds)


def quadrotor_worlds() -> tuple[list[WorldState], list[Quadrotor], WorldBatch]:
    """Three worlds of four quadrotors at rest, 3 m apart, agent 1 of world 2 failed."""
    start = np.column_stack([np.arange(N) * 2.0, np.zeros(N), np.full(N, 2.0)])
    ctx = build_context(positions=start, guidance_period=SUBSTEPS * DT, physics_step=DT)
    worlds = [WorldState.at_rest(start + [0.0, 3.0 * b, 0.0]) for b in range(B)]
    worlds[2].healthy[1] = False
    models = [Quadrotor(Quadrotor.Params(), ctx) for _ in worlds]
    for model, world in zip(models, worlds, strict=True):
        model.initialize(world)
    return worlds, models, WorldBatch(worlds)


class Unread(SetpointBatch):
    """A batch whose worlds may not be read one by one: control_batch must take it whole."""

    def __getitem__(self, b):
        raise AssertionError("the batch was read world by world")


def fly(setpoints_of_tick) -> list[WorldState]:
    """Three ticks of the worlds batched: ``control_batch``, then ``step_batch``."""
    worlds, models, batch = quadrotor_worlds()
    for tick in range(3):
        assert Quadrotor.control_batch(models, batch, worlds, setpoints_of_tick(tick)) is None
        batch.controlled()
        for _ in range(SUBSTEPS):
            assert Quadrotor.step_batch(models, batch, DT) is None
    return worlds


def fly_alone(setpoints_of_tick) -> list[WorldState]:
    """Three ticks of each world on its own: ``control``, then ``step`` (the single runs)."""
    worlds, models, _ = quadrotor_worlds()
    for tick in range(3):
        for model, world, sp in zip(models, worlds, setpoints_of_tick(tick), strict=True):
            model.control(world, sp)
            for _ in range(SUBSTEPS):
                model.step(world, DT)
    return worlds


@pytest.mark.parametrize("feedforward", [False, True], ids=["plain", "jerk-snap"])
def test_the_quadrotor_reads_a_setpoint_batch_whole_with_each_worlds_single_run_bits(feedforward):
    """Every mode, a failed agent, references moving, in float32 and int64 as a plugin may give
    them: flown from the batch read whole, each world has its single run's bits."""

    def record(tick: int) -> Setpoints:
        sp = stacked_record(B * N, seed=tick, feedforward=feedforward)
        sp.mode, sp.pos = sp.mode.astype(np.int64), sp.pos.astype(np.float32)
        return sp

    def as_list(tick: int) -> list[Setpoints]:
        return list(SetpointBatch(record(tick), B))

    whole, listed = fly(lambda tick: Unread(record(tick), B)), fly_alone(as_list)
    for a, b in zip(whole, listed, strict=True):
        for field in ("pos", "vel", "quat", "omega", "rotor_speed"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    assert np.linalg.norm(whole[0].pos - quadrotor_worlds()[0][0].pos, axis=1).min() > 1e-3  # every agent moved


def test_a_world_whose_record_was_replaced_is_flown_by_the_replacement():
    """A batch one of whose worlds' attributes was replaced after it was made: the controller
    falls back to the records, which hold the replacement (each world its single run's bits)."""

    def replaced(tick: int) -> list[Setpoints] | SetpointBatch:
        batch = SetpointBatch(stacked_record(B * N, seed=tick), B)
        batch[1].pos = batch[1].pos + 1.0
        return batch

    def as_list(tick: int) -> list[Setpoints]:
        records = [Setpoints(*(None if a is None else a.copy() for a in (sp.mode, sp.pos, sp.vel, sp.acc, sp.yaw)))
                   for sp in SetpointBatch(stacked_record(B * N, seed=tick), B)]
        records[1].pos += 1.0
        return records

    for a, b in zip(fly(replaced), fly_alone(as_list), strict=True):
        np.testing.assert_array_equal(a.pos, b.pos)


def test_the_policy_hands_its_setpoint_batch_to_the_quadrotors_batched_control(monkeypatch):
    """The multi-agent vector environment on quadrotors: every tick the ``policy`` avoidance's
    batch reaches ``control_batch`` whole, and every world is its single environment's."""
    given: list[type] = []
    control_batch = Quadrotor.control_batch.__func__

    def spy(cls, models, batch, worlds, setpoints):
        given.append(type(setpoints))
        return control_batch(cls, models, batch, worlds, setpoints)

    monkeypatch.setattr(Quadrotor, "control_batch", classmethod(spy))
    data = api.compose(["events=lead_fails", "clock.duration=1.2", "swarm.start.layout=random", "dynamics=quadrotor"])
    data["events"][0]["at"] = 0.3
    envs = swarm_env.SwarmMultiAgentVectorEnv(B, data)
    singles = [swarm_env.make_env(data) for _ in range(B)]
    obs, _ = envs.reset(seed=3)
    for b, env in enumerate(singles):
        env.reset(seed=3 + b)
    rng = np.random.default_rng(0)
    for _ in range(8):
        actions = rng.uniform(-1, 1, envs.action_space.shape)
        obs, rewards, *_ = envs.step(actions)
        for b, env in enumerate(singles):
            index = {a: i for i, a in enumerate(env.possible_agents)}
            o, r, *_ = env.step({a: actions[b, index[a]] for a in env.agents})
            for a in o:
                np.testing.assert_array_equal(obs[b, index[a]], o[a])
                assert rewards[b, index[a]] == r[a]
    envs.close()
    assert given == [SetpointBatch] * 8


def test_a_formations_setpoint_batch_reaches_the_quadrotors_control_whole(monkeypatch):
    """The default scenario on quadrotors with no avoidance, its leader failing mid-run (the
    slots are reassigned): every tick ``static_shape`` plans the three worlds in one call, its
    batch passes ``none`` as it is and reaches ``control_batch`` whole, and every world is its
    single run."""
    from swarmscene.plugins.formation.static_shape import StaticShape

    given: list[type] = []
    control_batch, setpoints_batch = Quadrotor.control_batch.__func__, StaticShape.setpoints_batch.__func__

    def spy(cls, models, batch, worlds, setpoints):
        given.append(type(setpoints))
        return control_batch(cls, models, batch, worlds, setpoints)

    planned: list[int] = []
    monkeypatch.setattr(Quadrotor, "control_batch", classmethod(spy))
    monkeypatch.setattr(StaticShape, "setpoints_batch", classmethod(
        lambda cls, formations, *rest: planned.append(len(formations)) or setpoints_batch(cls, formations, *rest)))
    data = api.compose(["dynamics=quadrotor", "avoidance=none", "events=lead_fails", "swarm.start.layout=random",
                        "clock.duration=3", "output.summary=false"])
    data["events"][0]["at"] = 1.0
    results = api.run_batch(data, SEEDS)
    ticks = results[0].metrics["steps"]
    assert given == [SetpointBatch] * ticks and planned == [B] * ticks
    monkeypatch.undo()
    assert_single_runs(data, results)
    assert results[0].metrics["healthy_at_end"] == results[0].metrics["agents"] - 1  # the leader failed


@pytest.mark.parametrize(("answer", "error"), [
    (lambda formations: (_ for _ in ()).throw(FloatingPointError("non-finite slot")), "non-finite slot"),
    (lambda formations: [None] * (len(formations) - 1), "StaticShape.setpoints_batch returned 2 setpoints for 3 worlds"),
], ids=["raises", "wrong-count"])
def test_a_batched_formation_that_raises_or_miscounts_stops_every_world_with_its_error(monkeypatch, answer, error):
    """The batched form's exception (or its answer of the wrong length, named) is every world's
    failure, at the same tick: the form answered for all of them."""
    from swarmscene.core.batch import BatchSimulation
    from swarmscene.plugins.formation.static_shape import StaticShape

    monkeypatch.setattr(StaticShape, "setpoints_batch", classmethod(lambda cls, formations, *rest: answer(formations)))
    data = api.compose(["clock.duration=2", "output.summary=false"])
    outcomes = BatchSimulation([api.build({**data, "seed": seed}) for seed in SEEDS]).run()
    assert [str(outcome.failure) for outcome in outcomes] == [error] * B
    assert {outcome.result.metrics["steps"] for outcome in outcomes} == {0}


def test_records_stack_into_a_batch_whose_worlds_are_theirs_and_mismatches_are_refused():
    records = [Setpoints.hold(np.full((N, 3), float(b))) for b in range(B)]
    batch = SetpointBatch.stack(records)
    for b, record in enumerate(records):
        np.testing.assert_array_equal(batch[b].pos, record.pos)
        assert batch[b].jerk is None
    with pytest.raises(ValueError, match=r"a setpoint batch stacks records of one size, not \[2, 4\]"):
        SetpointBatch.stack([*records, Setpoints.hold(np.zeros((2, 3)))])
    records[1].jerk = np.zeros((N, 3))
    with pytest.raises(ValueError, match="a setpoint batch stacks records that all carry jerk, or none"):
        SetpointBatch.stack(records)
    with pytest.raises(ValueError, match=r"not \[\]"):
        SetpointBatch.stack([])


@pytest.mark.parametrize(("overrides", "batched"), [
    (["avoidance=cbf"], True),
    (["avoidance=cbf", "avoidance.power=3"], False),
    (["scenario=swap", "avoidance=cbf", "avoidance.deadlock_turn=90", "swarm.n=6"], True),
], ids=["pillar", "power-3-declined", "swap-deadlock-turn"])
def test_the_certificates_filter_every_world_in_one_pass_each_its_single_run(monkeypatch, overrides, batched):
    """``cbf``'s batched form near the default scenario's pillar (obstacle half-planes from each
    world's sensing) and in a 6-agent swap escaping deadlocks: one ``safe_velocities`` call a tick
    for the three worlds' agents, each world its single run's bits; with ``power = 3`` it
    declines (numpy's power) and the worlds are filtered one by one, as their single runs."""
    from swarmscene.methods.baselines import cbf as numerics
    from swarmscene.plugins.avoidance import cbf as plugin

    rows: list[int] = []
    safe_velocities = numerics.safe_velocities
    monkeypatch.setattr(plugin, "safe_velocities", lambda pos, *a, **k: rows.append(len(pos)) or safe_velocities(
        pos, *a, **k))
    data = api.compose([*overrides, "clock.duration=4", "output.summary=false"])
    results = api.run_batch(data, SEEDS)
    n, ticks = results[0].metrics["agents"], results[0].metrics["steps"]
    assert rows == ([B * n] * ticks if batched else [n] * (B * ticks))
    monkeypatch.undo()
    assert_single_runs(data, results)


def test_the_potential_field_repels_every_world_in_one_pass_each_its_single_run(monkeypatch):
    """``potential``'s batched form in the default scenario among a field of obstacles (their
    repulsion from each world's sensing, from t = 2.3 s), from a random start (pairs within range
    from the first tick) and with the leader failing mid-run: every tick one call for the three
    worlds, answering one batch whose rows are each world's own ``adjust`` (the failed leader's
    untouched, though others are in its range); each world its single run's bits."""
    from swarmscene.plugins.avoidance.potential import Potential

    adjust_batch = Potential.adjust_batch.__func__
    near_failed: list[bool] = []
    repelled: list[bool] = []

    def spy(cls, avoidances, worlds, sensings, setpoints):
        given = [sp.copy() for sp in setpoints]
        answer = adjust_batch(cls, avoidances, worlds, sensings, setpoints)
        assert isinstance(answer, SetpointBatch)
        for a, world, sensing, sp, out in zip(avoidances, worlds, sensings, given, answer, strict=True):
            own = a.adjust(world, sensing, sp)
            for key in ("mode", "pos", "vel", "acc", "yaw"):
                np.testing.assert_array_equal(getattr(out, key), getattr(own, key), err_msg=key)
            failed = np.flatnonzero(~world.healthy)
            near_failed.append(bool(np.isin(sensing.pairs(a._range()), failed).any()))
            repelled.append(a._obstacle_repulsion(world, sensing) is not None)
        return answer

    monkeypatch.setattr(Potential, "adjust_batch", classmethod(spy))
    data = api.compose(["environment=obstacle_field", "events=lead_fails", "swarm.start.layout=random",
                        "clock.duration=4", "output.summary=false"])
    data["events"][0]["at"] = 1.0
    results = api.run_batch(data, SEEDS)
    assert len(near_failed) == B * results[0].metrics["steps"] and any(near_failed) and any(repelled)
    monkeypatch.undo()
    assert_single_runs(data, results)
    assert results[0].metrics["healthy_at_end"] == results[0].metrics["agents"] - 1  # the leader failed


def answers_of_setpoints_batch(monkeypatch, formation: type) -> list[type]:
    """The type of every answer ``formation.setpoints_batch`` gives while the monkeypatch holds."""
    setpoints_batch = formation.setpoints_batch.__func__
    answers: list[type] = []

    def spy(cls, formations, worlds, sensings):
        answer = setpoints_batch(cls, formations, worlds, sensings)
        answers.append(type(answer))
        return answer

    monkeypatch.setattr(formation, "setpoints_batch", classmethod(spy))
    return answers


@pytest.mark.parametrize("overrides", [
    ["events=random_failure"],
    ["formation.space=bounded", "formation.planar=false", "formation.goal=[60,40,30]", "formation.goal_weight=0.3"],
], ids=["torus-failure", "bounded-goal-3d"])
def test_the_flocks_of_every_world_turn_in_one_pass_each_its_single_run(monkeypatch, overrides):
    """``reynolds_flocking``'s batched form on the flocking preset: in its torus with a boid of
    each world failing at its own drawn time (failed boids keep their heading and are not
    followed), and in a bounded 3-D box seeking a goal. Every tick one call for the three worlds
    answers one batch; each world is its single run, bit for bit."""
    from swarmscene.plugins.formation.reynolds_flocking import ReynoldsFlocking

    answers = answers_of_setpoints_batch(monkeypatch, ReynoldsFlocking)
    data = api.compose(["scenario=flocking", *overrides, "clock.duration=25", "output.summary=false"])
    results = api.run_batch(data, SEEDS)
    assert answers == [SetpointBatch] * results[0].metrics["steps"]
    monkeypatch.undo()
    assert_single_runs(data, results)
    if overrides == ["events=random_failure"]:
        assert [r.metrics["healthy_at_end"] for r in results] == [99] * B  # each world lost a boid
        assert len({r.metrics["events.0.at"] for r in results}) == B  # at its own time


@pytest.mark.parametrize("overrides", [
    ["events=random_failure", "clock.duration=21"],
    ["dynamics=quadrotor", "formation.reassign=every_tick", "formation.formation_timeout=3", "clock.duration=12"],
], ids=["failure", "quadrotor-every-tick"])
def test_the_lattices_of_every_world_are_planned_in_one_pass_each_its_single_run(monkeypatch, overrides):
    """``hex_lattice``'s batched form on the suite's ``formation_reconfigure`` (noisy positions
    from mocap, so each world perceives its own): with a vehicle of each world failing at its own
    drawn time (the slots reassigned), and on quadrotors (the leader's applied input as
    feed-forward) re-assigning every tick, the leader setting off at its timeout. Every tick one
    call for the three worlds answers one batch; each world is its single run, bit for bit."""
    from swarmscene.plugins.formation.hex_lattice import HexLattice

    answers = answers_of_setpoints_batch(monkeypatch, HexLattice)
    data = api.compose(["task=formation_reconfigure", *overrides, "output.summary=false"])
    results = api.run_batch(data, SEEDS)
    assert answers == [SetpointBatch] * max(r.metrics["steps"] for r in results)
    monkeypatch.undo()
    assert_single_runs(data, results)
    if "events=random_failure" in overrides:
        assert [r.metrics["healthy_at_end"] for r in results] == [7] * B  # each world lost a vehicle
    else:
        assert all(r.metrics["hex.leader_start"] is not None for r in results)  # the leader set off
