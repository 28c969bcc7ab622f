"""swarmscene.plugin: the one module a plugin author imports, and its BuildContext factory."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from swarmscene import plugin
from swarmscene.core import plugin as core_plugin
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState

ROOT = Path(__file__).resolve().parents[1]
AUTHOR_FILES = [
    *sorted((ROOT / "plugins").glob("*/_template.py")),
    ROOT / "docs" / "examples" / "swarmscene-slowdown" / "swarmscene_slowdown" / "plugin.py",
]


def test_the_public_module_reexports_the_engine_classes_themselves():
    assert plugin.Avoidance is core_plugin.Avoidance and plugin.PluginParams is core_plugin.PluginParams
    assert plugin.Setpoints is Setpoints and plugin.Mode is Mode and plugin.WorldState is WorldState
    assert set(plugin.__all__) == {name for name in plugin.__all__ if hasattr(plugin, name)}


@pytest.mark.parametrize("path", AUTHOR_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_templates_and_the_packaged_example_import_only_the_public_module(path):
    imported = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module)
        elif isinstance(node, ast.Import):
            imported.update(alias.name for alias in node.names)
    ours = {name for name in imported if name.split(".")[0] == "swarmscene"}
    assert ours == {"swarmscene.plugin"}


PUBLIC_API_KINDS = ("formation", "avoidance", "dynamics", "policy", "observer", "event", "generator", "disturbance")
"""The kinds whose built-ins are worked examples of the public API (issue #35): every kind, now that
the event kinds and disturbance models sit in their plugin folders (their numerics in methods/)."""


@pytest.mark.parametrize(
    "path", [p for kind in PUBLIC_API_KINDS for p in sorted((ROOT / "plugins" / kind).glob("*.py"))
             if p.name != "__init__.py"], ids=lambda p: str(p.relative_to(ROOT)))
def test_a_builtin_plugin_imports_the_engine_only_through_the_public_module(path):
    """A built-in imports what a third-party plugin may (``swarmscene.plugin``) and its own
    numerics (``swarmscene.methods``), never the engine's internals."""
    engine = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = [node.module or ""] if isinstance(node, ast.ImportFrom) else (
            [a.name for a in node.names] if isinstance(node, ast.Import) else [])
        engine.update(n for n in names if n == "swarmscene.core" or n.startswith("swarmscene.core."))
    assert not engine, f"{path.relative_to(ROOT)} imports {sorted(engine)}: import them from swarmscene.plugin"


def test_build_context_is_what_a_small_scenario_gives():
    ctx = plugin.build_context(n=4, seed=3)
    assert ctx.n == 4 and ctx.guidance_period == 0.1 and ctx.physics_step == 0.01
    np.testing.assert_array_equal(ctx.initial.pos, [[0, 0, 2], [0, 3, 2], [3, 0, 2], [3, 3, 2]])
    assert ctx.initial.leader == 0 and ctx.environment.tree is None
    assert ctx.rng.random() == np.random.default_rng(3).random()
    assert (ctx.separation_limit, ctx.clearance_limit, ctx.comm_range, ctx.duration) == (0.5, 0.2, 10.0, 10.0)


def test_build_context_takes_positions_and_any_field():
    pos = np.array([[0.0, 0.0, 1.0], [5.0, 0.0, 1.0]])
    ctx = plugin.build_context(positions=pos, leader=None, separation_limit=1.5, duration=3.0)
    assert ctx.n == 2 and ctx.initial.leader is None
    assert ctx.separation_limit == 1.5 and ctx.duration == 3.0
    np.testing.assert_array_equal(ctx.initial.pos, pos)
    with pytest.raises(TypeError):
        plugin.build_context(n=2, no_such_field=1)
