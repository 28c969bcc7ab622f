"""Guardrails: every YAML composes and validates, every plugin honours its kind's contract,
every module imports on its own, core never imports plugins, every plugin module is registered."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.plugin import BuildContext, PluginParams
from swarmscene.core.environment import Environment
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState

ROOT = Path(__file__).resolve().parents[1]
_, REGISTRY = api.plugins()


def group_options(group: str) -> list[str]:
    return sorted(p.stem for p in (ROOT / "scenarios" / group).glob("*.yaml"))


@pytest.mark.parametrize("scenario", group_options("scenario"))
def test_every_scenario_composes_and_validates(scenario):
    api.load([f"scenario={scenario}"], REGISTRY)


@pytest.mark.parametrize(
    "override",
    [f"{g}={o}" for g in ("swarm", "environment", "formation", "avoidance", "dynamics", "events") for o in group_options(g)],
)
def test_every_group_option_composes(override):
    data = api.compose([override])
    assert data[override.split("=")[0]] is not None or override.startswith("events")


@pytest.mark.parametrize("kind", ["formation", "avoidance", "dynamics"])
def test_every_plugin_declares_name_and_documented_params(kind):
    for name in REGISTRY.names(kind):
        cls = REGISTRY.get(kind, name)
        assert cls.name == name
        assert issubclass(cls.Params, PluginParams)
        assert cls.Params.model_config.get("extra") == "forbid"
        for field, info in cls.Params.model_fields.items():
            assert info.description, f"{kind} {name}: option {field!r} has no description"
        yaml = ROOT / "scenarios" / kind / f"{name}.yaml"
        assert yaml.exists(), f"{kind} {name} has no {yaml.relative_to(ROOT)}"


def _context(n: int, pos: np.ndarray) -> BuildContext:
    return BuildContext(
        n=n, guidance_period=0.1, physics_step=0.01, duration=10.0, min_separation=0.3,
        min_clearance=0.1, comm_range=10.0, environment=Environment(), rng=np.random.default_rng(0),
        initial=WorldState.at_rest(pos, leader=0),
    )


@pytest.mark.parametrize("name", REGISTRY.names("dynamics"))
def test_dynamics_contract_hold_keeps_agents_near(name):
    """Every dynamics model, told to HOLD where agents are, keeps them there (within 1 cm)."""
    pos = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 2.0], [0.0, 3.0, 2.0]])
    cls = REGISTRY.get("dynamics", name)
    model = cls(cls.Params(), _context(3, pos))
    world = WorldState.at_rest(pos, leader=0)
    model.initialize(world)
    sp = Setpoints.hold(pos)
    for _ in range(20):
        model.control(world, sp)
        for _ in range(10):
            model.step(world, 0.01)
    assert np.abs(world.pos - pos).max() < 1e-2
    assert world.pos.shape == (3, 3) and world.vel.shape == (3, 3)


@pytest.mark.parametrize("name", REGISTRY.names("dynamics"))
def test_dynamics_contract_position_setpoint_is_approached(name):
    pos = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 2.0]])
    cls = REGISTRY.get("dynamics", name)
    model = cls(cls.Params(), _context(2, pos))
    world = WorldState.at_rest(pos, leader=0)
    model.initialize(world)
    sp = Setpoints.hold(pos + [1.0, 0.0, 0.0])
    sp.mode[:] = Mode.POSITION
    before = np.linalg.norm(world.pos - sp.pos, axis=1)
    for _ in range(300):  # 30 s: the thesis' position loop (omega_r = 0.23 rad/s) is slow
        model.control(world, sp)
        for _ in range(10):
            model.step(world, 0.01)
    assert np.all(np.linalg.norm(world.pos - sp.pos, axis=1) < 0.5 * before)


def test_none_avoidance_passes_setpoints_through():
    cls = REGISTRY.get("avoidance", "none")
    sp = Setpoints.hold(np.zeros((2, 3)))
    assert cls(cls.Params(), _context(2, np.zeros((2, 3)))).adjust(None, None, sp) is sp


def test_every_plugin_module_is_a_builtin():
    registering = set()
    for path in (ROOT / "plugins").rglob("*.py"):
        if path.name.startswith("_"):
            continue  # __init__ and the templates
        tree = ast.parse(path.read_text())
        if any(isinstance(node, ast.FunctionDef) and node.name.startswith("swarmscene_register_") for node in tree.body):
            rel = path.relative_to(ROOT).with_suffix("").as_posix().replace("/", ".")
            registering.add(f"swarmscene.{rel}")
    assert registering == set(BUILTIN_PLUGINS)


def test_core_never_imports_plugins():
    for path in (ROOT / "core").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                for name in names:
                    assert "plugins" not in name.split("."), f"{path.name} imports {name}"


def all_modules() -> list[str]:
    mods = []
    for folder, package in (
        ("core", "swarmscene.core"), ("methods", "swarmscene.methods"),
        ("plugins", "swarmscene.plugins"), ("swarmscene", "swarmscene"),
    ):
        for path in (ROOT / folder).rglob("*.py"):
            rel = path.relative_to(ROOT / folder).with_suffix("").parts
            if rel[-1] == "__init__":
                rel = rel[:-1]
            mods.append(".".join((package, *rel)))
    return sorted(mods)


def test_every_module_imports_on_its_own():
    from concurrent.futures import ThreadPoolExecutor

    def try_import(module: str) -> str | None:
        proc = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True)
        return None if proc.returncode == 0 else f"{module}: {proc.stderr.strip().splitlines()[-1]}"

    with ThreadPoolExecutor(max_workers=2) as pool:
        failures = [f for f in pool.map(try_import, all_modules()) if f]
    assert not failures, failures
