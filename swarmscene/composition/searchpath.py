"""The engine's Hydra setup before composing: third-party config folders on the search path, and
plain ``key=value`` for every documented option.

A plugin package contributes YAML options (``avoidance/myalgo.yaml``...) through an entry point in
the group ``swarmscene.conf`` whose value names the package holding its config folders (each
folder with an ``__init__.py``), e.g. in its pyproject::

    [project.entry-points."swarmscene.conf"]
    myalgo = "myalgo.conf"

The package joins Hydra's search path as ``pkg://myalgo.conf``.

Hydra's own discovery of ``hydra_plugins.*`` does not see setuptools editable installs, so the
engine registers this search-path plugin in code before composing.

Hydra's struct mode refuses ``key=value`` for a key the composed YAML does not hold (``+key``
adds one). Group YAML files hold only the plugin's ``name`` and deliberate deviations from its
``Params`` defaults, so most documented options are absent from the composition:
:func:`plain_overrides` rewrites each plain dotted override ``a.b=v`` (and each value list of a
sweep) into ``++a.b=v`` (add or replace) before Hydra parses the command line, and the engine's
validation then names a misspelt key with the valid ones (``avoidance.Kx: unknown key (valid keys:
...)``).
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib.metadata import entry_points

from hydra.core.config_search_path import ConfigSearchPath
from hydra.core.plugins import Plugins
from hydra.plugins.search_path_plugin import SearchPathPlugin

CONF_GROUP = "swarmscene.conf"  # = core.registry.CONF_ENTRY_POINT_GROUP (not imported: a light start)


def third_party_config_paths() -> list[tuple[str, str]]:
    """(provider, search-path entry) of every installed ``swarmscene.conf`` entry point that
    ``SWARMSCENE_DISABLE_PLUGINS`` does not name (``name`` or ``dist:name``, as for plugins)."""
    import os

    from ..core.registry import DISABLE_ENV

    blocked = {b.strip() for b in os.environ.get(DISABLE_ENV, "").split(",") if b.strip()}
    found = []
    for ep in entry_points(group=CONF_GROUP):
        dist = ep.dist.name if ep.dist is not None else ep.name
        if ep.name in blocked or f"{dist}:{ep.name}" in blocked:
            continue
        path = ep.value if "://" in ep.value else f"pkg://{ep.value}"
        found.append((f"swarmscene-{dist}", path))
    return sorted(found)


class SwarmsceneSearchPathPlugin(SearchPathPlugin):
    """Appends every third-party config folder after the engine's own tree."""

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        """Append each installed package's config folder to Hydra's search path."""
        for provider, path in third_party_config_paths():
            search_path.append(provider=provider, path=path)


def register_search_path() -> None:
    """Make Hydra use :class:`SwarmsceneSearchPathPlugin` and know swarmscene's sweeper
    (``hydra_plugins.swarmscene_sweeper``), :mod:`swarmscene.composition.hydra_files` and
    :mod:`swarmscene.composition.scenario_files`; idempotent."""
    from hydra_plugins.swarmscene_sweeper import register as register_sweeper

    from .groups import register_help_resolver
    from .hydra_files import install as protect_run_dirs
    from .scenario_files import install as check_scenario_files

    protect_run_dirs()  # the name's resolver in the run-dir patterns; .hydra/ written safely
    plugins = Plugins.instance()
    if SwarmsceneSearchPathPlugin not in plugins.class_name_to_class.values():
        plugins.register(SwarmsceneSearchPathPlugin)
    register_sweeper()
    # After Plugins.instance(): its first scan re-executes the modules of Hydra's config sources
    check_scenario_files()  # size, depth, alias expansion, UTF-8, no oc.env (scenario_files.py)
    register_help_resolver()  # the --help template's group list


def plain_overrides(overrides: Sequence[str]) -> list[str]:
    """``overrides`` with every plain dotted value override ``a.b=v`` spelled ``++a.b=v``.

    Left as written: ``+``, ``++`` and ``~`` overrides, group choices (no dot: ``avoidance=cem``,
    ``hydra/launcher=joblib``), ``key@package`` overrides, Hydra's own ``hydra.*`` keys and text
    Hydra cannot parse (Hydra reports it). A sweep ``a.b=1,2`` becomes ``++a.b=1,2``, which Hydra's
    sweepers expand into one ``++a.b=v`` per job.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import OverrideType
    from hydra.errors import OverrideParseException

    parser = OverridesParser.create()
    rewritten = []
    for text in overrides:
        try:
            (override,) = parser.parse_overrides([text])
        except OverrideParseException:
            rewritten.append(text)
            continue
        key = override.key_or_group
        plain = (
            override.type == OverrideType.CHANGE
            and override.package is None
            and "." in key
            and "/" not in key
            and not key.startswith("hydra.")
            and text.startswith(key)
        )
        rewritten.append(f"++{text}" if plain else text)
    return rewritten


OPTIONS_WITH_VALUE = frozenset(
    {"-cp", "--config-path", "-cn", "--config-name", "-cd", "--config-dir", "-c", "--cfg",
     "-p", "--package", "--experimental-rerun"}
)
"""Hydra's command-line flags followed by a value (which is not an override)."""


def plain_command_line(argv: Sequence[str]) -> list[str]:
    """``argv`` (without the program name) with :func:`plain_overrides` applied to its overrides,
    and a relative ``--config-path`` made absolute from the working directory (Hydra would resolve
    it against the installed package), so a run directory is re-run with
    ``swarmscene --config-path <run dir> --config-name config``.

    Shell completion (``-sc``) is left alone: its ``query=...`` words are not the app's overrides.
    ``--info`` takes an optional word, never of the form ``key=value``. An override without a key
    (``=3``) is a :class:`~swarmscene.core.errors.ConfigError` naming it.
    """
    args = list(argv)
    if any(a in ("-sc", "--shell-completion") for a in args):
        return args
    out: list[str] = []
    overrides: list[str] = []
    option = None  # the flag whose value comes next
    for arg in args:
        if option is not None:
            out.append(_absolute(arg) if option in ("-cp", "--config-path") else arg)
            option = None
        elif arg.startswith("--config-path="):
            out.append("--config-path=" + _absolute(arg.partition("=")[2]))
        elif arg.startswith("-"):
            out.append(arg)
            option = arg if arg in OPTIONS_WITH_VALUE else None
        elif arg.lstrip("+~").startswith("="):  # Hydra: "Config group override must be a string or a list"
            from ..core.errors import ConfigError

            raise ConfigError([f"{arg}: an override needs a key before '=' (key=value; got {arg!r})"])
        else:
            overrides.append(arg)
            out.extend(plain_overrides([arg]))
    return out


def _absolute(path: str) -> str:
    import os

    return path if "://" in path or os.path.isabs(path) else os.path.abspath(path)
