"""One source of truth for defaults: group YAML files hold the plugin's ``name`` and only
deliberate, commented deviations from the Params (or engine schema) defaults.

A value that merely repeats a default would hide a later change of that default (the run would keep
the old value, while docs/options.md shows the new one); a value that differs without a comment is a
silent deviation (the stale PD gains of double_integrator.yaml, issue #15). Both fail here, for
every group file shipped, including those of plugins added later, and for the primary config
(``scenarios/config.yaml``) against the engine schema.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml
from pydantic import BaseModel, TypeAdapter

from swarmscene import api
from swarmscene.core.config import EnvironmentConfig, ScenarioConfig, SwarmConfig
from swarmscene.core.plugin import PLUGIN_KINDS

SCENARIOS = Path(api.__file__).resolve().parent.parent / "scenarios"
GROUPS = ("swarm", "environment", "events", *PLUGIN_KINDS)


def group_files() -> list[Path]:
    return sorted(p for group in GROUPS for p in (SCENARIOS / group).glob("*.yaml"))


def model_of(group: str, data: dict[str, Any]) -> type[BaseModel]:
    if group == "swarm":
        return SwarmConfig
    if group == "environment":
        return EnvironmentConfig
    if group == "events":
        return ScenarioConfig  # `# @package _global_`
    _, registry = api.plugins()
    return registry.get(group, data["name"]).Params


def submodel(annotation: Any) -> type[BaseModel] | None:
    return annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None


def problems(
    model: type[BaseModel], data: dict[str, Any], text: str, prefix: str, commented: bool = True
) -> list[str]:
    """Keys of ``data`` that repeat ``model``'s default, are unknown, or (``commented``) deviate
    without a comment on their line."""
    found = []
    for key, value in data.items():
        if key == "name" and not prefix:
            continue  # the choice's name (a plugin's registered name, the map's label)
        if key == "defaults" and not prefix:
            continue  # Hydra's defaults list (a deprecated alias naming the option it stands for)
        field = model.model_fields.get(key)
        if field is None:
            found.append(f"{prefix}{key}: not an option of {model.__name__}")
            continue
        inner = submodel(field.annotation)
        if inner is not None and isinstance(value, dict):
            found += problems(inner, value, text, f"{prefix}{key}.", commented)
            continue
        if not field.is_required():
            adapter = TypeAdapter(field.annotation)
            default = adapter.dump_python(field.get_default(call_default_factory=True), mode="json")
            if adapter.dump_python(adapter.validate_python(value), mode="json") == default:
                found.append(f"{prefix}{key}: repeats the default {default!r}")
                continue
        if commented and not re.search(rf"^\s*{re.escape(key)}:.*#", text, flags=re.MULTILINE):
            found.append(f"{prefix}{key}: deviates from the default without a comment on its line")
    return found


@pytest.mark.parametrize("path", group_files(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_group_yaml_holds_only_commented_deviations(path):
    text = path.read_text()
    data = yaml.safe_load(text) or {}
    group = path.parent.name
    if group == "events":  # `# @package _global_`: the list is the choice's whole content
        assert set(data) <= {"events"} and ScenarioConfig.model_fields["events"]
        return
    # A map's obstacles are the option's content, described by the file's header.
    commented = group != "environment"
    if group == "environment" and data.get("generator"):  # its parameters: its own Params' options
        params = api.plugins()[1].get("generator", data["generator"]).Params
        own = {k: v for k, v in data.items() if k in params.model_fields}
        data = {k: v for k, v in data.items() if k not in own}
        # known options (as when they were the section's fields, a default may be spelt out)
        assert [p for p in problems(params, own, text, "", commented) if "repeats the default" not in p] == []
    assert problems(model_of(group, data), data, text, "", commented) == []


def test_primary_config_holds_only_commented_deviations_from_the_engine_schema():
    """scenarios/config.yaml copied ~30 engine defaults (issue #27): only deliberate values stay,
    each with a comment on its line saying why; a value equal to its default stays only where that
    comment starts with "deliberate" (``seed`` for ``${seed}`` interpolations, for example)."""
    text = (SCENARIOS / "config.yaml").read_text()
    data = yaml.safe_load(text)
    # Hydra's own node and the defaults list are not engine options; the description is the
    # default scenario's one line of text, not a tuning.
    engine = {k: v for k, v in data.items() if k not in ("hydra", "defaults", "description")}
    assert set(engine) <= set(ScenarioConfig.model_fields)
    kept = []
    for line in problems(ScenarioConfig, engine, text, ""):
        key = line.split(":")[0].rsplit(".", 1)[-1]
        deliberate = re.search(rf"^\s*{re.escape(key)}:.*#\s*deliberate", text, flags=re.MULTILINE)
        if not ("repeats the default" in line and deliberate):
            kept.append(line)
    assert kept == []
    assert re.search(r"^name:.*#\s*deliberate", text, flags=re.MULTILINE)  # the run dir reads it
    repeated = [k for k in ("seed", "guidance_period", "objective")
                if re.search(rf"^\s*{k}:.*#\s*deliberate", text, re.M)]
    assert repeated == ["seed", "guidance_period", "objective"], "a kept default says why; drop it here when it goes"


def test_the_primary_config_check_catches_a_copied_default():
    text = "seed: 0\nclock:\n  guidance_period: 0.1\n  duration: 45.0\ncomm:\n  range: 20.0  # m\n"
    assert problems(ScenarioConfig, yaml.safe_load(text), text, "") == [
        "seed: repeats the default 0",
        "clock.guidance_period: repeats the default 0.1",
        "clock.duration: deviates from the default without a comment on its line",
        "comm.range: repeats the default 20.0",
    ]


def test_the_contract_catches_a_repeated_and_an_uncommented_default():
    """The check itself: the old double_integrator.yaml fails it on every line."""
    from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

    old = "name: double_integrator\nomega: 1.0\nk_v: 2.0     # 1/s\nv_max: 5.0   # m/s\n"
    assert problems(DoubleIntegrator.Params, yaml.safe_load(old), old, "") == [
        "omega: deviates from the default without a comment on its line",
        "v_max: repeats the default 5.0",
    ]


def test_the_default_scenario_runs_the_double_integrator_params_defaults(data):
    """issue #15: the default scenario ran stale PD gains (omega 1.0, k_v 2.0, u_sat 3.0)."""
    from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

    scenario = api.load(data)
    assert scenario.plugin_params["dynamics"] == DoubleIntegrator.Params()
    assert (scenario.plugin_params["dynamics"].k_v, scenario.plugin_params["dynamics"].u_sat) == (12.04, 3.4)


def test_the_example_package_holds_only_commented_deviations_too():
    """docs/examples/swarmscene-slowdown is what a plugin author copies: its group file repeated
    both of its Params' defaults, against the rule docs/plugins.md states."""
    import script_modules

    package = SCENARIOS.parent / "docs" / "examples" / "swarmscene-slowdown" / "swarmscene_slowdown"
    module = script_modules.load("swarmscene_slowdown_example", package / "plugin.py")
    for path in sorted((package / "conf").rglob("*.yaml")):
        text = path.read_text()
        assert problems(module.Slowdown.Params, yaml.safe_load(text) or {}, text, "") == [], path
