"""swarmscene.tools.schema reads every kind chosen by name from the registry (issue #27): an event's
``name`` is an enum of the registered kinds, each with its own fields; disturbance models and map
generators are the registry's; a third-party package's event kind, disturbance model and map
generator appear beside the built-ins, refused where the engine refuses them."""

from __future__ import annotations

import copy
import importlib
import types

import jsonschema
import pytest

from swarmscene import api
from swarmscene.core import registry as registry_module
from swarmscene.core.errors import ConfigError
from swarmscene.tools.schema import group_schema, scenario_schema

_, REGISTRY = api.plugins()
FULL = scenario_schema(REGISTRY)
DRIFT = {"at": 1.0, "agents": [0], "name": "drift", "velocity": [0.2, 0.0, 0.0]}


class _EntryPoint:
    name, value = "allkinds", "swarmscene_allkinds.plugin"
    dist = types.SimpleNamespace(name="swarmscene-allkinds", version="1.0.0")

    def load(self):
        return importlib.import_module(self.value)


@pytest.fixture(scope="module")
def allkinds():
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(registry_module, "entry_points", lambda group: [_EntryPoint()])
        registry = api.plugins()[1]
    return registry, scenario_schema(registry)


def errors(schema: dict, data: dict) -> list[str]:
    return [e.message for e in jsonschema.Draft7Validator(schema).iter_errors(data)]


def _with(default_data, **sections):
    data = copy.deepcopy(default_data)
    data.pop("hydra", None)
    data.update(copy.deepcopy(sections))
    return data


def test_an_event_kind_is_an_enum_of_the_registered_kinds_each_with_its_own_definition():
    (choice,) = [c for c in FULL["properties"]["events"]["items"]["allOf"] if "else" in c]
    assert choice["then"]["properties"]["name"]["enum"] == REGISTRY.names("event") == [
        "comm_loss", "drift", "hover", "motor_failure", "stuck"]
    assert "EventConfig" not in FULL["definitions"]
    drift = FULL["definitions"]["events.drift"]
    assert list(drift["properties"]) == ["at", "agents", "name", "velocity"]
    assert drift["required"] == ["at", "agents", "name", "velocity"] and drift["additionalProperties"] is False
    assert list(FULL["definitions"]["events.motor_failure"]["properties"]) == [
        "at", "agents", "name", "rotor", "fraction"]
    assert list(FULL["definitions"]["events.hover"]["properties"]) == ["at", "agents", "name"]


@pytest.mark.parametrize("event, engine_line", [
    ({**DRIFT, "name": "explode"}, "events.0.name: unknown event kind 'explode'"),
    ({k: v for k, v in DRIFT.items() if k != "velocity"}, "events.0.velocity: a drift event needs"),
    ({**DRIFT, "rotor": 1}, "events.0.rotor: only a motor_failure event takes it"),
    ({"at": 1.0, "agents": [0], "name": "motor_failure"}, "events.0.rotor: a motor_failure event needs"),
    ({"at": 1.0, "agents": [0], "name": "hover", "velocity": [1.0, 0.0, 0.0]},
     "events.0.velocity: only a drift event takes it"),
])
def test_the_schema_refuses_the_events_the_engine_refuses(default_data, event, engine_line):
    data = _with(default_data, events=[event])
    with pytest.raises(ConfigError) as err:
        api.load(data, REGISTRY)
    assert any(line.startswith(engine_line) for line in err.value.lines), err.value.lines
    assert errors(FULL, data)
    assert errors(FULL, _with(default_data, events=[DRIFT])) == []


def test_an_events_file_is_checked_against_the_kind_it_names():
    schema = group_schema("events", REGISTRY)
    assert errors(schema, {"events": [{"at": 2.0, "agents": {"sample": 1}, "name": "stuck"}]}) == []
    assert errors(schema, {"events": [{"at": 2.0, "agents": [0], "name": "stuck", "fraction": 0.5}]}) == [
        "Additional properties are not allowed ('fraction' was unexpected)"]
    assert errors(schema, {"events": [{"at": 2.0, "agents": [0], "name": "fly_away"}]}) == [
        "'fly_away' is not one of ['comm_loss', 'drift', 'hover', 'motor_failure', 'stuck']"]


def test_a_package_event_kind_disturbance_model_and_generator_appear_in_the_schema(allkinds):
    registry, schema = allkinds
    defs = schema["definitions"]
    assert defs["events.ak_freeze"]["properties"]["keep"]["maximum"] == 1
    assert defs["disturbances.ak_updraft"]["properties"]["name"]["const"] == "ak_updraft"
    environment = defs["EnvironmentConfig"]["properties"]
    assert environment["generator"]["anyOf"][0] == {"enum": ["ak_posts", "building", "corridor", "obstacle_field"]}
    assert environment["count"]["description"] == "ak_posts: how many posts"
    jsonschema.Draft7Validator.check_schema(schema)


@pytest.mark.parametrize("sections, valid", [
    ({"events": [{"at": 0.5, "agents": [1], "name": "ak_freeze", "keep": 0.25}]}, True),
    ({"events": [{"at": 0.5, "agents": [1], "name": "ak_freeze", "keep": 2.0}]}, False),
    ({"events": [{"at": 0.5, "agents": [1], "name": "ak_freeze", "velocity": [1.0, 0.0, 0.0]}]}, False),
    ({"disturbances": {"up": {"name": "ak_updraft", "speed": 1.5}}}, True),
    ({"disturbances": {"up": {"name": "ak_updraft", "speed": -1.0}}}, False),
    ({"disturbances": {"up": {"name": "ak_updraft", "gust": 1.0}}}, False),
    ({"environment": {"name": "posts", "generator": "ak_posts", "count": 2}}, True),
    ({"environment": {"name": "posts", "generator": "ak_posts", "count": 0}}, False),
    ({"environment": {"name": "posts", "generator": "maze"}}, False),
])
def test_a_package_kind_is_refused_by_the_schema_where_the_engine_refuses_it(default_data, allkinds,
                                                                             sections, valid):
    registry, schema = allkinds
    data = _with(default_data, **sections)
    data["swarm"]["n"] = 3  # the default's agents start clear of the posts (20 m north)
    if valid:
        api.load(data, registry)
        assert errors(schema, data) == []
    else:
        with pytest.raises(ConfigError):
            api.load(data, registry)
        assert errors(schema, data)
