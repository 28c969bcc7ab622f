"""swarmscene.tools.schema: every shipped scenario validates against the JSON Schema, and the schema
refuses what the engine refuses; plugins (third-party ones too) bring their own options."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import jsonschema
import numpy as np
import pytest
import yaml
from pydantic import ConfigDict, Field

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.plugin import Formation, PluginParams
from swarmscene.tools.schema import scenario_schema

ROOT = Path(__file__).resolve().parents[1]
_, REGISTRY = api.plugins()
FULL = scenario_schema(REGISTRY)
PARTIAL = scenario_schema(REGISTRY, partial=True)
PRESETS = sorted(p.stem for p in (ROOT / "scenarios" / "scenario").glob("*.yaml"))
FILES = sorted((ROOT / "scenarios" / "scenario").glob("*.yaml")) + sorted((ROOT / "scenarios" / "sweep").glob("*.yaml"))


def errors(schema: dict, data: dict) -> list[str]:
    validator = jsonschema.Draft7Validator(schema)
    return [f"{'.'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(data)]


def test_the_schemas_are_valid_json_schema():
    jsonschema.Draft7Validator.check_schema(FULL)
    jsonschema.Draft7Validator.check_schema(PARTIAL)


@pytest.mark.parametrize("preset", PRESETS)
def test_every_shipped_preset_composed_validates(preset):
    data = api.compose([f"scenario={preset}"])
    data.pop("hydra", None)
    assert errors(FULL, data) == []


@pytest.mark.parametrize("path", FILES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_shipped_scenario_file_validates_as_written(path):
    assert errors(PARTIAL, yaml.safe_load(path.read_text()) or {}) == []


def test_each_plugin_kind_is_one_of_its_registered_plugins_by_name():
    for kind in ("formation", "avoidance", "dynamics"):
        refs = [v["$ref"].rsplit("/", 1)[1] for v in FULL["properties"][kind]["oneOf"]]
        assert refs == [f"{kind}.{name}" for name in REGISTRY.names(kind)]
    cem = FULL["definitions"]["avoidance.cem"]
    assert cem["properties"]["name"] == {"const": "cem", "description": "registered avoidance name"}
    assert cem["additionalProperties"] is False and cem["required"] == ["name"]
    assert cem["properties"]["K"]["minimum"] == 1  # the Params' own constraint


@pytest.mark.parametrize(
    "change, engine_line",
    [
        (lambda d: d["clock"].update(durration=3.0), "clock.durration: unknown key"),
        (lambda d: d.update(avoidance={"name": "none", "K": 1}), "avoidance.K: unknown key"),
        (lambda d: d.update(avoidance={"name": "cem", "K": 0}), "avoidance.K: must be >= 1 (got 0)"),
        (lambda d: d.update(avoidance={"name": "nope"}), "avoidance.name: unknown avoidance 'nope'"),
        (lambda d: d["swarm"].update(n=0), "swarm.n: must be >= 1 (got 0)"),
        (lambda d: d["environment"].update(obstacles=[{"type": "circle", "center": [1, 2, 3], "radius": 1}]),
         "environment.obstacles.0.center: must have at most 2 item(s)"),
    ],
)
def test_the_schema_refuses_what_the_engine_refuses(default_data, change, engine_line):
    data = copy.deepcopy(default_data)
    data.pop("hydra", None)
    change(data)
    with pytest.raises(ConfigError) as err:
        api.load(data, REGISTRY)
    assert any(line.startswith(engine_line) for line in err.value.lines), err.value.lines
    assert errors(FULL, data)


def test_a_third_party_plugin_brings_its_options():
    class Spiral(Formation):
        """A spiral, from another package."""

        name = "spiral"

        class Params(PluginParams):
            turns: int = Field(3, ge=1, description="turns of the spiral")

        def setpoints(self, world, sensing):  # pragma: no cover - never flown here
            raise NotImplementedError

    _, registry = api.plugins()
    registry.register("formation", Spiral)
    schema = scenario_schema(registry)
    spiral = schema["definitions"]["formation.spiral"]
    assert spiral["title"] == "formation=spiral" and spiral["description"] == "A spiral, from another package."
    assert spiral["properties"]["turns"] == {"default": 3, "description": "turns of the spiral", "minimum": 1,
                                            "title": "Turns", "type": "integer"}
    base = {k: v for k, v in api.compose([]).items() if k != "hydra"}
    assert errors(schema, {**base, "formation": {"name": "spiral", "turns": 2}}) == []
    assert errors(schema, {**base, "formation": {"name": "spiral", "turns": 0}})


def test_one_command_writes_the_schema(tmp_path):
    out = tmp_path / "swarmscene.tools.schema.json"
    subprocess.run([sys.executable, "-m", "swarmscene.tools.schema", "-o", str(out)], check=True)
    assert json.loads(out.read_text()) == json.loads(json.dumps(scenario_schema()))


def test_a_plugin_with_a_callable_an_array_and_an_infinite_default_gives_strict_json():
    """Fields JSON Schema cannot describe accept any value (the engine still checks them) and an
    infinite default is said in words: json.dumps(allow_nan=False) never meets Infinity."""
    class Odd(Formation):
        """A plugin with unusual options."""

        name = "odd"

        class Params(PluginParams):
            model_config = ConfigDict(extra="forbid", arbitrary_types_allowed=True)
            shaper: Callable[[float], float] = Field(abs, description="a function")
            table: np.ndarray = Field(default_factory=lambda: np.zeros(3), description="an array")
            reach: float = Field(float("inf"), gt=0, description="how far")

        def setpoints(self, world, sensing):  # pragma: no cover - never flown here
            raise NotImplementedError

    _, registry = api.plugins()
    registry.register("formation", Odd)
    for partial in (False, True):
        schema = scenario_schema(registry, partial=partial)
        text = json.dumps(schema, allow_nan=False)  # raises on Infinity/NaN
        assert "Infinity" not in text and "NaN" not in text
        jsonschema.Draft7Validator.check_schema(schema)
    props = scenario_schema(registry)["definitions"]["formation.odd"]["properties"]
    assert props["reach"]["description"] == "how far (default: inf)" and "default" not in props["reach"]
    # any value (no "type"): the engine checks what JSON Schema cannot say
    assert props["shaper"] == {"description": "a function", "title": "Shaper"}  # abs: no JSON default
    assert props["table"] == {"description": "an array", "title": "Table"}
    base = {k: v for k, v in api.compose([]).items() if k != "hydra"}
    assert errors(scenario_schema(registry), {**base, "formation": {"name": "odd", "reach": 3.0}}) == []
