"""swarmscene.tools.schema's group schemas: every shipped config-group file, and every file the tutorial
has a user write, validates as written against its group's schema (issue #28: map files failed
with "'obstacles' was unexpected" under the one top-level schema), and each group's schema still
refuses a bad file: an unknown key and a wrong type, with a best match that names the key."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
import yaml
from jsonschema.exceptions import best_match

from swarmscene import api
from swarmscene.tools.schema import GLOBAL_GROUPS, GROUPS, group_schema, scenario_schema, schema_file_name

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
_, REGISTRY = api.plugins()
SCHEMAS = {group: group_schema(group, REGISTRY) for group in GROUPS}


def group_of(relative: Path) -> str:
    """The group a file under scenarios/ or the tutorial's my_scenarios/ belongs to."""
    parts = relative.parts
    return "/".join(parts[:2]) if parts[0] == "tuning" else parts[0]


def errors(schema: dict, data: object) -> list[str]:
    return [f"{'.'.join(map(str, e.absolute_path))}: {e.message}"
            for e in jsonschema.Draft7Validator(schema).iter_errors(data)]


# Hydra's own groups (hydra/help, hydra/sweeper, hydra/callbacks) configure Hydra, not a scenario.
SHIPPED = sorted(p for p in SCENARIOS.rglob("*.yaml")
                 if p.parent != SCENARIOS and p.relative_to(SCENARIOS).parts[0] != "hydra")


def tutorial_files() -> dict[str, str]:
    """docs/tutorial.md's files: a line `my_scenarios/<path>`: then its ```yaml block."""
    text = (ROOT / "docs" / "tutorial.md").read_text()
    return dict(re.findall(r"^`my_scenarios/([^`]+\.yaml)`:\n+```yaml\n(.*?)^```", text, re.M | re.S))


def test_every_group_schema_is_valid_draft7_and_strict_json():
    for group, schema in SCHEMAS.items():
        jsonschema.Draft7Validator.check_schema(schema)
        json.dumps(schema, allow_nan=False)
        assert schema["$schema"] == "http://json-schema.org/draft-07/schema#", group


def test_every_shipped_file_belongs_to_a_group_with_a_schema():
    groups = {group_of(p.relative_to(SCENARIOS)) for p in SHIPPED}
    assert groups == set(GROUPS)
    assert len(SHIPPED) >= 90  # 16 maps, 28 tuning files, 12 presets, ...: the glob found them


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(SCENARIOS)))
def test_every_shipped_group_file_validates_against_its_group(path):
    group = group_of(path.relative_to(SCENARIOS))
    text = path.read_text()
    # the header decides what the file holds: top-level keys, or the group's node
    assert ("# @package _global_" in text.split("\n", 1)[0]) == (group in GLOBAL_GROUPS)
    assert errors(SCHEMAS[group], yaml.safe_load(text) or {}) == []


def test_the_tutorial_files_validate_against_their_groups():
    files = tutorial_files()
    assert sorted(files) == ["environment/warehouse.yaml", "events/two_failures.yaml",
                             "scenario/my_preset.yaml", "tuning/avoidance/my_preset/cem.yaml",
                             "tuning/formation/my_preset/static_shape.yaml"]
    for name, text in files.items():
        assert errors(SCHEMAS[group_of(Path(name))], yaml.safe_load(text)) == [], name


def test_a_map_file_is_the_environment_node_not_a_scenario():
    """The issue's symptom: the top-level (partial) schema refuses a map file; its group's accepts it."""
    warehouse = yaml.safe_load(tutorial_files()["environment/warehouse.yaml"])
    top = best_match(jsonschema.Draft7Validator(scenario_schema(REGISTRY, partial=True)).iter_errors(warehouse))
    assert "'obstacles' was unexpected" in top.message
    assert errors(SCHEMAS["environment"], warehouse) == []


BAD = [  # group, a file, where the best match points, its message
    ("scenario", {"swram": {"n": 3}}, "", "Additional properties are not allowed ('swram' was unexpected)"),
    ("scenario", {"clock": {"duration": "long"}}, "clock.duration", "'long' is not of type 'number'"),
    ("sweep", {"sweeep": 1}, "", "Additional properties are not allowed ('sweeep' was unexpected)"),
    ("sweep", {"seed": "zero"}, "seed", "'zero' is not of type 'integer'"),
    ("events", {"event": []}, "", "Additional properties are not allowed ('event' was unexpected)"),
    ("events", {"events": "none"}, "events", "'none' is not of type 'array'"),
    ("swarm", {"count": 5}, "", "Additional properties are not allowed ('count' was unexpected)"),
    ("swarm", {"n": "five"}, "n", "'five' is not of type 'integer'"),
    ("environment", {"obstacle": []}, "", "Additional properties are not allowed ('obstacle' was unexpected)"),
    ("environment", {"obstacles": [{"type": "circle", "center": [0, 0], "radius": "big"}]},
     "obstacles.0.radius", "'big' is not of type 'number'"),
    ("formation", {"name": "static_shape", "spacng": 2}, "",
     "Additional properties are not allowed ('spacng' was unexpected)"),
    ("formation", {"name": "static_shape", "spacing": "far"}, "spacing", "'far' is not of type 'number'"),
    ("avoidance", {"name": "cem", "Kk": 1}, "", "Additional properties are not allowed ('Kk' was unexpected)"),
    ("avoidance", {"name": "cem", "K": "two"}, "K", "'two' is not of type 'integer'"),
    ("dynamics", {"name": "single_integrator", "gian": 1}, "",
     "Additional properties are not allowed ('gian' was unexpected)"),
    ("dynamics", {"name": "single_integrator", "gain": "high"}, "gain", "'high' is not of type 'number'"),
    ("disturbances", {"dryden": {"sped": 8}}, "dryden",
     "Additional properties are not allowed ('sped' was unexpected)"),
    ("disturbances", {"dryden": {"speed": "x"}}, "dryden.speed", "'x' is not of type 'number'"),
    ("task", {"tsak": {}}, "", "Additional properties are not allowed ('tsak' was unexpected)"),
    ("task", {"task": {"seeds": "all"}}, "task.seeds", "'all' is not of type 'array'"),
    ("observers", {"swarmlab": []}, "swarmlab", "[] is not of type 'object'"),
    ("tuning/formation", {"spacng": 2}, "", "Additional properties are not allowed ('spacng' was unexpected)"),
    ("tuning/formation", {"spacing": "far"}, "spacing", "'far' is not of type 'number'"),
    ("tuning/avoidance", {"Kk": 1}, "", "Additional properties are not allowed ('Kk' was unexpected)"),
    ("tuning/avoidance", {"K": "two"}, "K", "'two' is not of type 'integer'"),
    ("tuning/dynamics", {"gian": 1}, "", "Additional properties are not allowed ('gian' was unexpected)"),
    ("tuning/dynamics", {"gain": "high"}, "gain", "'high' is not of type 'number'"),
]


@pytest.mark.parametrize("group, data, where, message", BAD, ids=[f"{b[0]}-{i % 2 and 'type' or 'key'}"
                                                                  for i, b in enumerate(BAD)])
def test_each_group_refuses_an_unknown_key_and_a_wrong_type(group, data, where, message):
    error = best_match(jsonschema.Draft7Validator(SCHEMAS[group]).iter_errors(data))
    assert error is not None
    assert (".".join(map(str, error.absolute_path)), error.message) == (where, message)


def test_every_group_is_covered_by_a_bad_file():
    assert {b[0] for b in BAD} == set(GROUPS)


@pytest.mark.parametrize("section, best", [
    # the method from the defaults list: the key's own constraint, not another plugin's "unexpected"
    ({"K": 0}, ("K", "0 is less than the minimum of 1")),
    # a chosen name: that plugin's options alone (cbf has no K)
    ({"name": "cbf", "K": 1}, ("", "Additional properties are not allowed ('K' was unexpected)")),
    ({"name": "nope"}, ("name", "'nope' is not one of ['apf_navigation', 'cbf', 'cem', 'none', 'orca', "
                                "'policy', 'potential', 'potential_barrier']")),
])
def test_a_plugin_section_gets_a_best_match_about_its_own_keys(section, best):
    """Issue #28: with the method from the defaults list, the best match used to name some other
    plugin's mismatch (an anyOf of every plugin); it now names the key of the section itself."""
    for group, data, prefix in (("avoidance", section, ""), ("scenario", {"avoidance": section}, "avoidance")):
        error = best_match(jsonschema.Draft7Validator(SCHEMAS[group]).iter_errors(data))
        path = ".".join(map(str, [*([prefix] if prefix else []), *([best[0]] if best[0] else [])]))
        assert (".".join(map(str, error.absolute_path)), error.message) == (path, best[1])


def test_a_disturbance_entry_is_its_kind_or_its_key():
    schema = SCHEMAS["disturbances"]
    assert errors(schema, {"gusty": {"name": "gust", "hold": 0}}) == []
    assert errors(schema, {"gust": {"hold": 0}}) == []  # kind defaults to the key
    # neither: an entry another file declares (disturbances=[gps]), any model's options; the
    # composed configuration always has the kind
    assert errors(schema, {"gusty": {"hold": 0}}) == []
    assert errors(schema, {"gusty": {"hodl": 0}}) != []
    full = errors(scenario_schema(REGISTRY), {"disturbances": {"gusty": {"hold": 0}}})
    assert "disturbances.gusty: 'name' is a required property" in full
    assert errors(schema, {"gusty": {"name": "dryden", "hold": 0}}) != []  # hold is gust's


def test_a_group_file_may_open_with_a_defaults_list_but_a_section_field_may_not_hold_one():
    assert errors(SCHEMAS["swarm"], {"defaults": ["led"], "n": 3}) == []
    assert errors(SCHEMAS["swarm"], {"start": {"defaults": []}}) != []


def test_an_unknown_group_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"unknown group 'maps' \(valid: scenario, sweep, events, "):
        group_schema("maps")
    run = subprocess.run([sys.executable, "-m", "swarmscene.tools.schema", "--group", "maps"],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "invalid choice: 'maps'" in run.stderr and "Traceback" not in run.stderr


def test_one_command_writes_every_group_schema(tmp_path):
    subprocess.run([sys.executable, "-m", "swarmscene.tools.schema", "--all-groups", str(tmp_path)], check=True)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == sorted(schema_file_name(g) for g in GROUPS)
    assert "swarmscene.tuning.avoidance.schema.json" in names
    written = json.loads((tmp_path / "swarmscene.environment.schema.json").read_text())
    assert written == json.loads(json.dumps(group_schema("environment")))
    out = subprocess.run([sys.executable, "-m", "swarmscene.tools.schema", "--group", "tuning/dynamics"],
                         capture_output=True, text=True, check=True).stdout
    assert json.loads(out) == json.loads(json.dumps(group_schema("tuning/dynamics")))


def test_a_composed_configuration_with_disturbances_validates_and_a_bad_option_is_refused():
    data = api.compose(["disturbances=[dryden,gps,packet_loss]"])
    data.pop("hydra", None)
    full = scenario_schema(REGISTRY)
    assert errors(full, data) == []
    data["disturbances"]["gps"]["pos_std"] = "far"
    assert [e for e in errors(full, data) if e.startswith("disturbances.gps")] == [
        "disturbances.gps.pos_std: 'far' is not of type 'array'"]


def test_docs_editors_gives_every_group_its_modeline():
    """docs/editors.md's table: one modeline per group, naming the file --all-groups writes, its
    ../ climbing from the group's folder (tuning/<kind>/<preset>/ is two deeper) to its parent."""
    text = (ROOT / "docs" / "editors.md").read_text()
    rows = re.findall(r"^\| `([a-z/_]+)/(?:<preset>/)?\*\.yaml`.*\| `# yaml-language-server: \$schema=([^`]+)` \|$",
                      text, re.M)
    assert sorted(group for group, _ in rows) == sorted(GROUPS)
    for group, path in rows:
        depth = group.count("/") + 2 + (group.startswith("tuning/"))  # + scenarios/ itself
        assert path == "../" * depth + "schemas/" + schema_file_name(group), group
