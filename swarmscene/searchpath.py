"""Third-party config folders on Hydra's search path.

A plugin package contributes YAML options (``avoidance/myalgo.yaml``...) through an entry point in
the group ``swarmscene.conf`` whose value names the package holding its config folders (each
folder with an ``__init__.py``), e.g. in its pyproject::

    [project.entry-points."swarmscene.conf"]
    myalgo = "myalgo.conf"

The package joins Hydra's search path as ``pkg://myalgo.conf``.

Hydra's own discovery of ``hydra_plugins.*`` does not see setuptools editable installs, so the
engine registers this search-path plugin in code before composing.
"""

from __future__ import annotations

from importlib.metadata import entry_points

from hydra.core.config_search_path import ConfigSearchPath
from hydra.core.plugins import Plugins
from hydra.plugins.search_path_plugin import SearchPathPlugin

CONF_GROUP = "swarmscene.conf"


def third_party_config_paths() -> list[tuple[str, str]]:
    """(provider, search-path entry) of every installed ``swarmscene.conf`` entry point."""
    found = []
    for ep in entry_points(group=CONF_GROUP):
        dist = ep.dist.name if ep.dist is not None else ep.name
        path = ep.value if "://" in ep.value else f"pkg://{ep.value}"
        found.append((f"swarmscene-{dist}", path))
    return sorted(found)


class SwarmsceneSearchPathPlugin(SearchPathPlugin):
    """Appends every third-party config folder after the engine's own tree."""

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        for provider, path in third_party_config_paths():
            search_path.append(provider=provider, path=path)


def register_search_path() -> None:
    """Make Hydra use :class:`SwarmsceneSearchPathPlugin` and know swarmscene's sweeper
    (``hydra_plugins.swarmscene_sweeper``); idempotent."""
    from hydra_plugins.swarmscene_sweeper import register as register_sweeper

    plugins = Plugins.instance()
    if SwarmsceneSearchPathPlugin not in plugins.class_name_to_class.values():
        plugins.register(SwarmsceneSearchPathPlugin)
    register_sweeper()
