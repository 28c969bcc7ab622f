"""The optional outputs a run asked for (plots, animation, Rerun replay, ROS 2 bag, live view), as
writer functions the run path calls with the run directory (:func:`swarmscene.runpath.land`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..core.errors import ConfigError

if TYPE_CHECKING:
    from ..core.simulation import Simulation


def unbatched_output(output: Any) -> str | None:
    """The first output option of ``output`` (a scenario's ``output`` section) that a batch of
    worlds does not write (``output.plots=true``, ``output.live=window``...), None when there is
    none: ``api.run_batch`` refuses such a composition, ``hydra/launcher=batch`` runs its jobs one
    by one."""
    asked = files_asked(output) + ([f"output.live={output.live}"] if output.live != "off" else [])
    return asked[0] if asked else None


def files_asked(output: Any) -> list[str]:
    """The output options that write files beside the run's own (``output.plots=true``...)."""
    return [f"output.{key}=true" for key in ("plots", "animation", "rerun", "mcap") if getattr(output, key)]


def extra_writers(sim: Simulation) -> list[Callable[..., Any]]:
    """The optional outputs asked for (plots, animation, Rerun replay, ROS 2 bag), as writer functions; a
    missing optional package is a one-line ConfigError now, not after the run. A live view
    (``output.live``) is attached to ``sim`` here, before its run (swarmscene.views.live)."""
    output = sim.config.output
    writers: list[Callable[..., Any]] = []
    if output.plots or output.animation:
        _require("matplotlib", "output.plots/output.animation", "plots")
        from .plots import write_run_plots

        writers.append(write_run_plots)
    if output.rerun:
        _require("rerun", "output.rerun", "rerun")
        from .replay import export_rerun

        writers.append(export_rerun)
    if output.mcap:  # streams during the run: an observer, whose writer publishes the bag
        _require("zstandard", "output.mcap", "ros")
        from .mcap_bag import attach as attach_bag

        writers.append(attach_bag(sim))
    if output.live != "off":  # streams during the run: an observer on this run's plugin manager
        from .live import attach

        attach(sim)
    return writers


def _require(module: str, option: str, extra: str) -> None:
    """A one-line error naming the extra to install when an optional output's package is missing."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise ConfigError([f"{option}=true needs the {extra!r} extra: pip install 'swarmscene[{extra}]'"])
