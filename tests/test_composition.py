"""Presets declare the scenario, not the method (issue #14, section 1).

A preset (``scenarios/scenario/*.yaml``) chooses its default methods in its defaults list; its tuning
of one method lives in ``scenarios/tuning/<kind>/<scenario>/<method>.yaml`` and is merged only when
that method is the one chosen (``scenarios/config.yaml``); the command line wins over everything.
These tests hold the presets to that: every preset with every built-in avoidance (and formation,
and a few dynamics) runs the method asked for, or fails with one line naming a key.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import yaml

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.core.spelling import canonical_names
from swarmscene.views.summary import summary_text

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
TUNING = SCENARIOS / "tuning"
KINDS = ("formation", "avoidance", "dynamics")
RECORDED = json.loads((Path(__file__).parent / "data" / "preset_compositions.json").read_text())
_, REGISTRY = api.plugins()
PRESETS = sorted(p.stem for p in (SCENARIOS / "scenario").glob("*.yaml"))


def effective(scenario) -> dict:
    """The validated values a run uses: the engine's schema dump and each chosen plugin's Params
    dump, defaults included (insensitive to which YAML file a value came from)."""
    out = scenario.config.model_dump(mode="json")
    for kind, params in scenario.plugin_params.items():
        out[kind] = {"name": scenario.plugin_classes[kind].name, **params.model_dump(mode="json")}
    return out


def preset_file(name: str) -> dict:
    return yaml.safe_load((SCENARIOS / "scenario" / f"{name}.yaml").read_text())


def base_preset(name: str) -> str | None:
    """The preset a preset inherits (a bare name in its defaults list), if any."""
    for entry in preset_file(name).get("defaults", []):
        if isinstance(entry, str) and entry != "_self_":
            return entry
    return None


def tuning_files() -> list[Path]:
    return sorted(TUNING.glob("*/*/*.yaml"))


# -- the presets' default methods give exactly what they gave before the tuning moved out -------
@pytest.mark.parametrize("preset", sorted(RECORDED))
def test_preset_composes_to_its_recorded_effective_config(preset):
    """tests/data/preset_compositions.json was first recorded at ef1b6fc, when the presets still
    spelled out their methods' options: moving them into tuning files changed no value a run uses
    (re-recorded after 6d8bd66 changed double_integrator's defaults on purpose). Compared in the
    canonical spelling (an event's kind keyed ``kind``, as recorded then: its ``name`` since)."""
    now = canonical_names(effective(api.load([f"scenario={preset}"], REGISTRY)))
    assert now == canonical_names(RECORDED[preset]), (
        f"{preset}'s values changed; if that is meant, re-record: "
        f"python tests/data/record_preset_compositions.py {preset}"
    )


@pytest.mark.parametrize("preset", PRESETS)
def test_preset_chooses_methods_and_sets_none_of_their_options(preset):
    body = preset_file(preset)
    assert not set(KINDS) & set(body), f"{preset}: method options belong in tuning/<kind>/{preset}/"
    for entry in body.get("defaults", []):
        if isinstance(entry, dict):
            ((group, choice),) = entry.items()
            assert choice is not None, f"{preset}: {group} must name a method, not null"


@pytest.mark.parametrize("path", tuning_files(), ids=lambda p: "/".join(p.parts[-3:]))
def test_every_tuning_file_belongs_to_a_preset_and_a_method_and_validates(path):
    kind, preset, method = path.parts[-3], path.parts[-2], path.stem
    assert kind in KINDS and preset in PRESETS
    assert method in REGISTRY.names(kind)
    assert (path.parent / "__init__.py").exists(), "pkg:// reads only package folders"
    scenario = api.load([f"scenario={preset}", f"{kind}={method}"], REGISTRY)
    assert scenario.plugin_classes[kind].name == method


# -- the user's choice wins; a preset's tuning follows its method -------------------------------
def test_cem_preset_runs_the_avoidance_asked_for():
    """The issue's reproduction: ``scenario=cem_six_vehicle avoidance=none`` silently ran CEM."""
    scenario = api.load(["scenario=cem_six_vehicle", "avoidance=none"], REGISTRY)
    assert effective(scenario)["avoidance"] == {"name": "none"}


def test_another_avoidance_gets_its_own_defaults_not_the_presets_cem_tuning():
    tuned = api.load(["scenario=cem_six_vehicle", "avoidance=potential"], REGISTRY)
    plain = api.load(["avoidance=potential"], REGISTRY)
    assert effective(tuned)["avoidance"] == effective(plain)["avoidance"]


def test_preset_tuning_applies_to_its_method_and_the_command_line_wins():
    cem = effective(api.load(["scenario=cem_six_vehicle"], REGISTRY))["avoidance"]
    assert (cem["K"], cem["eps"], cem["delta"], cem["a_f"]) == (2, 0.28, 0.40, 0.68)  # section V-A
    assert effective(api.load(["avoidance=cem"], REGISTRY))["avoidance"]["a_f"] is None  # eps + delta
    override = effective(api.load(["scenario=cem_six_vehicle", "avoidance.a_f=0.9", "avoidance.K=5"], REGISTRY))
    assert (override["avoidance"]["a_f"], override["avoidance"]["K"]) == (0.9, 5)


def test_formation_tuning_follows_the_formation():
    """cem_six_vehicle's triangle is static_shape's tuning; another formation gets its own."""
    triangle = effective(api.load(["scenario=cem_six_vehicle"], REGISTRY))["formation"]
    assert (triangle["shape"], triangle["spacing"]) == ("triangle", 2.72)
    swap = effective(api.load(["scenario=cem_six_vehicle", "formation=antipodal_swap"], REGISTRY))
    assert swap["formation"] == effective(api.load(["formation=antipodal_swap"], REGISTRY))["formation"]


@pytest.mark.parametrize("preset", [p for p in PRESETS if base_preset(p)])
def test_inheriting_preset_carries_its_bases_tuning(preset):
    """A preset reads tuning/<kind>/<its own name>/: one that inherits another forwards to the
    base's tuning file by file, and then runs every method as the base does."""
    base = base_preset(preset)
    for path in TUNING.glob(f"*/{base}/*.yaml"):
        forward = path.parent.parent / preset / path.name
        assert forward.exists(), f"{forward.relative_to(SCENARIOS)} missing: {preset} inherits {base}"
    mine, theirs = (effective(api.load([f"scenario={p}"], REGISTRY)) for p in (preset, base))
    for kind in KINDS:
        assert mine[kind] == theirs[kind]


# -- every preset with every method: ran (the method asked for) or one line naming a key --------
def short(preset: str) -> list[str]:
    """Overrides for a run of two guidance ticks (at least 0.2 s), no trajectory written."""
    period = RECORDED.get(preset, {}).get("clock", {}).get("guidance_period")
    if period is None:
        period = api.compose([f"scenario={preset}"])["clock"]["guidance_period"]
    return [f"clock.duration={max(0.2, 2 * period)}", "output.trajectory=false"]


def run_or_error(overrides: list[str], run_dir: Path | None = None):
    """(sim, result) of a short run, or the ConfigError it raised (composition or validation)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # presets that start close on purpose warn
            sim = api.build(overrides)
            result = sim.run()
    except ConfigError as exc:
        return exc
    if run_dir is not None:
        api.write_outputs(sim, result, run_dir)
    return sim, result


def is_config_key(key: str, data: dict) -> bool:
    """Whether dotted ``key`` is in the composed ``data``, or is an option of a chosen plugin
    (whose default the YAML need not spell out)."""
    kind, _, option = key.partition(".")
    if kind in KINDS and option:
        return option.split(".")[0] in REGISTRY.get(kind, data[kind]["name"]).Params.model_fields
    node = data
    for part in key.split("."):
        if isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return False
    return True


def assert_one_line_naming_a_key(exc: ConfigError, overrides: list[str]) -> None:
    assert len(exc.lines) == 1 and "\n" not in exc.lines[0], exc.lines
    key = exc.lines[0].split(": ", 1)[0]
    assert is_config_key(key, api.compose(overrides)), f"{exc.lines[0]!r} names no key of the config"


def assert_ran_with(sim, result, kind: str, method: str, preset: str, run_dir: Path) -> None:
    assert result.complete and result.stop_reason in ("duration", "complete", "collision")
    assert getattr(sim, kind).name == method
    names = {k: getattr(sim, k).name for k in KINDS}
    header = summary_text(sim, result, None).splitlines()[0]
    assert header == (
        f"swarmscene: scenario {preset!r} "
        f"({names['formation']} / {names['avoidance']} / {names['dynamics']})"
    )
    recorded = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert recorded[kind]["name"] == method
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert manifest["complete"] is True
    assert (manifest["scenario"], manifest["methods"]) == (preset, names)


EXPECTED_AVOIDANCE_ERRORS: dict[tuple[str, str], str] = {}
"""(preset, avoidance) -> the one line; every other pair runs."""


@pytest.mark.parametrize("avoidance", REGISTRY.names("avoidance"))
@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_runs_every_avoidance(preset, avoidance, tmp_path):
    overrides = [f"scenario={preset}", f"avoidance={avoidance}", *short(preset)]
    outcome = run_or_error(overrides, tmp_path)
    expected = EXPECTED_AVOIDANCE_ERRORS.get((preset, avoidance))
    if expected is not None:
        assert isinstance(outcome, ConfigError) and outcome.lines == [expected]
        return
    assert not isinstance(outcome, ConfigError), outcome.lines
    assert_ran_with(*outcome, "avoidance", avoidance, preset, tmp_path)


_RUN_EACH = """
import json, sys, warnings
from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.views.summary import summary_text
warnings.simplefilter("ignore")
out = {}
for preset, overrides in json.loads(sys.argv[1]).items():
    try:
        sim = api.build(overrides)
        out[preset] = summary_text(sim, sim.run(), None).splitlines()[0]
    except ConfigError as exc:
        out[preset] = exc.lines
print(json.dumps(out))
"""


def test_every_preset_runs_a_third_party_avoidance(tmp_path):
    """The issue's case: ``scenario=cem_six_vehicle avoidance=<a third-party avoidance>`` failed
    with one line per CEM option. The packaged example (docs/examples/swarmscene-slowdown),
    installed into a private folder, flies every shipped preset."""
    source = tmp_path / "src"
    shutil.copytree(ROOT / "docs" / "examples" / "swarmscene-slowdown", source,
                    ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                    "--target", str(site), str(source)], check=True, capture_output=True)
    jobs = {p: [f"scenario={p}", "avoidance=slowdown", *short(p)] for p in PRESETS}
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", _RUN_EACH, json.dumps(jobs)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    headers = json.loads(proc.stdout.splitlines()[-1])
    for preset in PRESETS:
        assert isinstance(headers[preset], str), f"{preset}: {headers[preset]}"
        assert f"scenario {preset!r} (" in headers[preset] and "/ slowdown /" in headers[preset]


@pytest.mark.parametrize("formation", REGISTRY.names("formation"))
@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_runs_every_formation_or_says_why_not(preset, formation, tmp_path):
    overrides = [f"scenario={preset}", f"formation={formation}", *short(preset)]
    outcome = run_or_error(overrides, tmp_path)
    if isinstance(outcome, ConfigError):
        assert_one_line_naming_a_key(outcome, overrides)
    else:
        assert_ran_with(*outcome, "formation", formation, preset, tmp_path)


@pytest.mark.parametrize(
    "preset, kind, method",
    [
        ("cem_six_vehicle", "dynamics", "double_integrator"),
        ("cem_six_vehicle", "dynamics", "quadrotor"),
        ("indoor_corridor", "dynamics", "double_integrator"),
        ("outdoor_square", "dynamics", "single_integrator"),
        ("vrb_airshow", "dynamics", "double_integrator"),
        ("indoor_corridor", "formation", "static_shape"),
        ("vrb_airshow", "formation", "static_shape"),
    ],
)
def test_method_swaps_run_the_method_asked_for(preset, kind, method, tmp_path):
    outcome = run_or_error([f"scenario={preset}", f"{kind}={method}", *short(preset)], tmp_path)
    assert not isinstance(outcome, ConfigError), outcome.lines
    assert_ran_with(*outcome, kind, method, preset, tmp_path)


def test_swapped_dynamics_gets_its_own_defaults_not_the_presets_tuning():
    """cem_six_vehicle tunes single_integrator (u_max 5 m/s); double_integrator gets its own."""
    swapped = effective(api.load(["scenario=cem_six_vehicle", "dynamics=double_integrator"], REGISTRY))
    plain = effective(api.load(["dynamics=double_integrator"], REGISTRY))
    assert swapped["dynamics"] == plain["dynamics"]


# -- combinations that cannot be flown: one line that says why and names the key ---------------
@pytest.mark.parametrize(
    "overrides, line",
    [
        (
            ["scenario=cem_multi_failure", "formation=hex_lattice"],
            "swarm.leader: formation 'hex_lattice' needs a leader (an agent index 0..11)",
        ),
        (
            ["scenario=vrb_airshow", "formation=outdoor_mission"],
            "swarm.leader: formation 'outdoor_mission' needs a leader (an agent index 0..2)",
        ),
        (
            ["scenario=flocking", "formation=indoor_swarm"],
            "swarm.leader: formation 'indoor_swarm' needs a leader (an agent index 0..99)",
        ),
        (   # a periodic space teleports agents across its faces: through walls in a map
            ["scenario=indoor_corridor", "formation=reynolds_flocking", "formation.space=toroidal"],
            "formation.space: toroidal wraps agents across the box's faces, through obstacles: "
            "environment 'indoor_corridor_w080' has 12 (use space: open or bounded)",
        ),
        (   # ... and would teleport the agents that start outside its box at t = 0
            ["scenario=cem_six_vehicle", "formation=reynolds_flocking", "formation.space=toroidal"],
            "swarm.start: 4 agents ([1, 3, 4, 5]) start outside the periodic box of formation "
            "'reynolds_flocking', [0.0, 0.0] to [100.0, 100.0] m (its wrap would move them at t = 0)",
        ),
        (   # ... naming ten of them when there are more
            ["scenario=flocking", "formation.box_max=[50,50,50]"],
            "swarm.start: 84 agents ([0, 2, 3, 4, 5, 6, 7, 8, 11, 12] and 74 more) start outside the periodic "
            "box of formation 'reynolds_flocking', [0.0, 0.0] to [50.0, 50.0] m (its wrap would move them at t = 0)",
        ),
    ],
    ids=lambda case: " ".join(case) if isinstance(case, list) else "line",
)
def test_meaningless_combination_is_one_line_naming_the_key(overrides, line):
    preset = overrides[0].removeprefix("scenario=")
    outcome = run_or_error([*overrides, *short(preset)])
    assert isinstance(outcome, ConfigError), "ran: it must be refused"
    assert outcome.lines == [line]


def test_flocking_keeps_its_torus_where_the_map_is_open():
    """The Mesa torus is the flocking preset's tuning of reynolds_flocking, and runs there."""
    scenario = api.load(["scenario=flocking"], REGISTRY)
    params = effective(scenario)["formation"]
    assert (params["space"], params["box_min"], params["box_max"]) == (
        "toroidal", [0.0, 0.0, 0.0], [100.0, 100.0, 100.0]
    )
