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
    """Compose (if given overrides) and validate; raises ConfigError with one line per problem."""
    data = config if isinstance(config, dict) else compose(config)
    data = {k: v for k, v in data.items() if k != "hydra"}
    if registry is None:
        _, registry = plugins()
    return validate(data, registry)


def build(config: Sequence[str] | dict[str, Any] | Scenario = ()) -> Simulation:
    """A ready-to-run :class:`Simulation` owning a fresh plugin manager."""
    pm, registry = plugins()
    scenario = config if isinstance(config, Scenario) else load(config, registry)
    return Simulation(scenario, pm, registry.observers)


def run(
    config: Sequence[str] | dict[str, Any] | Scenario = (),
    output_dir: str | Path | None = None,
    progress: Callable[[Simulation], None] | None = None,
) -> RunResult:
    """Run a scenario; write its run directory when ``output_dir`` is given."""
    sim = build(config)
    result = sim.run(progress=progress)
    if output_dir is not None:
        write_outputs(sim, result, Path(output_dir))
    return result


def write_outputs(
    sim: Simulation, result: RunResult, run_dir: Path, extras: Sequence[Callable[[Path], Any]] = ()
) -> None:
    """Write config, trajectory, metrics and manifest of a finished run into ``run_dir``;
    ``extras(run_dir)`` (plots, replay) write theirs before the manifest, which lists them."""
    from .core.outputs import write_run_dir

    write_run_dir(
        run_dir,
        data=sim.scenario.data,
        metrics=result.metrics,
        trajectory=result.trajectory,
        complete=result.complete,
        seed=sim.config.seed,
        extras=extras,
    )
    result.run_dir = run_dir
