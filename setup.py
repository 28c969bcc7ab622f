"""Package discovery for the folder-to-package mapping of ../shared/ARCHITECTURE.md.

The top-level folders are mapped to namespaced packages (``core/`` -> ``swarmscene.core``). Every
folder below a mapped root that holds an ``__init__.py`` is a package, so adding a package needs no
edit here or in pyproject.toml; tests/test_packaging.py checks that the wheel holds every file the
source tree has. (setuptools' own ``find`` cannot map prefixes, and hatchling cannot do this in
editable mode.)
"""

from pathlib import Path

from setuptools import setup

ROOTS = {
    "swarmscene": "swarmscene",
    "swarmscene.core": "core",
    "swarmscene.methods": "methods",
    "swarmscene.plugins": "plugins",
    "swarmscene.scenarios": "scenarios",
    "hydra_plugins.swarmscene_sweeper": "hydra_plugins/swarmscene_sweeper",
}


def discover(roots: dict[str, str]) -> dict[str, str]:
    """Every package under each root (a folder with ``__init__.py``), mapped to its folder."""
    here = Path(__file__).parent
    found: dict[str, str] = {}
    for package, folder in roots.items():
        base = here / folder
        for init in sorted(base.rglob("__init__.py")):
            parts = init.parent.relative_to(base).parts
            if "__pycache__" in parts or any(p.startswith(".") for p in parts):
                continue
            found[".".join((package, *parts))] = init.parent.relative_to(here).as_posix()
    return found


PACKAGE_DIR = discover(ROOTS)
setup(packages=sorted(PACKAGE_DIR), package_dir=PACKAGE_DIR)
