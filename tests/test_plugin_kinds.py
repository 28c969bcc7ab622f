"""The kinds beside the three algorithms (disturbance model, event kind, map generator, policy,
observer): one registry and one choice check for all, the contract checks every built-in passes
and that refuse a broken plugin rule by rule, the templates, and a third-party package that
registers one of every kind and runs."""

from __future__ import annotations

import importlib
import inspect
import re
import types
import warnings
from pathlib import Path

import numpy as np
import pytest
from pydantic import Field
from shapely.geometry import Point as ShapelyPoint
from shapely.geometry import box

from swarmscene import api, testing
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core import hookspecs
from swarmscene.core import registry as registry_module
from swarmscene.core.registry import KINDS, make_plugin_manager, validate_choice
from swarmscene.plugin import (
    Disturbance,
    DisturbanceParams,
    EventKindPlugin,
    EventParams,
    MapGenerator,
    Motion,
    PluginParams,
    Policy,
    StrictModel,
    hookimpl,
)

ROOT = Path(__file__).resolve().parents[1]
_, REGISTRY = api.plugins()
EVENT_OPTIONS = {"drift": {"velocity": [0.2, 0.0, 0.0]}, "motor_failure": {"rotor": 1}}
GENERATOR_OPTIONS = {"corridor": {"width": 1.0}, "obstacle_field": {"density": 0.05, "radius": 1.0}}
CHECKS = {"disturbance": testing.check_disturbance, "event": testing.check_event_kind,
          "generator": testing.check_generator, "policy": testing.check_policy}


# -- one registry, one choice check --------------------------------------------------------------
def test_every_kind_registers_through_its_own_hook():
    assert set(KINDS) == {"formation", "avoidance", "dynamics", "observer", "disturbance", "event",
                          "generator", "policy"}
    for kind, spec in KINDS.items():
        assert spec.hook.startswith("swarmscene_register_") and hasattr(hookspecs, spec.hook), kind
    assert REGISTRY.names("disturbance") == ["battery", "comm_delay", "constant_wind", "downwash", "drag", "dryden",
                                             "ground_effect", "gust", "packet_loss", "radio", "sensing_noise"]
    assert REGISTRY.names("event") == ["comm_loss", "drift", "hover", "motor_failure", "stuck"]
    assert REGISTRY.names("generator") == ["building", "corridor", "obstacle_field"]
    assert REGISTRY.names("policy") == ["seek_reference"]
    assert REGISTRY.sources[("disturbance", "dryden")] == "swarmscene.plugins.disturbance.dryden"


@pytest.mark.parametrize("overrides, line", [
    (["formation.name=spiral"], "formation.name: unknown formation 'spiral' (valid: antipodal_swap, "),
    (["+disturbances.x.name=hurricane"], "disturbances.x.name: unknown disturbance model 'hurricane' (valid: "
                                         "battery, comm_delay, constant_wind, downwash, drag, dryden, ground_effect, "
                                         "gust, packet_loss, radio, sensing_noise)"),
    (["events=drift", "events.0.name=explode"], "events.0.name: unknown event kind 'explode' (valid: comm_loss, "
                                                "drift, hover, motor_failure, stuck)"),
    (["+environment.generator=maze"], "environment.generator: unknown map generator 'maze' (valid: building, "
                                      "corridor, obstacle_field)"),
    (["avoidance=policy", "avoidance.policy=nope"], "avoidance.policy: unknown policy 'nope' (valid: seek_reference)"),
])
def test_an_unknown_name_of_any_kind_is_one_line_in_one_format(overrides, line):
    with pytest.raises(Exception) as exc:
        api.load(overrides, REGISTRY)
    lines = exc.value.lines
    assert len(lines) == 1 and lines[0].startswith(line), lines


def test_validate_choice_returns_the_class_or_appends_one_line():
    errors: list[str] = []
    assert validate_choice(REGISTRY, "event", "hover", "events.0.name", errors).name == "hover"
    assert validate_choice(REGISTRY, "policy", 3, "avoidance.policy", errors) is None
    assert errors == ["avoidance.policy: unknown policy 3 (valid: seek_reference)"]


def test_a_policy_option_is_checked_by_the_policy_params():
    with pytest.raises(Exception) as exc:
        api.load(["avoidance=policy", "+avoidance.policy_options.radius=0"], REGISTRY)
    assert exc.value.lines == ["avoidance.policy_options.radius: must be > 0.0 (got 0)"]


# -- the built-ins pass their checks ---------------------------------------------------------------
@pytest.mark.parametrize("kind, name", [(k, n) for k in CHECKS for n in REGISTRY.names(k)])
def test_every_builtin_passes_its_contract_check(kind, name):
    options = {"event": EVENT_OPTIONS, "generator": GENERATOR_OPTIONS}.get(kind, {}).get(name)
    CHECKS[kind](REGISTRY.get(kind, name), options)


@pytest.mark.parametrize("observer", REGISTRY.observers, ids=lambda c: c.__name__)
def test_every_builtin_observer_passes_its_contract_check(observer):
    testing.check_observer(observer)


@pytest.mark.parametrize("kind", ["disturbance", "event", "generator", "policy", "observer"])
def test_each_template_is_a_working_plugin(kind):
    """A copy of plugins/<kind>/_template.py runs as is: it registers one class, which passes the
    contract check of its kind."""
    module = importlib.import_module(f"swarmscene.plugins.{kind}._template")
    hook = getattr(module, KINDS[kind].hook)
    registered: list[type] = []
    hook(registered.append)
    (cls,) = registered
    check = {"event": testing.check_event_kind}.get(kind) or getattr(testing, f"check_{kind}")
    check(cls)


# -- each rule, broken -----------------------------------------------------------------------------
class _Bias(Disturbance):
    name = "bias"
    phase = "sense"

    class Params(DisturbanceParams):
        std: float = Field(0.1, ge=0, description="m")

    def sense(self, world, pos, vel):
        return pos + self.rng.normal(0.0, self.params.std, pos.shape), vel


def _variant(base, **members):
    return type(base.__name__ + "Broken", (base,), members)


def test_the_disturbance_check_refuses_each_broken_rule():
    testing.check_disturbance(_Bias)  # the unbroken model passes

    class NoDescription(DisturbanceParams):
        std: float = 0.1

    class Named(DisturbanceParams):  # name (or kind) chooses the model: an option of that name is never read
        std: float = Field(0.1, ge=0, description="m")
        name: str = Field("x", description="clashes")

    shared = {"drawn": np.random.default_rng(0)}

    def in_place(self, world, pos, vel):
        world.pos += 0.1
        return world.pos.copy(), vel

    cases = [
        (_variant(_Bias, name=""), "set a `name`"),
        (_variant(_Bias, phase="gravity"), "phase must be one of"),
        (_variant(_Bias, phase="wind"), "must define air"),
        (_variant(_Bias, Params=NoDescription), "has no description"),
        (_variant(_Bias, Params=Named), "clash with the key that chooses the model"),
        (_variant(_Bias, sense=in_place), "modified world.pos"),
        (_variant(_Bias, sense=lambda self, w, p, v: (p[:, :2], v)), r"must be \(N, 3\)"),
        (_variant(_Bias, sense=lambda self, w, p, v: (p * np.nan, v)), "is not finite"),
        (_variant(_Bias, sense=lambda self, w, p, v: (p + np.random.default_rng().normal(size=p.shape), v)),
         "not deterministic"),
        (_variant(_Bias, sense=lambda self, w, p, v: (p + shared["drawn"].normal(size=p.shape), v)),
         "deterministic|share state"),
        (_variant(_Bias, metrics=lambda self: {"disturbances.bias.x": 1.0}), "unprefixed"),
        (_variant(_Bias, metrics=lambda self: {"x": float("nan")}), "not finite JSON"),
    ]
    for cls, rule in cases:
        with pytest.raises(AssertionError, match=rule):
            testing.check_disturbance(cls)


def test_the_disturbance_check_refuses_shared_state_between_instances():
    class Memory(_Bias):
        total = [0.0]  # one list for every instance

        def sense(self, world, pos, vel):
            self.total[0] += float(self.rng.normal())
            return pos + self.total[0], vel

    with pytest.raises(AssertionError, match="share state"):
        testing.check_disturbance(Memory)


class _Slow(EventKindPlugin):
    name = "slow"
    motion = Motion.COAST

    class Params(EventParams):
        keep: float = Field(0.5, ge=0, le=1, description="the fraction of its velocity it keeps")

    @classmethod
    def apply(cls, event, world, idx):
        super().apply(event, world, idx)
        world.vel[idx] *= event.params.keep


def test_the_event_kind_check_refuses_each_broken_rule():
    testing.check_event_kind(_Slow)

    class Clash(EventParams):
        agents: int = Field(1, description="clashes")

    class KindClash(EventParams):  # the old spelling of name, read until 0.9.0
        kind: str = Field("x", description="clashes")

    class Undescribed(EventParams):
        keep: float = 0.5

    def moves(cls, event, world, idx):
        EventKindPlugin.apply.__func__(cls, event, world, idx)
        world.pos[idx] += 1.0

    def everyone(cls, event, world, idx):
        world.healthy[:] = False

    def radio(cls, event, world, idx):
        world.comm_ok[idx] = False

    def grounded(cls, event, world, idx):
        world.healthy[idx] = False

    cases = [
        (_variant(_Slow, name=None), "set a `name`"),
        (_variant(_Slow, Params=Clash), "clash with every event's own keys"),
        (_variant(_Slow, Params=KindClash), r"\['kind'\] clash with every event's own keys"),
        (_variant(_Slow, Params=Undescribed), "has no description"),
        (_variant(_Slow, failure="yes"), "failure must be True or False"),
        (_variant(_Slow, motion="coast"), "motion must be a Motion"),
        (_variant(_Slow, apply=classmethod(moves)), "moved agents"),
        (_variant(_Slow, apply=classmethod(everyone)), "of agents it does not hit"),
        (_variant(_Slow, apply=classmethod(radio)), "must drop healthy"),
        (_variant(_Slow, failure=False, apply=classmethod(grounded)), "must drop comm_ok"),
    ]
    for cls, rule in cases:
        with pytest.raises(AssertionError, match=rule):
            testing.check_event_kind(cls)


def test_a_plugin_event_kind_is_validated_by_its_params_with_the_built_ins_lines():
    """A required field missing names it with its description; a field of another kind, or out of
    range, is one line at its key; the kind's fields are recorded with their defaults."""
    from pydantic import ValidationError

    from swarmscene.core.errors import format_validation_error
    from swarmscene.core.events import EventConfig

    class Tilt(_Slow):
        name = "tilt"

        class Params(EventParams):
            angle: float = Field(ge=0, le=90, description="the tilt angle, degrees")

    class Reg:
        classes = {"event": {**REGISTRY.classes["event"], "tilt": Tilt}}

    def lines(event):
        try:
            EventConfig.model_validate(event, context={"registry": Reg})
        except ValidationError as exc:
            return format_validation_error(exc, EventConfig, event, prefix="events.0")
        return []

    base = {"at": 1.0, "agents": [0], "name": "tilt"}
    assert lines(base) == ["events.0.angle: a tilt event needs the tilt angle, degrees (got None)"]
    assert lines({**base, "angle": 95}) == ["events.0.angle: must be <= 90.0 (got 95)"]
    assert lines({**base, "angle": 5, "rotor": 1}) == [
        "events.0.rotor: only a motor_failure event takes it (this event is tilt) (got 1)"]
    assert lines({**base, "angle": 5, "spin": 1}) != []
    recorded = EventConfig.model_validate({**base, "angle": 5}, context={"registry": Reg}).model_dump(mode="json")
    assert recorded == {**base, "angle": 5.0}


class _Row(MapGenerator):
    name = "row"

    class Params(StrictModel):
        count: int = Field(2, ge=1, description="how many")

    @classmethod
    def build(cls, params):
        return [box(3.0 * k, 0.0, 3.0 * k + 1.0, 1.0) for k in range(params.count)]


def test_the_generator_check_refuses_each_broken_rule():
    testing.check_generator(_Row)

    class Clash(StrictModel):
        obstacles: int = Field(2, description="clashes with the environment's own key")

    rng = np.random.default_rng()
    cases = [
        (_variant(_Row, Params=Clash), "clash with the environment"),
        (_variant(_Row, build=classmethod(lambda cls, p: [])), "non-empty list"),
        (_variant(_Row, build=classmethod(lambda cls, p: [ShapelyPoint(0, 0)])), "not a Polygon"),
        (_variant(_Row, build=classmethod(lambda cls, p: [box(0, 0, 0, 1)])), "not a valid, non-empty"),
        (_variant(_Row, build=classmethod(lambda cls, p: [box(0, 0, 1e9, 1)])), "reaches beyond"),
        (_variant(_Row, build=classmethod(lambda cls, p: [box(0, 0, 1 + rng.random(), 1)])), "not deterministic"),
    ]
    for cls, rule in cases:
        with pytest.raises(AssertionError, match=rule):
            testing.check_generator(cls)

    class NoBuild(MapGenerator):
        name = "no_build"
        Params = _Row.Params

    with pytest.raises(AssertionError, match="define build"):
        testing.check_generator(NoBuild)


class _Hover(Policy):
    name = "hover_policy"

    class Params(PluginParams):
        rate: float = Field(0.1, ge=0, le=1, description="fraction of the top speed, up")

    def __call__(self, obs):
        return np.tile([0.0, 0.0, self.params.rate], (len(obs), 1))


def test_the_policy_check_refuses_each_broken_rule():
    testing.check_policy(_Hover)

    def in_place(self, obs):
        obs[:] = 0.0
        return np.zeros((len(obs), 3))

    class Counter(_Hover):
        calls = [0]

        def __call__(self, obs):
            self.calls[0] += 1
            return np.full((len(obs), 3), min(self.calls[0], 10) / 10)

    cases = [
        (_variant(_Hover, __call__=lambda self, obs: np.zeros((len(obs), 2))), "have shape"),
        (_variant(_Hover, __call__=lambda self, obs: np.full((len(obs), 3), 2.0)), r"in \[-1, 1\]"),
        (_variant(_Hover, __call__=in_place), "modified the observations"),
        (_variant(_Hover, __call__=lambda self, obs: np.random.default_rng().uniform(-1, 1, (len(obs), 3))),
         "not deterministic"),
        (Counter, "share state|not deterministic"),
    ]
    for cls, rule in cases:
        with pytest.raises(AssertionError, match=rule):
            testing.check_policy(cls)


class _Ticks:
    def __init__(self, sim):
        self.ticks = 0

    @hookimpl
    def swarmscene_step_end(self, sim):
        self.ticks += 1

    @hookimpl
    def swarmscene_run_end(self, sim, metrics):
        metrics["ticks.count"] = self.ticks


def test_the_observer_check_refuses_each_broken_rule():
    testing.check_observer(_Ticks)

    class Unmarked(_Ticks):
        def swarmscene_step_end(self, sim):  # no @hookimpl: pluggy would never call it
            self.ticks += 1

    class Typo(_Ticks):
        @hookimpl
        def swarmscene_step_ends(self, sim):
            pass

    class Pusher(_Ticks):
        @hookimpl
        def swarmscene_step_end(self, sim):
            sim.world.pos[:, 2] += 0.01

    class Overwrites(_Ticks):
        @hookimpl
        def swarmscene_run_end(self, sim, metrics):
            metrics["steps"] = 0  # an engine metric

    class Remembers(_Ticks):
        runs = [0]

        @hookimpl
        def swarmscene_run_end(self, sim, metrics):
            self.runs[0] += 1
            metrics["ticks.runs"] = self.runs[0]

    class NotJson(_Ticks):
        @hookimpl
        def swarmscene_run_end(self, sim, metrics):
            metrics["ticks.array"] = np.zeros(2)

    cases = [(Unmarked, "not marked @hookimpl"), (Typo, "not a lifecycle hook"), (Pusher, "moved differently"),
             (Overwrites, "changed the run's metrics"), (Remembers, "a second run"), (NotJson, "finite JSON")]
    for cls, rule in cases:
        with pytest.raises(AssertionError, match=rule):
            testing.check_observer(cls)


# -- a third-party package with one of every kind -------------------------------------------------
class _EntryPoint:
    name, value = "allkinds", "swarmscene_allkinds.plugin"
    dist = types.SimpleNamespace(name="swarmscene-allkinds", version="1.0.0")

    def load(self):
        return importlib.import_module(self.value)


@pytest.fixture
def allkinds(monkeypatch):
    monkeypatch.setattr(registry_module, "entry_points", lambda group: [_EntryPoint()])
    return api.plugins()


def test_the_package_imports_nothing_of_the_engine_but_the_public_module():
    source = (ROOT / "tests" / "swarmscene_allkinds" / "plugin.py").read_text()
    engine = set(re.findall(r"^(?:from|import) (swarmscene[\w.]*)", source, re.M))
    assert engine == {"swarmscene.plugin"}


def test_a_package_registers_one_of_every_kind_and_each_passes_its_check(allkinds):
    _, reg = allkinds
    names = {"formation": "ak_climb", "avoidance": "ak_damped", "dynamics": "ak_point",
             "disturbance": "ak_updraft", "event": "ak_freeze", "generator": "ak_posts", "policy": "ak_up"}
    for kind, name in names.items():
        assert reg.sources[(kind, name)] == "swarmscene-allkinds:allkinds"
        check = {"event": testing.check_event_kind}.get(kind) or getattr(testing, f"check_{kind}")
        check(reg.get(kind, name))
    (altitude,) = [c for c in reg.observers if c.__name__ == "Altitude"]
    testing.check_observer(altitude)
    from swarmscene.tools.info import components

    rows = {(r["kind"], r["name"]): r["package"] for r in components(reg)}
    assert {rows[(k, n)] for k, n in names.items()} | {rows[("observer", "Altitude")]} == {"swarmscene-allkinds"}


def _composed(**sections):
    data = api.compose(["swarm.n=3", "swarm.start.layout=line", "environment=open", "clock.duration=2"])
    data.update({k: v for k, v in sections.items()})
    return data


def test_the_package_flies_its_components_by_name(allkinds):
    """The package's formation, avoidance, dynamics, observer, disturbance model and event kind in one
    run: the updraft carries every agent up at 0.5 m/s (ak_point is carried by the air), and agent 1,
    frozen at t = 0.5 s keeping none of its velocity, stays where it froze."""
    data = _composed(formation={"name": "ak_climb", "height": 0.0}, avoidance={"name": "ak_damped"},
                     dynamics={"name": "ak_point"}, disturbances={"up": {"name": "ak_updraft", "speed": 0.5}},
                     events=[{"at": 0.5, "agents": [1], "name": "ak_freeze", "keep": 0.0}])
    scenario = api.load(data, allkinds[1])
    assert scenario.data["events"] == [{"at": 0.5, "agents": [1], "name": "ak_freeze", "keep": 0.0}]
    run = api.run(scenario)
    z = run.trajectory["pos"][:, :, 2]
    assert run.metrics["disturbances.up.speed"] == 0.5 and run.metrics["healthy_at_end"] == 2
    assert run.metrics["ak_altitude.top"] == pytest.approx(z.max(), abs=1e-12)
    frozen = run.trajectory["pos"][6:, 1]  # frames from t = 0.6 s on
    assert np.array_equal(frozen, np.repeat(frozen[:1], len(frozen), axis=0))
    assert np.all(np.diff(z[:, 0]) > 0.0)  # the others keep rising
    again = api.load(scenario.data, allkinds[1])
    assert again.data == scenario.data  # the run's record validates to itself


def test_the_package_flies_in_a_batch_of_worlds_as_alone(allkinds):
    """ak_point has no batched form (docs/batched.md): a batch steps its worlds one by one with
    their own instances, and each world is its single run (every kind of the package in play)."""
    data = _composed(formation={"name": "ak_climb", "height": 0.0}, avoidance={"name": "ak_damped"},
                     dynamics={"name": "ak_point"}, disturbances={"up": {"name": "ak_updraft", "speed": 0.5}},
                     events=[{"at": 0.5, "agents": [1], "name": "ak_freeze", "keep": 0.0}],
                     swarm={"n": 3, "start": {"layout": "random", "extent": 6.0}})
    batched = api.run_batch(data, [3, 4])
    for seed, result in zip([3, 4], batched, strict=True):
        alone = api.run(api.load({**data, "seed": seed}, allkinds[1]))
        assert result.metrics["ak_altitude.top"] == alone.metrics["ak_altitude.top"]
        np.testing.assert_array_equal(result.trajectory["pos"], alone.trajectory["pos"])
    assert not np.array_equal(batched[0].trajectory["pos"], batched[1].trajectory["pos"])  # two seeds


def test_the_package_policy_flies_the_agents(allkinds):
    """ak_up at rate 0.25 with 4 m/s velocity actions: every agent climbs at exactly 1 m/s."""
    data = _composed(formation={"name": "ak_climb"}, dynamics={"name": "ak_point"},
                     avoidance={"name": "policy", "policy": "ak_up", "policy_options": {"rate": 0.25},
                                "max_speed": 4.0})
    run = api.run(api.load(data, allkinds[1]))
    climb = run.trajectory["pos"][:, 0, 2] - run.trajectory["pos"][0, 0, 2]
    np.testing.assert_allclose(climb, np.arange(len(climb)) * 0.1, atol=1e-12)


def test_a_broken_registration_of_a_new_kind_is_skipped_naming_its_plugin(monkeypatch):
    class NotAModel:  # a disturbance that does not derive from Disturbance
        name = "bad"

    module = types.SimpleNamespace()

    @hookimpl
    def swarmscene_register_disturbances(register):
        register(NotAModel)

    module.swarmscene_register_disturbances = swarmscene_register_disturbances
    ep = types.SimpleNamespace(name="bad", value="bad", load=lambda: module,
                               dist=types.SimpleNamespace(name="baddist", version="0.1"))
    monkeypatch.setattr(registry_module, "entry_points", lambda group: [ep])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, reg = make_plugin_manager(BUILTIN_PLUGINS)
    assert any("'baddist:bad'" in str(w.message) and "must subclass Disturbance" in str(w.message) for w in caught)
    assert "bad" not in reg.names("disturbance")


# -- docs ------------------------------------------------------------------------------------------
def test_each_hook_documents_the_arguments_of_its_hookspec():
    """docs/hooks.md writes each hook as `name(args)`: the arguments are the hookspec's, in order."""
    text = (ROOT / "docs" / "hooks.md").read_text()
    documented = dict(re.findall(r"^### `(swarmscene_\w+)\(([^)]*)\)`", text, re.M))
    for name, spec in inspect.getmembers(hookspecs, inspect.isfunction):
        if name.startswith("swarmscene_"):
            args = ", ".join(inspect.signature(spec).parameters)
            assert documented.get(name) == args, f"docs/hooks.md: {name}({documented.get(name)}) != ({args})"


def test_the_plugin_guide_has_a_section_per_kind_naming_its_hook_check_and_template():
    text = (ROOT / "docs" / "plugins.md").read_text()
    for kind, spec in KINDS.items():
        assert spec.hook in text, f"docs/plugins.md never names {spec.hook}"
        assert f"plugins/{kind}/_template.py" in text, kind
        check = "check_event_kind" if kind == "event" else f"check_{kind}"
        assert check in text, check
        assert (ROOT / "plugins" / kind / "README.md").is_file(), kind


def test_a_misspelt_field_of_a_plugin_event_kind_lists_that_kinds_fields(allkinds):
    """It listed the built-in kinds' fields (velocity, rotor, fraction), not the kind's own."""
    from swarmscene.core.errors import ConfigError

    _, registry = allkinds
    with pytest.raises(ConfigError) as err:
        api.load(["events=lead_fails", "events.0.name=ak_freeze", "++events.0.kep=0.5"], registry)
    assert err.value.lines == ["events.0.kep: unknown key of a ak_freeze event (valid keys: at, agents, name, keep) "
                               "(got 0.5)"]
    with pytest.raises(ConfigError) as err:
        api.load(["events=drift", "++events.0.velocty=[1,0,0]"], registry)
    assert err.value.lines == ["events.0.velocty: unknown key of a drift event (valid keys: at, agents, name, "
                               "velocity) (got [1, 0, 0])"]
