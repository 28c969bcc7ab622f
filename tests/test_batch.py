"""Many worlds in one step (issue #34, docs/batched.md): a world of a batch is its single run.

``api.run_batch(config, seeds)`` steps B worlds of one composition together, the dynamics of every
world in one call where the model has a batched form. Each world's result must be the single run's
bit for bit: every preset at B = 3, worlds that end early, a model without a batched form, and the
quadrotor's compiled batched step (one kernel call for all worlds' agents)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api, testing
from swarmscene.core.batch import BatchSimulation
from swarmscene.core.plugin import Dynamics
from swarmscene.methods.quadrotor.flatness import heading_vector
from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator
from swarmscene.plugins.dynamics.quadrotor import Quadrotor
from swarmscene.plugins.dynamics.single_integrator import SingleIntegrator

from .test_composition import PRESETS

WALL_CLOCK = {"wall_time", "realtime_factor", "step_ms_median", "cem.step_ms_median", "vrb.planning_ms"}
"""Metrics that time the computer, not the flight (the batch's own, in a batch)."""

SEEDS = [0, 1, 2]


def assert_world_is_its_single_run(config, seed, batched):
    alone = api.run([*config, f"seed={seed}", "output.summary=false"])
    flight = {k: v for k, v in alone.metrics.items() if k not in WALL_CLOCK}
    assert {k: v for k, v in batched.metrics.items() if k not in WALL_CLOCK} == flight, seed
    assert (alone.stop_reason, alone.error) == (batched.stop_reason, batched.error)
    assert alone.trajectory.keys() == batched.trajectory.keys()
    for key, value in alone.trajectory.items():
        np.testing.assert_array_equal(batched.trajectory[key], value, err_msg=f"seed {seed}: {key}")
    return alone


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_in_a_batch_of_three_is_its_single_runs(preset):
    """3 s of each preset (every phase of a tick, events from t = 0); the whole flights: -m slow."""
    config = [f"scenario={preset}", "clock.duration=3", "output.summary=false"]
    for seed, result in zip(SEEDS, api.run_batch(config, SEEDS), strict=True):
        assert_world_is_its_single_run(config, seed, result)


@pytest.mark.slow
@pytest.mark.parametrize("preset", PRESETS)
def test_every_whole_preset_in_a_batch_of_three_is_its_single_runs(preset):
    config = [f"scenario={preset}", "output.summary=false"]
    for seed, result in zip(SEEDS, api.run_batch(config, SEEDS), strict=True):
        assert_world_is_its_single_run(config, seed, result)


EVENT_AT_1S = {"at": 1.0, "agents": [1]}
BUILTINS_BEYOND_PRESETS: dict[tuple[str, str], tuple[list[str], list[dict] | None]] = {
    ("formation", "hex_lattice"): (["task=formation_reconfigure"], None),
    ("avoidance", "apf_navigation"): (["avoidance=apf_navigation"], None),
    ("avoidance", "cbf"): (["avoidance=cbf"], None),
    ("avoidance", "policy"): (["avoidance=policy"], None),
    ("policy", "seek_reference"): (["avoidance=policy", "avoidance.policy=seek_reference"], None),
    **{("disturbance", name): (["dynamics=quadrotor", f"disturbances=[{name}]"], None) for name in (
        "battery", "comm_delay", "constant_wind", "downwash", "drag", "dryden", "gust", "packet_loss", "radio",
        "sensing_noise")},
    ("disturbance", "ground_effect"): (["dynamics=quadrotor", "disturbances=[ground_effect]",
                                        "environment.floor=0", "swarm.start.center=[0,0,0.3]"], None),
    ("event", "comm_loss"): ([], [{**EVENT_AT_1S, "name": "comm_loss"}]),
    ("event", "drift"): ([], [{**EVENT_AT_1S, "name": "drift", "velocity": [0.3, 0.1, 0.0]}]),
    ("event", "stuck"): ([], [{**EVENT_AT_1S, "name": "stuck"}]),
    ("event", "motor_failure"): (["dynamics=quadrotor"], [{**EVENT_AT_1S, "name": "motor_failure", "rotor": 2}]),
    ("generator", "obstacle_field"): (["environment=obstacle_field"], None),
    ("observer", "swarmlab"): (["observers=[swarmlab]"], None),
}
"""Every built-in plugin that no preset composes, with a scenario that flies it: overrides of the
default scenario, and the events to set (None: the scenario's own)."""


def _composed_plugins(data: dict) -> set[tuple[str, str]]:
    """The (kind, name) of every plugin a composed scenario chooses."""
    chosen = {(kind, data[kind]["name"]) for kind in ("formation", "avoidance", "dynamics")}
    chosen |= {("disturbance", model["name"]) for model in (data.get("disturbances") or {}).values()}
    chosen |= {("event", event["name"]) for event in data.get("events") or []}
    if data["environment"].get("generator"):
        chosen.add(("generator", data["environment"]["generator"]))
    if data["avoidance"]["name"] == "policy":
        chosen.add(("policy", data["avoidance"]["policy"]))
    return chosen | {("observer", name) for name in data.get("observers") or {}}


def test_every_built_in_plugin_is_flown_in_a_batch_by_a_preset_or_below():
    """The presets (above) and :data:`BUILTINS_BEYOND_PRESETS` (below) between them choose every
    plugin the package registers, so the two batch tests cover every built-in."""
    from swarmscene.core.registry import KINDS, installed_registry

    registry = installed_registry()
    builtin = {(kind, name) for kind in KINDS if KINDS[kind].base is not None for name in registry.names(kind)}
    builtin |= {("observer", getattr(cls, "name", cls.__name__)) for cls in registry.observers}
    in_presets = set().union(*(_composed_plugins(api.compose([f"scenario={p}"])) for p in PRESETS))
    always = {("observer", "SafetyMonitor"), ("observer", "TrajectoryRecorder")}  # in every run
    assert builtin - in_presets - always - set(BUILTINS_BEYOND_PRESETS) == set()
    assert in_presets.isdisjoint(BUILTINS_BEYOND_PRESETS)  # the table lists only what presets miss


@pytest.mark.parametrize("plugin", list(BUILTINS_BEYOND_PRESETS), ids=lambda p: f"{p[0]}-{p[1]}")
def test_every_built_in_plugin_beyond_the_presets_in_a_batch_of_three_is_its_single_runs(plugin):
    """3 s of a scenario choosing the plugin (its batched form where it has one, else world by
    world), three seeds: each world is its single run, bit for bit."""
    overrides, events = BUILTINS_BEYOND_PRESETS[plugin]
    data = api.compose([*overrides, "clock.duration=3", "output.summary=false"])
    if events is not None:
        data["events"] = events
    assert plugin in _composed_plugins(data)
    assert_single_runs(data, api.run_batch(data, SEEDS))


def assert_single_runs(data: dict, results: list) -> None:
    """Each world of a batch of ``data`` (composed) under ``SEEDS``: its single run's metrics (but
    the wall clock's) and trajectory, bit for bit."""
    for seed, result in zip(SEEDS, results, strict=True):
        alone = api.run({**data, "seed": seed})
        flight = {k: v for k, v in alone.metrics.items() if k not in WALL_CLOCK}
        assert {k: v for k, v in result.metrics.items() if k not in WALL_CLOCK} == flight, seed
        for key, value in alone.trajectory.items():
            np.testing.assert_array_equal(result.trajectory[key], value, err_msg=f"seed {seed}: {key}")


def test_the_keep_out_condition_of_each_world_is_its_single_runs():
    """safety.keep_out on 100 boids (the monitor's pair list from the compiled cell list): every
    world's conflicts, first time and agents are its single run's."""
    config = ["scenario=flocking", "clock.duration=20", "safety.keep_out=[0.12,0.12,0.3]", "output.summary=false"]
    results = api.run_batch(config, SEEDS)
    assert any(result.metrics["keep_out_conflicts"] for result in results)  # not vacuous
    for seed, result in zip(SEEDS, results, strict=True):
        alone = assert_world_is_its_single_run(config, seed, result)
        np.testing.assert_array_equal(result.series["min_keep_out"], alone.series["min_keep_out"])


def test_worlds_that_end_early_are_masked_and_the_others_go_on(monkeypatch):
    """swap (single integrator, ends when complete): world 1's model raises at t = 1 s, world 2
    flies 2 s only; world 0 flies on to its completion, equal to its single run."""
    step, step_batch = SingleIntegrator.step, SingleIntegrator.step_batch
    failing = {}

    def failing_step(self, world, dt):
        if self is failing.get("model") and world.t >= 1.0:
            raise RuntimeError("rotor on fire")
        step(self, world, dt)

    def failing_step_batch(cls, models, batch, dt):
        if any(model is failing.get("model") for model in models):
            return NotImplemented  # world by world, so that world 1 raises in its own step
        return step_batch.__func__(cls, models, batch, dt)

    monkeypatch.setattr(SingleIntegrator, "step", failing_step)
    monkeypatch.setattr(SingleIntegrator, "step_batch", classmethod(failing_step_batch))
    data = api.compose(["scenario=swap", "output.summary=false"])
    sims = [api.build({**data, "seed": 0}), api.build({**data, "seed": 1}),
            api.build({**data, "seed": 2, "clock": {**data["clock"], "duration": 2.0}})]
    failing["model"] = sims[1].dynamics
    outcomes = BatchSimulation(sims).run()
    assert [o.result.stop_reason for o in outcomes] == ["complete", "plugin_error", "duration"]
    assert outcomes[1].result.error.startswith("dynamics 'single_integrator' raised in failing_step at t = 1 s: RuntimeError"), (
        outcomes[1].result.error)
    assert isinstance(outcomes[1].failure, RuntimeError) and outcomes[0].failure is None
    assert outcomes[2].result.metrics["duration"] == 2.0
    monkeypatch.undo()
    assert_world_is_its_single_run(["scenario=swap", "output.summary=false"], 0, outcomes[0].result)


def test_the_quadrotor_steps_every_world_in_one_kernel_call(monkeypatch):
    """vrb_airshow (quadrotor): one step_swarm call per physics step for the three worlds, and
    each world its single run's bits; worlds whose options differ are stepped one by one."""
    from swarmscene.methods.quadrotor import kernels

    calls = []
    kernel = kernels.step_swarm
    monkeypatch.setattr(kernels, "step_swarm", lambda *a, **k: calls.append(a[0].shape[0]) or kernel(*a, **k))
    config = ["scenario=vrb_airshow", "clock.duration=1", "output.summary=false"]
    results = api.run_batch(config, SEEDS)
    physics_step = api.compose(config)["clock"]["physics_step"]
    assert calls == [3 * results[0].metrics["agents"]] * round(1.0 / physics_step)
    monkeypatch.undo()
    for seed, result in zip(SEEDS, results, strict=True):
        assert_world_is_its_single_run(config, seed, result)


def _count_latches(monkeypatch) -> list[int]:
    """The rows of every ``latch_references`` call from now on."""
    from swarmscene.methods.quadrotor import kernels

    calls: list[int] = []
    kernel = kernels.latch_references
    monkeypatch.setattr(kernels, "latch_references", lambda *a: calls.append(a[0].shape[0]) or kernel(*a))
    return calls


def test_quadrotor_worlds_with_setpoints_of_their_own_latch_in_one_kernel_call(monkeypatch):
    """swap flown by quadrotors under sensing noise (each world's controller reads its own noisy
    estimates, not the truth): every tick one latch_references call for the three worlds' agents,
    whose setpoints differ, and each world its single run's bits."""
    config = ["scenario=swap", "dynamics=quadrotor", "swarm.n=4", "disturbances=[sensing_noise]",
              "clock.duration=2", "output.summary=false"]
    calls = _count_latches(monkeypatch)
    results = api.run_batch(config, SEEDS)
    ticks = results[0].metrics["steps"]
    assert calls == [4] * 3 + [3 * 4] * ticks  # each world's initialize, then one call per tick
    monkeypatch.undo()
    for seed, result in zip(SEEDS, results, strict=True):
        assert_world_is_its_single_run(config, seed, result)
    ends = [result.trajectory["pos"][-1] for result in results]
    assert not np.array_equal(ends[0], ends[1])  # the worlds flew apart (not vacuous)


def test_quadrotor_worlds_tuned_apart_are_controlled_one_by_one(monkeypatch):
    """Worlds whose quadrotors have different gains decline the batched control (one kernel takes
    one set of options): each world latches its own references, and is its single run."""
    data = api.compose(["scenario=vrb_airshow", "clock.duration=1", "output.summary=false"])
    worlds = [{**data, "seed": 5, "dynamics": {**data["dynamics"], "position_omega": w}} for w in (1.0, 2.0)]
    calls = _count_latches(monkeypatch)
    outcomes = BatchSimulation([api.build(world) for world in worlds]).run()
    n = outcomes[0].result.metrics["agents"]
    assert calls == [n] * (2 + 2 * outcomes[0].result.metrics["steps"])
    monkeypatch.undo()
    for world, outcome in zip(worlds, outcomes, strict=True):
        np.testing.assert_array_equal(outcome.result.trajectory["pos"], api.run(world).trajectory["pos"])


def test_lockstep_latches_quadrotor_worlds_in_one_call_as_the_batch_does(monkeypatch):
    """lockstep (the vector environment's tick) steps its worlds with the batch's stepper: three
    quadrotor worlds latched in one call per tick, each world's state its single run's after
    every tick."""
    from swarmscene.core.batch import lockstep
    from swarmscene.core.state import WorldBatch

    data = api.compose(["scenario=swap", "dynamics=quadrotor", "swarm.n=4", "output.summary=false"])
    together = [api.build({**data, "seed": seed}) for seed in SEEDS]
    alone = [api.build({**data, "seed": seed}) for seed in SEEDS]
    for sim in together + alone:
        sim.hook.swarmscene_run_start(sim=sim.view)
    calls = _count_latches(monkeypatch)
    batch = WorldBatch([sim.world for sim in together])
    for _ in range(10):
        lockstep(together, batch)
        for sim in alone:
            sim.step()
        for one, batched in zip(alone, together, strict=True):
            for field in ("pos", "vel", "quat", "omega", "rotor_speed"):
                np.testing.assert_array_equal(getattr(batched.world, field), getattr(one.world, field), err_msg=field)
    assert sorted(calls) == [4] * 30 + [12] * 10  # the single runs' latches, and one a tick for the three


def test_the_quadrotor_heading_vector_has_the_same_bits_at_every_length():
    """control_batch computes y_c = (-sin psi, cos psi, 0) over the worlds' yaws stacked, control
    over one world's: numpy's elementwise sin and cos must give each yaw the same bits at any
    array length and position (else the batched control would leave its worlds' bits)."""
    rng = np.random.default_rng(34)
    special = np.array([0.0, -0.0, np.pi, -np.pi / 2, 1e-300, 1e6, 2.0**52, 7.0, -1e-8])
    for _ in range(200):
        lengths = rng.integers(1, 40, size=rng.integers(2, 30))
        parts = [rng.choice(special, k) if rng.random() < 0.2 else rng.uniform(-1, 1, k) * 10.0 ** rng.integers(-6, 7)
                 for k in lengths]
        stacked = heading_vector(np.concatenate(parts))
        start = 0
        for part in parts:
            own = heading_vector(part)
            assert own.tobytes() == stacked[start:start + part.size].tobytes(), part
            start += part.size


def test_a_latched_value_is_the_coming_ticks_and_packed_arrays_follow_a_reallocation():
    """WorldBatch.latch gives the next tick's per_tick (and that tick's only); pack(together=True)
    checks the first name, and restacks every name when the instances reallocated them all."""
    from types import SimpleNamespace

    from swarmscene.core.state import WorldBatch, WorldState

    batch = WorldBatch([WorldState.at_rest(np.zeros((2, 3))) for _ in range(3)])
    batch.latch("k", "latched")
    assert batch.per_tick("k", lambda: "made") == "made"  # still the tick before controlled()
    batch.controlled()
    assert batch.per_tick("k", lambda: "made") == "latched"
    batch.controlled()
    assert batch.per_tick("k", lambda: "made again") == "made again"

    models = [SimpleNamespace(a=np.full(2, b), c=np.full(2, -b)) for b in range(3)]
    first = batch.pack(models, ("a", "c"), together=True)
    assert first["a"].tolist() == [[0, 0], [1, 1], [2, 2]] and models[1].a.base is first["a"]
    models[2].a[:] = 7  # in place: into the batch
    assert batch.pack(models, ("a", "c"), together=True)["a"] is first["a"] and first["a"][2].tolist() == [7, 7]
    models[1].a, models[1].c = np.full(2, 5), np.full(2, 6)  # an allocation: both rebound
    again = batch.pack(models, ("a", "c"), together=True)
    assert again["a"][1].tolist() == [5, 5] and again["c"][1].tolist() == [6, 6] and models[1].c.base is again["c"]


def test_a_quadrotor_motor_failure_in_a_batch_is_its_single_runs():
    """A rotor fault writes the hit vehicles' rotor gains into the arrays the batch packed (the
    batch checks one of the references for reallocation, not all twelve): the failing world
    and the others are their single runs, and the fault changed the flight (not vacuous)."""
    data = api.compose(["scenario=vrb_airshow", "clock.duration=2", "output.summary=false"])
    failing = {**data, "events": [{"at": 0.5, "agents": [1], "name": "motor_failure", "rotor": 2, "fraction": 0.3}]}
    outcomes = BatchSimulation([api.build({**failing, "seed": seed}) for seed in SEEDS]).run()
    for seed, outcome in zip(SEEDS, outcomes, strict=True):
        alone = api.run({**failing, "seed": seed})
        np.testing.assert_array_equal(outcome.result.trajectory["pos"], alone.trajectory["pos"])
    healthy = api.run({**data, "seed": 0}).trajectory["pos"]
    assert np.abs(outcomes[0].result.trajectory["pos"][-1, 1] - healthy[-1, 1]).max() > 1e-3


_DT, _SUBSTEPS, _N = 1.0 / 240.0, 24, 4
_START = np.column_stack([2.0 * np.arange(_N), np.zeros(_N), np.full(_N, 2.0)])


def _quadrotor_worlds() -> tuple[list, list, list]:
    """Three worlds of four quadrotors, 3 m apart, and their setpoints: TRACK references moving
    at 0.5 m/s, accelerating at 0.2 m/s^2 (the kernel moves them by tau, the time since the
    latch, so a wrong clock changes the flight)."""
    from swarmscene.core.setpoint import Mode, Setpoints
    from swarmscene.core.state import WorldState
    from swarmscene.plugin import build_context

    ctx = build_context(positions=_START, guidance_period=_SUBSTEPS * _DT, physics_step=_DT)
    worlds = [WorldState.at_rest(_START + [0.0, 3.0 * b, 0.0]) for b in range(3)]
    models = [Quadrotor(Quadrotor.Params(), ctx) for _ in worlds]
    for model, world in zip(models, worlds, strict=True):
        model.initialize(world)
    moving = [Setpoints(np.full(_N, Mode.TRACK, dtype=np.int8), w.pos.copy(), np.full((_N, 3), 0.5),
                        np.full((_N, 3), 0.2), np.zeros(_N)) for w in worlds]
    return worlds, models, moving


def _fly_alone(worlds: list, models: list, setpoints: list) -> None:
    """One tick of every world on its own: ``control``, then the sub-steps' ``step``."""
    for model, world, sp in zip(models, worlds, setpoints, strict=True):
        model.control(world, sp)
        for _ in range(_SUBSTEPS):
            model.step(world, _DT)


def _assert_same_states(worlds: list, alone: list) -> None:
    for world, one in zip(worlds, alone, strict=True):
        np.testing.assert_array_equal(world.pos, one.pos)
        np.testing.assert_array_equal(world.quat, one.quat)


def test_quadrotor_worlds_stepped_alone_after_the_batched_control_are_their_single_runs():
    """A world that ends in a sub-step's wind leaves the tick's other sub-steps to each world's
    own step, after a batched control and batched steps: each world then advances its own
    clock (tau, by which TRACK references move), not the batch's, and ends in its single run's
    bits; a later batched tick shares one clock again."""
    from swarmscene.core.state import WorldBatch

    alone, models, moving = _quadrotor_worlds()
    together, batched, _ = _quadrotor_worlds()
    batch = WorldBatch(together)
    for tick in range(3):
        _fly_alone(alone, models, moving)
        assert Quadrotor.control_batch(batched, batch, together, moving) is None
        batch.controlled()
        for j in range(_SUBSTEPS):
            if tick == 1 and j >= 5:  # from sub-step 5 of tick 1, each world on its own
                for model, world in zip(batched, together, strict=True):
                    model.step(world, _DT)
            else:
                assert Quadrotor.step_batch(batched, batch, _DT) is None
        assert len({id(model._clock) for model in batched}) == (3 if tick == 1 else 1)
        _assert_same_states(together, alone)
    assert np.all(together[0].pos[:, 0] > _START[:, 0] + 0.05)  # the references moved (TRACK, tau)


@pytest.mark.parametrize("when", ["never", "before the controllers"])
def test_quadrotor_worlds_driven_without_controlled_after_the_controllers_are_their_single_runs(when):
    """``WorldBatch.controlled`` belongs after the controllers; a driver that skips it, or calls
    it first, hands the steps the previous tick's latched references: the steps see that their
    clock is not the instances' and gather this tick's, so every world stays its single run."""
    from swarmscene.core.state import WorldBatch

    alone, models, moving = _quadrotor_worlds()
    together, batched, _ = _quadrotor_worlds()
    batch = WorldBatch(together)
    for _ in range(3):
        _fly_alone(alone, models, moving)
        if when == "before the controllers":
            batch.controlled()
        assert Quadrotor.control_batch(batched, batch, together, moving) is None
        for _ in range(_SUBSTEPS):
            assert Quadrotor.step_batch(batched, batch, _DT) is None
        _assert_same_states(together, alone)


def test_a_controller_that_raises_in_one_world_stops_that_world_only(monkeypatch):
    """A model without a batched control (the single integrator with the default one) is controlled
    world by world: world 1's control raises at t = 1 s and world 1 alone stops, named as its
    single run names it."""
    control = SingleIntegrator.control
    failing = {}
    # the model's controllers world by world (the default control_batch), as a third party's without one
    monkeypatch.setattr(SingleIntegrator, "control_batch", Dynamics.__dict__["control_batch"])

    def failing_control(self, world, sp):
        if self is failing.get("model") and world.t >= 1.0:
            raise RuntimeError("controller on fire")
        control(self, world, sp)

    monkeypatch.setattr(SingleIntegrator, "control", failing_control)
    data = api.compose(["scenario=swap", "clock.duration=3", "output.summary=false"])
    sims = [api.build({**data, "seed": seed}) for seed in SEEDS]
    failing["model"] = sims[1].dynamics
    outcomes = BatchSimulation(sims).run()
    assert [o.result.stop_reason for o in outcomes] == ["duration", "plugin_error", "duration"]
    assert outcomes[1].result.error.startswith(
        "dynamics 'single_integrator' raised in failing_control at t = 1 s: RuntimeError"), outcomes[1].result.error
    monkeypatch.undo()
    assert_world_is_its_single_run(["scenario=swap", "clock.duration=3", "output.summary=false"], 0,
                                   outcomes[0].result)


def test_a_world_the_batched_control_leaves_stops_alone_when_its_control_raises(monkeypatch):
    """The double integrator's batched control steps worlds 0 and 2 on their law together and
    leaves world 1 (whose law it cannot tell) to the engine, which runs its own ``control``: that
    raises at t = 1 s and world 1 alone stops; world 0 is its single run."""
    from swarmscene.methods.quadrotor.thesis_controllers import ThesisController

    control, steady_law, failing, grouped = DoubleIntegrator.control, ThesisController.steady_law, {}, []

    def failing_control(self, world, sp):
        if self is failing.get("model") and world.t >= 1.0:
            raise RuntimeError("controller on fire")
        control(self, world, sp)

    def law(self, mode):
        return None if self is failing["model"].controller else steady_law(self, mode)

    real = DoubleIntegrator._control_steady.__func__
    monkeypatch.setattr(DoubleIntegrator, "control", failing_control)
    monkeypatch.setattr(ThesisController, "steady_law", law)
    monkeypatch.setattr(DoubleIntegrator, "_control_steady",
                        classmethod(lambda cls, flock, *a: grouped.append(len(flock)) or real(cls, flock, *a)))
    config = ["clock.duration=3", "output.summary=false"]
    sims = [api.build({**api.compose(config), "seed": seed}) for seed in SEEDS]
    failing["model"] = sims[1].dynamics
    outcomes = BatchSimulation(sims).run()
    assert grouped and set(grouped) == {2}  # worlds 0 and 2 together, world 1 never
    assert [o.result.stop_reason for o in outcomes] == ["duration", "plugin_error", "duration"]
    assert "RuntimeError: controller on fire" in outcomes[1].result.error
    monkeypatch.undo()
    assert_world_is_its_single_run(config, 0, outcomes[0].result)


def test_a_control_batch_that_returns_a_wrong_answer_is_named():
    from swarmscene.core.batch import left_places

    assert left_places(None, 3, DoubleIntegrator) == [] and left_places([2, 0], 3, DoubleIntegrator) == [2, 0]
    for wrong in ([3], [-1], "0", [0.0], 1):
        with pytest.raises(ValueError, match=r"DoubleIntegrator.control_batch returned .*: None, NotImplemented "
                                             r"or the places \(0..2\) of the worlds it left to their own control"):
            left_places(wrong, 3, DoubleIntegrator)


def test_the_control_batch_contract_check_catches_a_batched_control_that_differs():
    class Nudged(DoubleIntegrator):
        name = "nudged_double_integrator"

        @classmethod
        def control_batch(cls, models, batch, worlds, setpoints):
            setpoints = list(setpoints)
            setpoints[1] = setpoints[1].copy()
            setpoints[1].pos += 1e-12  # world 1's target moved by a picometre
            return DoubleIntegrator.control_batch.__func__(cls, models, batch, worlds, setpoints)

    with pytest.raises(AssertionError, match="dynamics.control_batch_equals_worlds.*control_batch flew world 1 "
                                             "to another pos"):
        testing.check_dynamics(Nudged)


def _count_steady_steps(monkeypatch) -> list[int]:
    """Rows of each steady step of the thesis controller: a world's own (N rows, also inside its
    ``control``) or double_integrator's stacked one (B N rows)."""
    from swarmscene.methods.quadrotor.thesis_controllers import ThesisController

    rows: list[int] = []
    real = ThesisController.step_steady

    def counted(self, family, r, *rest):
        rows.append(len(r))
        return real(self, family, r, *rest)

    monkeypatch.setattr(ThesisController, "step_steady", counted)
    return rows


def test_double_integrator_worlds_on_one_law_are_controlled_in_one_stacked_step(monkeypatch):
    """The default scenario: at each world's first tick a law starts (each world's own control);
    at every later tick the controllers run as one stacked step over all worlds' agents; each
    world is its single run."""
    rows = _count_steady_steps(monkeypatch)
    config = ["clock.duration=3", "output.summary=false"]
    data = api.compose(config)
    outcomes = BatchSimulation([api.build({**data, "seed": seed}) for seed in SEEDS]).run()
    n, ticks = data["swarm"]["n"], int(round(3 / data["clock"]["guidance_period"]))
    assert rows == [n] * len(SEEDS) + [n * len(SEEDS)] * (ticks - 1)
    monkeypatch.undo()
    for seed, outcome in zip(SEEDS, outcomes, strict=True):
        assert_world_is_its_single_run(config, seed, outcome.result)


def test_double_integrator_worlds_tuned_apart_are_controlled_one_by_one(monkeypatch):
    rows = _count_steady_steps(monkeypatch)
    configs = [["clock.duration=2", "output.summary=false", f"dynamics.omega={omega}"] for omega in (1.5, 2.0)]
    outcomes = BatchSimulation([api.build(config) for config in configs]).run()
    assert rows and set(rows) == {api.compose(configs[0])["swarm"]["n"]}  # each world's own step
    monkeypatch.undo()
    for config, outcome in zip(configs, outcomes, strict=True):
        assert_world_is_its_single_run(config, 0, outcome.result)


def test_single_integrator_worlds_are_controlled_in_one_stacked_pass(monkeypatch):
    """swap: every tick one control_batch for the three worlds and no world's own control; each
    world its single run."""
    calls = []
    monkeypatch.setattr(SingleIntegrator, "control", lambda *a: calls.append("control"))
    config = ["scenario=swap", "clock.duration=2", "output.summary=false"]
    data = api.compose(config)
    real = SingleIntegrator.control_batch.__func__
    monkeypatch.setattr(SingleIntegrator, "control_batch",
                        classmethod(lambda cls, models, *a: calls.append(len(models)) or real(cls, models, *a)))
    outcomes = BatchSimulation([api.build({**data, "seed": seed}) for seed in SEEDS]).run()
    assert calls and set(calls) == {len(SEEDS)}
    monkeypatch.undo()
    for seed, outcome in zip(SEEDS, outcomes, strict=True):
        assert_world_is_its_single_run(config, seed, outcome.result)


def test_orca_adjusts_every_world_in_one_pass_of_its_numerics(monkeypatch):
    """swap (ORCA): one new_velocities call a tick for all worlds' agents, each world its single run."""
    import swarmscene.plugins.avoidance.orca as orca_plugin

    calls = []
    real = orca_plugin.new_velocities
    monkeypatch.setattr(orca_plugin, "new_velocities", lambda pos, *a: calls.append(len(pos)) or real(pos, *a))
    data = api.compose(["scenario=swap", "clock.duration=2", "output.summary=false"])
    outcomes = BatchSimulation([api.build({**data, "seed": seed}) for seed in SEEDS]).run()
    n = data["swarm"]["n"]
    assert calls and set(calls) == {n * len(SEEDS)}  # every tick, every world's agents at once
    for seed, outcome in zip(SEEDS, outcomes, strict=True):
        assert_world_is_its_single_run(["scenario=swap", "clock.duration=2", "output.summary=false"], seed,
                                       outcome.result)


def test_orca_worlds_tuned_apart_are_adjusted_one_by_one(monkeypatch):
    """World 1 considers fewer neighbours (a neighbour table of another width): orca declines the
    batch before touching a world, and each world is its single run."""
    import swarmscene.plugins.avoidance.orca as orca_plugin

    calls = []
    real = orca_plugin.new_velocities
    monkeypatch.setattr(orca_plugin, "new_velocities", lambda pos, *a: calls.append(len(pos)) or real(pos, *a))
    configs = [["scenario=swap", "clock.duration=2", "output.summary=false", f"avoidance.max_neighbours={k}"]
               for k in (10, 3)]
    outcomes = BatchSimulation([api.build(config) for config in configs]).run()
    assert calls and set(calls) == {api.compose(configs[0])["swarm"]["n"]}  # world by world
    for config, outcome in zip(configs, outcomes, strict=True):
        assert_world_is_its_single_run(config, 0, outcome.result)


def test_the_adjust_batch_contract_check_catches_a_batched_avoidance_that_differs():
    from swarmscene.plugins.avoidance.orca import Orca

    class Nudged(Orca):
        name = "nudged_orca"

        @classmethod
        def adjust_batch(cls, avoidances, worlds, sensings, setpoints):
            out = Orca.adjust_batch.__func__(cls, avoidances, worlds, sensings, setpoints)
            out[1].vel[0] += 1e-12  # world 1's first agent one picometre per second faster
            return out

    with pytest.raises(AssertionError, match="avoidance.adjust_batch_equals_worlds.*adjust_batch gave world 1 "
                                             "other setpoints \\(vel\\)"):
        testing.check_avoidance(Nudged)


def test_the_batch_contract_check_catches_a_batched_form_that_differs():
    class Rounded(DoubleIntegrator):
        name = "rounded_double_integrator"

        @classmethod
        def step_batch(cls, models, batch, dt):
            DoubleIntegrator.step_batch.__func__(cls, models, batch, dt)
            batch.pos[1] += 1e-12  # world 1 drifts by one part in 10^12

    with pytest.raises(AssertionError, match="dynamics.batch_equals_worlds.*step_batch gave world 1 another pos"):
        testing.check_dynamics(Rounded)


def test_worlds_that_cannot_share_the_physics_are_refused_in_one_line():
    data = api.compose(["scenario=swap"])
    sims = [api.build({**data, "seed": 0}), api.build({**data, "swarm": {**data["swarm"], "n": 4}})]
    with pytest.raises(ValueError, match=r"^world 1 cannot share the batch's physics: its swarm.n is 4, world 0's"):
        BatchSimulation(sims)


def test_quadrotor_worlds_under_wind_with_different_options_are_their_single_runs():
    """vrb_airshow under Dryden turbulence, the worlds' position loops tuned apart: the quadrotor
    declines the batch (its kernel takes one set of gains) and each world is stepped alone."""
    data = api.compose(["scenario=vrb_airshow", "clock.duration=1", "disturbances=[dryden]", "output.summary=false"])
    omegas = [1.0, 1.5, 2.0]
    worlds = [{**data, "seed": 5, "dynamics": {**data["dynamics"], "position_omega": w}} for w in omegas]
    outcomes = BatchSimulation([api.build(world) for world in worlds]).run()
    for world, outcome in zip(worlds, outcomes, strict=True):
        alone = api.run(world)
        np.testing.assert_array_equal(outcome.result.trajectory["pos"], alone.trajectory["pos"])
    assert not np.array_equal(outcomes[0].result.trajectory["pos"], outcomes[2].result.trajectory["pos"])
    same = api.run_batch({**data, "seed": 5}, [5, 6])  # one set of gains: batched, under the wind
    np.testing.assert_array_equal(same[1].trajectory["pos"], api.run({**data, "seed": 6}).trajectory["pos"])


def test_a_batch_writes_each_worlds_run_directory_as_a_single_run_does(tmp_path):
    """output_dir/<b>: config.yaml and trajectory.npz byte for byte, metrics but the timing ones."""
    import json

    config = ["scenario=swap", "clock.duration=2", "output.summary=false"]
    api.run_batch(config, [4, 9], output_dir=tmp_path / "batch")
    for b, seed in enumerate([4, 9]):
        api.run([*config, f"seed={seed}"], output_dir=tmp_path / f"alone{b}")
        batch, alone = tmp_path / "batch" / str(b), tmp_path / f"alone{b}"
        for name in ("config.yaml", "trajectory.npz"):
            assert (batch / name).read_bytes() == (alone / name).read_bytes(), name
        flight = [{k: v for k, v in json.loads((d / "metrics.json").read_text()).items() if k not in WALL_CLOCK}
                  for d in (batch, alone)]
        assert flight[0] == flight[1]


def test_a_batch_refuses_the_per_run_views_in_one_line():
    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        api.run_batch(["scenario=swap", "output.plots=true"], [0, 1])
    assert err.value.lines == ["output.plots=true: not written by a batch of worlds (run that world alone)"]


class _HalfCommand(DoubleIntegrator):
    """A subclass that overrides ``control`` alone: half its base's command."""

    name = "half_command"

    def control(self, world, sp):
        super().control(world, sp)
        self.u *= 0.5


class _HalfVelocity(SingleIntegrator):
    """A subclass that overrides ``control`` alone: half its base's velocity command."""

    name = "half_velocity"
    xfail_checks = {"dynamics.velocity_mode": "flies half the commanded velocity"}

    def control(self, world, sp):
        super().control(world, sp)
        self.u = self.u * 0.5


class _HalfStep(SingleIntegrator):
    """A subclass that overrides ``step`` alone: it flies half the command."""

    name = "half_step"
    xfail_checks = {"dynamics.velocity_mode": "flies half the commanded velocity"}

    def step(self, world, dt):
        world.pos += 0.5 * self.u * dt
        world.vel[:] = 0.5 * self.u


class _TurnedHeading(Quadrotor):
    """A subclass that overrides ``control`` alone and rebinds a reference array (a new heading,
    turned 0.3 rad), as the base's ``control`` no longer does: its worlds' packed references must
    be checked name by name, not through the first name only."""

    name = "turned_heading"

    def control(self, world, sp):
        super().control(world, sp)
        self._heading = heading_vector(np.asarray(sp.yaw, dtype=float) + 0.3)


@pytest.mark.parametrize(("scenario", "subclass"), [("default", _HalfCommand), ("swap", _HalfVelocity),
                                                    ("swap", _HalfStep), ("vrb_airshow", _TurnedHeading)])
def test_a_subclass_overriding_the_per_world_form_alone_is_flown_by_it(scenario, subclass):
    """Its base's batched form was written for the base's ``control`` (``step``): the subclass's
    worlds in a batch are controlled (stepped) by their own, each world its single run."""
    from swarmscene.core.batch import written_for

    single = {_HalfCommand: "control", _HalfVelocity: "control", _HalfStep: "step", _TurnedHeading: "control"}[subclass]
    assert written_for(subclass.__base__, f"{single}_batch", single)
    assert not written_for(subclass, f"{single}_batch", single)
    data = api.compose([f"scenario={scenario}", "clock.duration=2", "output.summary=false"])

    def built(seed):
        sim = api.build({**data, "seed": seed})
        sim.dynamics.__class__ = subclass
        return sim

    for seed, outcome in zip(SEEDS, BatchSimulation([built(seed) for seed in SEEDS]).run(), strict=True):
        alone = built(seed).run()
        assert outcome.result.metrics["min_separation"] == alone.metrics["min_separation"]
        np.testing.assert_array_equal(outcome.result.trajectory["pos"], alone.trajectory["pos"])
    plain = api.build({**data, "seed": SEEDS[-1]}).run()
    assert not np.array_equal(plain.trajectory["pos"], alone.trajectory["pos"])  # the subclass flies apart
    testing.check_dynamics(subclass)  # the batched forms' checks pass as the engine flies them


def test_an_avoidance_subclass_overriding_adjust_alone_is_adjusted_by_it():
    from swarmscene.core.batch import written_for
    from swarmscene.plugins.avoidance.orca import Orca

    class Wrapped(Orca):
        def adjust(self, world, sensing, sp):
            return super().adjust(world, sensing, sp)

    assert written_for(Orca, "adjust_batch", "adjust") and not written_for(Wrapped, "adjust_batch", "adjust")


def test_the_dryden_wind_of_every_world_is_asked_at_once_each_its_single_run(monkeypatch):
    """``dryden``'s ``air_batch`` in three quadrotor worlds (their own seeds, so their own
    turbulence): it answers for all of them at every physics step but the first (where each world
    starts its filters alone), and each world is its single run, bit for bit."""
    from swarmscene.plugins.disturbance.dryden import Dryden

    air_batch = Dryden.air_batch.__func__
    answered: list[bool] = []

    def spy(cls, models, worlds, t):
        airs = air_batch(cls, models, worlds, t)
        answered.append(airs is not NotImplemented and len(airs) == len(models) == len(SEEDS))
        return airs

    monkeypatch.setattr(Dryden, "air_batch", classmethod(spy))
    data = api.compose(["dynamics=quadrotor", "disturbances=[dryden]", "disturbances.dryden.field=independent",
                        "clock.duration=2", "output.summary=false"])
    results = api.run_batch(data, SEEDS)
    steps = results[0].metrics["steps"] * round(data["clock"]["guidance_period"] / data["clock"]["physics_step"])
    assert answered == [False] + [True] * (steps - 1)
    monkeypatch.undo()
    assert_single_runs(data, results)
