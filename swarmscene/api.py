"""Python API for notebooks and tests: compose, validate, run.

Example::

    from swarmscene import api
    result = api.run(["scenario=cem_six_vehicle", "avoidance.K=1"])
    result.metrics["cem.max_speed"], result.trajectory["pos"].shape

``run`` accepts Hydra overrides (a list of ``key=value`` strings), an already composed plain dict,
or a validated :class:`~swarmscene.core.config.Scenario`. Outputs are written only when
``output_dir`` is given.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .builtins import BUILTIN_PLUGINS
from .core.config import Scenario, validate
from .core.errors import ConfigError
from .core.registry import Registry, make_plugin_manager
from .core.result import RunResult
from .core.simulation import Simulation

CONFIG_MODULE = "swarmscene.scenarios"
CONFIG_NAME = "config"


def plugins() -> tuple[Any, Registry]:
    """A fresh plugin manager (built-ins, then entry points) and its registry."""
    return make_plugin_manager(BUILTIN_PLUGINS)


def compose(overrides: Sequence[str] = ()) -> dict[str, Any]:
    """Compose the config tree with Hydra overrides; return plain data without the ``hydra`` node.

    Every documented option is set with plain ``key=value`` (rewritten to ``++key=value``,
    :func:`swarmscene.searchpath.plain_overrides`), whether or not the composed YAML holds it.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module
    from omegaconf import OmegaConf

    from .searchpath import plain_overrides, register_search_path

    register_search_path()
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        cfg = hydra_compose(config_name=CONFIG_NAME, overrides=plain_overrides(overrides))
    return OmegaConf.to_container(cfg, resolve=True)


def load(config: Sequence[str] | dict[str, Any] = (), registry: Registry | None = None) -> Scenario:
    """Compose (if given overrides) and validate; raises ConfigError with one line per problem.

    A dict is taken as composed data: a run directory's ``config.yaml`` (the effective
    configuration) loads back to the same scenario.
    """
    data = config if isinstance(config, dict) else compose(config)
    data = {k: v for k, v in data.items() if k != "hydra"}
    if registry is None:
        _, registry = plugins()
    return validate(data, registry)


def build(
    config: Sequence[str] | dict[str, Any] | Scenario = (),
    plugin_set: tuple[Any, Registry] | None = None,
) -> Simulation:
    """A ready-to-run :class:`Simulation` owning a plugin manager.

    Args:
        config: overrides, composed data, or a scenario validated by ``load``.
        plugin_set: the ``(plugin manager, registry)`` pair of :func:`plugins` that validated
            ``config`` (one manager per run); a fresh one when omitted.
    """
    pm, registry = plugin_set if plugin_set is not None else plugins()
    scenario = config if isinstance(config, Scenario) else load(config, registry)
    try:
        return Simulation(scenario, pm, registry.observers)
    except ConfigError:
        raise
    except Exception as exc:  # options valid one by one that no plugin can build (memory, overflow)
        raise ConfigError([build_error_line(scenario, exc)]) from exc


def build_error_line(scenario: Scenario, exc: BaseException) -> str:
    """One line for an exception raised while building a run: the plugin kind whose code raised
    it (the first plugin module in the traceback), its name, and the exception."""
    reason = f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}"
    modules = {cls.__module__: kind for kind, cls in scenario.plugin_classes.items()}
    tb = exc.__traceback__
    while tb is not None:
        kind = modules.get(tb.tb_frame.f_globals.get("__name__"))
        if kind is not None:
            name = scenario.plugin_classes[kind].name
            return f"{kind}: {name!r} cannot be built for this scenario (swarm.n = {scenario.config.swarm.n}): {reason}"
        tb = tb.tb_next
    return f"scenario: cannot be built: {reason}"


def run(
    config: Sequence[str] | dict[str, Any] | Scenario = (),
    output_dir: str | Path | None = None,
    progress: Callable[[Simulation], None] | None = None,
) -> RunResult:
    """Run a scenario; write its run directory when ``output_dir`` is given."""
    sim = build(config)
    started_at = utc_now()
    result = sim.run(progress=progress)
    if output_dir is not None:
        write_outputs(sim, result, Path(output_dir), started_at=started_at)
    return result


def utc_now() -> str:
    """The current time, UTC, ISO 8601 (the manifest's ``started_at``)."""
    from datetime import datetime, timezone

    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def write_outputs(
    sim: Simulation,
    result: RunResult,
    run_dir: Path,
    extras: Sequence[Callable[[Path], Any]] = (),
    started_at: str | None = None,
) -> None:
    """Write config, trajectory, metrics and manifest of a finished run into ``run_dir``;
    ``extras(run_dir)`` (plots, replay) write theirs before the manifest, which lists them.

    ``config.yaml`` is the effective configuration (``sim.scenario.data``); ``started_at`` is the
    run's start (UTC, ISO 8601) for the manifest.
    """
    from .core.outputs import write_run_dir

    write_run_dir(
        run_dir,
        data=sim.scenario.data,
        metrics=result.metrics,
        trajectory=result.trajectory,
        complete=result.complete,
        seed=sim.config.seed,
        extras=extras,
        started_at=started_at,
    )
    result.run_dir = run_dir
