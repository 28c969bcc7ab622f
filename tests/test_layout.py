"""The layout shows the architecture: dependencies point one way (app -> plugins -> methods -> core),
a plugin folder holds registered plugin modules only, and each method package stands on its own."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from swarmscene.builtins import BUILTIN_PLUGINS

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"core": "swarmscene.core", "methods": "swarmscene.methods", "plugins": "swarmscene.plugins"}


def module_name(path: Path) -> str:
    folder = path.relative_to(ROOT).parts[0]
    rel = path.relative_to(ROOT / folder).with_suffix("").parts
    return ".".join((PACKAGES[folder], *(rel[:-1] if rel[-1] == "__init__" else rel)))


def imported_modules(path: Path) -> set[str]:
    """Absolute names of every module ``path`` imports (relative imports resolved)."""
    package = module_name(path).rsplit(".", 1)[0] if path.name != "__init__.py" else module_name(path)
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return found


def sources(folder: str) -> list[Path]:
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


@pytest.mark.parametrize("path", sources("plugins"), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_a_plugin_module_imports_no_other_plugin_module(path):
    me = module_name(path)
    others = {
        name for name in imported_modules(path)
        if name.startswith("swarmscene.plugins.") and name.count(".") >= 3 and not me.startswith(name)
        and name.rsplit(".", 1)[0] != "swarmscene.plugins"  # the kind's package itself
    }
    others = {n for n in others if module_name_exists(n)}
    assert not others, f"{me} imports plugin modules {sorted(others)}: move shared numerics to methods/"


def module_name_exists(name: str) -> bool:
    parts = name.split(".")
    if parts[:2] != ["swarmscene", "plugins"]:
        return False
    path = ROOT / "plugins" / Path(*parts[2:])
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


@pytest.mark.parametrize("folder, forbidden", [("core", ("plugins", "methods")), ("methods", ("plugins",))])
def test_dependencies_point_one_way(folder, forbidden):
    for path in sources(folder):
        for name in imported_modules(path):
            parts = name.split(".")
            assert not (parts[0] == "swarmscene" and len(parts) > 1 and parts[1] in forbidden), (
                f"{path.relative_to(ROOT)} imports {name}"
            )


def test_plugin_folders_hold_registered_plugins_only():
    modules = {
        module_name(p) for p in sources("plugins")
        if p.name != "__init__.py" and not p.name.startswith("_")
    }
    unregistered = sorted(modules - set(BUILTIN_PLUGINS))
    assert not unregistered, f"not registered plugins (move their numerics to methods/): {unregistered}"


def test_every_kind_has_a_plugin_folder_with_a_readme_and_a_template():
    """plugins/<kind>/ for each kind of the registry (core/registry.py KINDS), as RotorPy keeps one
    folder per component kind: a README listing its modules and a runnable _template.py."""
    from swarmscene.core.registry import KINDS

    for kind in KINDS:
        folder = ROOT / "plugins" / kind
        missing = [f for f in ("__init__.py", "README.md", "_template.py") if not (folder / f).is_file()]
        assert not missing, f"plugins/{kind}/ lacks {missing}"


@pytest.mark.parametrize("module", BUILTIN_PLUGINS)
def test_a_builtin_module_registers_one_component_of_its_folders_kind(module):
    """One registered plugin per module, through the hook of the kind its folder names (the
    deprecated policy entry-point group's adapter registers what that group lists)."""
    import importlib

    from swarmscene.core.registry import KINDS

    kind = module.split(".")[2]
    loaded = importlib.import_module(module)
    hooks = sorted(name for name in vars(loaded) if name.startswith("swarmscene_register_"))
    assert hooks == [KINDS[kind].hook], f"{module}: registration hooks {hooks}"
    if module.endswith(".entry_point_group"):
        return
    registered: list[type] = []
    getattr(loaded, hooks[0])(registered.append)
    assert len(registered) == 1, f"{module} registers {len(registered)} components"


@pytest.mark.parametrize("folder", ["core", "methods", "plugins"])
def test_the_engine_imports_nothing_of_the_application_layer(folder):
    """Run directories, sweeps, the command line and the pictures are the application's (swarmscene/):
    the engine, the methods and the plugins read and write no run directory (issue #27)."""
    engine = {"core", "methods", "plugins", "scenarios", "plugin"}  # plugin: the public re-export of core
    for path in sources(folder):
        for name in imported_modules(path):
            parts = name.split(".")
            assert not (parts[0] == "swarmscene" and len(parts) > 1 and parts[1] not in engine), (
                f"{path.relative_to(ROOT)} imports {name}, which belongs to the application layer"
            )


def _import_graph(folder: str) -> dict[str, set[str]]:
    """Each module of ``folder`` (a package root of setup.py) and the modules of the same root it
    imports anywhere: at the top, inside functions and under ``TYPE_CHECKING`` alike."""
    mods = {}
    for path in sources(folder):
        rel = path.relative_to(ROOT / folder).with_suffix("").parts
        base = "swarmscene" if folder == "swarmscene" else PACKAGES[folder]
        mods[".".join((base, *(rel[:-1] if rel[-1] == "__init__" else rel)))] = path
    graph = {}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                found.update([base, *(f"{base}.{a.name}" for a in node.names)])
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names)
        graph[name] = {m for m in _with_packages(found) if m in mods and m != name and not _within(name, m)}
    return graph


def _within(module: str, package: str) -> bool:
    """Whether ``package`` holds ``module``: importing its own package is no circle (Python has it
    half-built already, and a sibling's ``from . import x`` names the package only to reach x)."""
    return module.startswith(package + ".")


def _with_packages(names: set[str]) -> set[str]:
    """The modules imported and the packages that hold them (importing ``a.b`` runs ``a``)."""
    out = set(names)
    for name in names:
        parts = name.split(".")
        out.update(".".join(parts[:k]) for k in range(1, len(parts)))
    return out


@pytest.mark.parametrize("folder", ["core", "methods", "plugins", "swarmscene"])
def test_no_import_circle(folder):
    """No module of these packages imports itself through others, at the top, inside functions or
    under ``TYPE_CHECKING`` (issue #35)."""
    import networkx as nx

    graph = nx.DiGraph([(a, b) for a, targets in _import_graph(folder).items() for b in targets])
    circles = [sorted(c) for c in nx.strongly_connected_components(graph) if len(c) > 1]
    assert not circles, f"import circles: {circles}"


def test_no_import_circle_in_the_sweeps_package():
    """swarmscene.sweeps: chunks encodes a launcher task, task runs it, compose composes its jobs;
    none imports back the module that imports it."""
    import networkx as nx

    graph = _import_graph("swarmscene")
    sweeps = {a: {b for b in t if b.startswith("swarmscene.sweeps.")} for a, t in graph.items()
              if a.startswith("swarmscene.sweeps.")}
    g = nx.DiGraph([(a, b) for a, targets in sweeps.items() for b in targets])
    circles = [sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1]
    assert not circles, f"import circles: {circles}"


ROOMS = {
    # the entry points users import (and the old names of moved modules, until they go)
    "": 0, "api": 0, "cli": 0, "env": 0,
    "export": 0, "replay": 0, "docgen": 0, "schema": 0, "compile": 0,
    "tools": 1, "suite": 1,  # commands of their own: the falsifier, docs, schema, info; the benchmark suite
    "rl": 1,                 # the RL environments' machinery: their worlds on worker processes
    "sweeps": 2,             # the sweep: its grid, its launchers, its job, its tables
    "testing": 3,            # the contract checks (public, and listed by the docs generator)
    "runpath": 4,            # the one path from a built run to its directory
    "views": 5,              # what a run prints, draws, streams, replays and exports
    "composition": 5,        # Hydra's side: composing, the search path, Hydra's files and errors
    "runs": 6,               # the run directory's writer and reader, and a run built from its config
    "builtins": 7, "plugin": 7,  # the engine's interface: the built-ins' list, the public plugin module
}
"""The application's rooms (``swarmscene/<room>``), from the entry points down. A module imports its own
room and rooms below it (a larger number) only: nothing below the entry points imports ``api`` or
``cli``, and two rooms on one level do not import each other."""

MOVED = {"export": "views", "replay": "views", "docgen": "tools", "schema": "tools", "compile": "tools"}
"""Top-level names of modules moved into rooms in 0.7.0, kept as forwarding modules until 0.9.0."""


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_every_application_module_is_in_a_room():
    """A new module of the application goes into one of the rooms (or is a new room, placed here)."""
    unplaced = sorted(m for m in _import_graph("swarmscene") if _room(m) not in ROOMS)
    assert not unplaced, f"modules in no room of tests/test_layout.py ROOMS: {unplaced}"


def against_the_rooms(graph: dict[str, set[str]]) -> list[str]:
    """``module -> target`` for each import of ``graph`` that goes up the rooms or across one level."""
    wrong = []
    for module, targets in graph.items():
        here = _room(module)
        for target in targets:
            there = _room(target)
            if there != here and here in ROOMS and there in ROOMS and ROOMS[there] <= ROOMS[here] > 0:
                wrong.append(f"{module} -> {target}")
    return sorted(wrong)


def test_the_application_imports_one_way():
    """Imports go down the rooms (``ROOMS``), at the top of a module, inside functions and under
    ``TYPE_CHECKING`` alike; the entry points alone may import each other (``cli`` runs ``api``)."""
    wrong = against_the_rooms(_import_graph("swarmscene"))
    assert not wrong, "imports against the rooms' direction:\n" + "\n".join(wrong)


def test_the_one_way_check_sees_an_upward_import():
    """The check above has something to find (a check that finds nothing proves nothing)."""
    graph = {
        "swarmscene.views.plots": {"swarmscene.cli", "swarmscene.runs.rundir"},  # up; down
        "swarmscene.views.replay": {"swarmscene.composition.groups"},  # across one level
        "swarmscene.sweeps.job": {"swarmscene.api"},  # up to the public API
        "swarmscene.cli": {"swarmscene.api", "swarmscene.sweeps.job"},  # entry points; down
    }
    assert against_the_rooms(graph) == ["swarmscene.sweeps.job -> swarmscene.api",
                                        "swarmscene.views.plots -> swarmscene.cli",
                                        "swarmscene.views.replay -> swarmscene.composition.groups"]


@pytest.mark.parametrize("old, room", MOVED.items())
def test_a_moved_modules_old_name_only_forwards(old, room):
    """``swarmscene.<old>`` (and ``python -m swarmscene.<old>``) forwards to ``swarmscene.<room>.<old>``
    with a warning that names the new place, and holds nothing of its own."""
    import importlib
    import sys
    import warnings

    sys.modules.pop(f"swarmscene.{old}", None)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        module = importlib.import_module(f"swarmscene.{old}")
    assert module is importlib.import_module(f"swarmscene.{room}.{old}")
    assert [str(w.message) for w in seen if w.category is FutureWarning] == [
        f"swarmscene.{old} moved to swarmscene.{room}.{old}; the old name works until 0.9.0"]
    assert len((ROOT / "swarmscene" / f"{old}.py").read_text().splitlines()) <= 16


HYDRA_INTERNALS = "swarmscene/composition/hydra_internals.py"
PRIVATE_HYDRA = ("hydra._internal", "hydra.core.singleton")
"""Hydra's modules that only :mod:`swarmscene.composition.hydra_internals` may import or name."""


def _is_private_hydra(name: str) -> bool:
    return any(name == p or name.startswith(p + ".") for p in PRIVATE_HYDRA)


def _hydra_names(tree: ast.AST) -> set[str]:
    """The local names a file binds to Hydra's modules or to what it imports from them."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == "hydra" or alias.name.startswith("hydra."):
                    names.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            if node.module == "hydra" or node.module.startswith("hydra."):
                names.update(alias.asname or alias.name for alias in node.names)
    return names


def _root(node: ast.AST) -> ast.AST:
    """The name an attribute chain starts from (``a`` of ``a.b().c[0].d``)."""
    while isinstance(node, (ast.Attribute, ast.Call, ast.Subscript)):
        node = node.func if isinstance(node, ast.Call) else node.value
    return node


def hydra_private_uses(path: Path) -> list[str]:
    """``<file>:<line>: what`` for each use of Hydra's private API in ``path``: an import of
    ``hydra._internal`` or ``hydra.core.singleton``, a string naming one, an attribute of something
    imported from Hydra assigned (``hydra_utils._save_config = ...``, ``HydraConfig.instance().cfg
    = ...``, ``setattr(FileConfigSource, ...)``) or a private one (``_name``) read."""
    tree = ast.parse(path.read_text())
    hydra = _hydra_names(tree)
    where = path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else path.name
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Import):
            found += [(line, f"imports {a.name}") for a in node.names if _is_private_hydra(a.name)]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            full = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            private = [n for n in full if _is_private_hydra(n)]
            if private:
                found.append((line, f"imports {private[0]}"))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            if any(p in node.value for p in PRIVATE_HYDRA):
                found.append((line, f"names {next(p for p in PRIVATE_HYDRA if p in node.value)}"))
        elif isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign, ast.Delete)):
            targets = node.targets if isinstance(node, (ast.Assign, ast.Delete)) else [node.target]
            for target in targets:
                for t in (target.elts if isinstance(target, (ast.Tuple, ast.List)) else [target]):
                    root = _root(t)
                    if isinstance(t, ast.Attribute) and isinstance(root, ast.Name) and root.id in hydra:
                        found.append((line, f"assigns {ast.unparse(t)}"))
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load) and node.attr.startswith("_")
              and not node.attr.startswith("__")):
            root = _root(node)
            if isinstance(root, ast.Name) and root.id in hydra:
                found.append((line, f"reads {ast.unparse(node)}"))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("setattr", "delattr"):
            root = _root(node.args[0]) if node.args else None
            if isinstance(root, ast.Name) and root.id in hydra:
                found.append((line, ast.unparse(node)))
    return [f"{where}:{line}: {what}" for line, what in sorted(found)]


def test_only_hydra_internals_touches_hydras_private_api():
    """Hydra's private modules (``hydra._internal``, ``hydra.core.singleton``) and every patch of
    Hydra's state are in one module, each with its reason and the hydra-core version it was checked
    against (issue #35): a Hydra upgrade is then one file to read."""
    uses = [
        use for folder in ("swarmscene", "core", "methods", "plugins", "scenarios", "hydra_plugins")
        for path in sources(folder) if path.relative_to(ROOT).as_posix() != HYDRA_INTERNALS
        for use in hydra_private_uses(path)
    ]
    assert not uses, "Hydra's private API outside swarmscene/composition/hydra_internals.py:\n" + "\n".join(uses)


def test_the_private_api_check_sees_each_kind_of_use(tmp_path):
    """The check above finds what it looks for (a check that finds nothing proves nothing)."""
    path = tmp_path / "probe.py"
    path.write_text(
        "import hydra.core.utils as hydra_utils\n"
        "from hydra._internal.config_loader_impl import ConfigLoaderImpl\n"
        "from hydra.core import singleton\n"
        "from hydra.core.hydra_config import HydraConfig\n"
        "TARGET = 'hydra._internal.core_plugins.basic_sweeper.BasicSweeper'\n"
        "hydra_utils._save_config = print\n"
        "HydraConfig.instance().cfg = None\n"
        "setattr(ConfigLoaderImpl, 'x', 1)\n"
        "cfg.hydra.job.num = 1\n"
        "writer = hydra_utils._save_config\n"
    )
    uses = hydra_private_uses(path)
    assert [u.split(": ", 1)[0].rsplit(":", 1)[1] for u in uses] == ["2", "3", "5", "6", "7", "8", "10"], uses
