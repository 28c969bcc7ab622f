"""The lint habits (issue #27): ruff (pycodestyle, pyflakes, isort, bugbear, pyupgrade and the
Google docstring rules) over the package, tests/ and benchmarks/, and mypy over the package, both
without a finding. The rules and their few ignores, each with its reason, are in pyproject.toml.

mypy cannot check the source tree as it stands: setup.py maps folders to modules (``core/`` ->
``swarmscene.core``), so :func:`link_tree` builds that layout from links and mypy checks the links.
``python tests/test_lint.py`` prints every finding of both tools (paths in the source tree).
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# benchmarks/ too: unlinted, it hid an UnboundLocalError (bench_sweep.py --jobs-per-task, issue #35).
RUFF_PATHS = ("core", "methods", "plugins", "swarmscene", "scenarios", "hydra_plugins", "tests", "benchmarks")


def package_roots() -> dict[str, str]:
    """setup.py's ``ROOTS`` (package -> folder), read without running setup()."""
    tree = ast.parse((ROOT / "setup.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "ROOTS" for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError("setup.py: no ROOTS mapping")


def link_tree(base: Path) -> dict[Path, Path]:
    """The installed layout under ``base``, each package folder a link to its source folder.

    Returns:
        each link (relative to ``base``) and the source folder it points to (relative to the repo).
    """
    links: dict[Path, Path] = {}
    roots = package_roots()
    for package, folder in sorted(roots.items(), key=lambda item: item[0].count(".")):
        target = base.joinpath(*package.split("."))
        if package == "swarmscene":  # its subpackages (core, methods, ...) come from other roots
            target.mkdir(parents=True, exist_ok=True)
            for child in (ROOT / folder).iterdir():
                if child.name != "__pycache__":
                    (target / child.name).symlink_to(child)
                    links[target.relative_to(base) / child.name] = Path(folder) / child.name
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        target.symlink_to(ROOT / folder, target_is_directory=True)
        links[target.relative_to(base)] = Path(folder)
    return links


def source_path(line: str, links: dict[Path, Path]) -> str:
    """A mypy line with its path in the link tree turned into the path in the source tree."""
    path, sep, rest = line.partition(":")
    for link, folder in sorted(links.items(), key=lambda item: -len(item[0].parts)):
        if Path(path).parts[: len(link.parts)] == link.parts:
            return str(folder.joinpath(*Path(path).parts[len(link.parts):])) + sep + rest
    return line


def ruff_findings() -> list[str]:
    """Every ruff finding over :data:`RUFF_PATHS`, one line each (no cache written)."""
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--no-cache", "--output-format", "concise", *RUFF_PATHS],
        cwd=ROOT, capture_output=True, text=True, check=False,
    )
    assert proc.returncode in (0, 1), proc.stderr  # 2: ruff itself failed (config, crash)
    return [line for line in proc.stdout.splitlines() if re.match(r"\S+:\d+:\d+: ", line)]


def mypy_findings(base: Path) -> list[str]:
    """Every mypy error over the package (checked as installed, through :func:`link_tree`)."""
    links = link_tree(base / "tree")
    env = {**os.environ, "MYPYPATH": str(base / "tree")}
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
         "--cache-dir", str(base / "cache"), "--no-error-summary", "--hide-error-context",
         "-p", "swarmscene", "-p", "hydra_plugins.swarmscene_sweeper"],
        cwd=base / "tree", env=env, capture_output=True, text=True, check=False,
    )
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr  # 2: mypy itself failed
    return [source_path(line, links) for line in proc.stdout.splitlines() if ": error:" in line]


def test_ruff_finds_nothing():
    found = ruff_findings()
    assert found == [], f"{len(found)} ruff findings:\n" + "\n".join(found)


def test_mypy_finds_nothing(tmp_path):
    found = mypy_findings(tmp_path)
    assert found == [], f"{len(found)} mypy errors:\n" + "\n".join(found)


def test_the_link_tree_is_the_installed_layout(tmp_path):
    links = link_tree(tmp_path)
    assert links[Path("swarmscene/core")] == Path("core")
    assert links[Path("hydra_plugins/swarmscene_sweeper")] == Path("hydra_plugins/swarmscene_sweeper")
    assert (tmp_path / "swarmscene" / "plugins" / "formation" / "outdoor_mission.py").is_file()
    assert (tmp_path / "swarmscene" / "cli.py").resolve() == ROOT / "swarmscene" / "cli.py"
    line = "swarmscene/methods/outdoor/mission.py:12: error: x  [misc]"
    assert source_path(line, links) == "methods/outdoor/mission.py:12: error: x  [misc]"


def test_every_name_the_config_module_lists_is_bound():
    """``core.config`` is the schema only (the validation pass and the memory checks import it and
    live in their own modules, issue #35): every name in its ``__all__`` is bound there."""
    from swarmscene.core import config

    assert [name for name in config.__all__ if name not in vars(config)] == []
    assert not hasattr(config, "validate") and not hasattr(config, "estimated_memory")


if __name__ == "__main__":
    import tempfile
    from collections import Counter

    for tool, found in (("ruff", ruff_findings()), ("mypy", mypy_findings(Path(tempfile.mkdtemp())))):
        print(f"{tool}: {len(found)} findings")
        for path, count in Counter(line.split(":", 1)[0] for line in found).most_common():
            print(f"  {count:4d}  {path}")
