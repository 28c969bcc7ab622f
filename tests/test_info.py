"""``swarmscene --version`` and ``swarmscene plugins``: what is installed, and who provides it."""

from __future__ import annotations

import platform
import types
from importlib.metadata import version

from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core import registry as registry_module
from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import Formation, PluginParams
from swarmscene.core.registry import make_plugin_manager
from swarmscene.tools import info


def test_version_line_names_the_package_hydra_and_python():
    assert info.version_line() == (
        f"swarmscene {version('swarmscene')} (Hydra {version('hydra-core')}, Python {platform.python_version()})"
    )


def test_package_version_of_an_absent_distribution():
    assert info.package_version("no-such-distribution-xyz") == "not installed"


class _EntryPoint:
    def __init__(self, module):
        self.name, self.value, self._module = "shapes", "shapesdist.plugin", module
        self.dist = types.SimpleNamespace(name="shapesdist", version="2.0.1")

    def load(self):
        return self._module


def test_plugin_table_lists_every_component_with_its_package_and_version(monkeypatch):
    class Spiral(Formation):
        """Agents on a spiral.

        Not shown: only the first line is the description.
        """

        name = "spiral"

        class Params(PluginParams):
            pass

    module = types.SimpleNamespace()

    @hookimpl
    def swarmscene_register_formations(register):
        register(Spiral)

    module.swarmscene_register_formations = swarmscene_register_formations
    monkeypatch.setattr(registry_module, "entry_points", lambda group: [_EntryPoint(module)])
    _, reg = make_plugin_manager(BUILTIN_PLUGINS)
    rows = {(r["kind"], r["name"]): r for r in info.components(reg)}
    assert rows[("formation", "spiral")] == {
        "kind": "formation", "name": "spiral", "package": "shapesdist", "version": "2.0.1",
        "description": "Agents on a spiral.",
    }
    own = version("swarmscene")
    assert rows[("avoidance", "cem")]["package"] == "swarmscene" and rows[("avoidance", "cem")]["version"] == own
    assert rows[("observer", "SafetyMonitor")]["package"] == "swarmscene"
    registered = sum(len(reg.names(kind)) for kind in reg.classes if kind != "observer") + len(reg.observers)
    assert {r["kind"] for r in rows.values()} >= {"disturbance", "event", "observer"}
    assert len(rows) == registered
    text = info.plugins_text(reg).splitlines()
    assert text[0].split() == ["kind", "name", "package", "version", "description"]
    assert len(text) == registered + 1
    spiral = next(line for line in text if " spiral " in line)
    assert spiral.split()[:4] == ["formation", "spiral", "shapesdist", "2.0.1"]
    assert spiral.endswith("Agents on a spiral.")


def _cli(*args):
    import subprocess
    import sys

    code = "from swarmscene.cli import main; main()"
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120)


def test_version_command_prints_the_version_line():
    proc = _cli("--version")
    assert proc.returncode == 0 and proc.stdout.strip() == info.version_line()


def test_plugins_command_lists_the_built_ins():
    proc = _cli("plugins")
    assert proc.returncode == 0
    lines = proc.stdout.splitlines()
    assert lines[0].split() == ["kind", "name", "package", "version", "description"]
    cem = next(line for line in lines if line.split()[:2] == ["avoidance", "cem"])
    assert cem.split()[2:4] == ["swarmscene", version("swarmscene")]
