"""What is installed: ``swarmscene --version`` and ``swarmscene plugins``.

swarmscene --version     # swarmscene 0.2.0 (Hydra 1.3.2, Python 3.11.7)
swarmscene plugins       # every registered component: kind, name, package, version, description
"""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version
from typing import Any

DISTRIBUTION = "swarmscene"


def package_version(name: str = DISTRIBUTION) -> str:
    """An installed distribution's version, or ``"not installed"``."""
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


def version_line() -> str:
    """One line: this package's version, then Hydra's and Python's (what a bug report needs)."""
    return (f"swarmscene {package_version()} (Hydra {package_version('hydra-core')}, "
            f"Python {platform.python_version()})")


def _description(cls: type) -> str:
    """The first line of a class's docstring (its one-line description)."""
    doc = (cls.__doc__ or "").strip()
    return doc.splitlines()[0].strip() if doc else ""


def components(registry: Any) -> list[dict[str, str]]:
    """One row per registered component: kind, name, package, version, description.

    A built-in is provided by this package; a third-party class by the distribution whose entry
    point registered it (``Registry.sources`` and ``Registry.distributions``).
    """
    own = (DISTRIBUTION, package_version())
    rows = []
    for kind in sorted(registry.classes):
        if kind == "observer":
            continue  # listed below, in the order they run
        for name in registry.names(kind):
            cls = registry.classes[kind][name]
            source = registry.sources.get((kind, name), "")
            dist, ver = registry.distributions.get(source, own)
            rows.append({"kind": kind, "name": name, "package": dist, "version": ver,
                         "description": _description(cls)})
    for cls in registry.observers:
        dist = _observer_package(cls, registry)
        rows.append({"kind": "observer", "name": cls.__name__, "package": dist,
                     "version": package_version(dist) if dist != "unknown" else "",
                     "description": _description(cls)})
    return rows


def _observer_package(cls: type, registry: Any) -> str:
    """Observers are registered without a name: the package is read from the class's module."""
    module = cls.__module__
    if module.startswith(f"{DISTRIBUTION}."):
        return DISTRIBUTION
    top = module.split(".")[0]
    for dist, _ in registry.distributions.values():
        if dist.replace("-", "_").lower() == top.lower():
            return dist
    return "unknown"


def plugins_text(registry: Any) -> str:
    """``swarmscene plugins``: an aligned table, one component per line."""
    rows = components(registry)
    header = {"kind": "kind", "name": "name", "package": "package", "version": "version", "description": "description"}
    keys = ("kind", "name", "package", "version")
    widths = {k: max(len(r[k]) for r in [header, *rows]) for k in keys}
    lines = []
    for row in [header, *rows]:
        lines.append("  ".join(row[k].ljust(widths[k]) for k in keys) + "  " + row["description"])
    return "\n".join(line.rstrip() for line in lines)


def command(name: str) -> int:
    """``swarmscene --version`` or ``swarmscene plugins``: print, return the exit status."""
    if name == "--version":
        print(version_line())
        return 0
    from ..runs.build import plugins

    _, registry = plugins()
    print(plugins_text(registry))
    return 0
