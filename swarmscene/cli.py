"""The ``swarmscene`` command: Hydra composes, the engine validates and runs, a summary is printed.

    swarmscene                                    # the default scenario
    swarmscene scenario=cem_six_vehicle avoidance.K=1
    swarmscene --multirun avoidance.K=1,2,5       # a sweep (Hydra launchers)
    swarmscene --help | --cfg job | --info

Bad input prints one line per problem (``dotted.key: what is allowed (got value)``) and exits
with status 2, without a traceback (set ``SWARMSCENE_DEBUG=1`` for one) and without leaving a run
directory behind. In a multirun, a failing job raises an ordinary exception, so the others run.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Any

EXIT_CONFIG = 2
DEBUG_ENV = "SWARMSCENE_DEBUG"


def main() -> None:
    """Console entry point."""
    import hydra

    from .searchpath import register_search_path

    register_search_path()
    debug = bool(os.environ.get(DEBUG_ENV)) or bool(os.environ.get("HYDRA_FULL_ERROR"))
    if debug:
        os.environ[DEBUG_ENV] = "1"  # the task reads it too
    # With HYDRA_FULL_ERROR Hydra raises composition errors instead of printing them with its own
    # multi-line wording, so they reach the one-line formatting below.
    os.environ["HYDRA_FULL_ERROR"] = "1"
    app = hydra.main(config_path="pkg://swarmscene.scenarios", config_name="config", version_base="1.3")(
        _task
    )
    try:
        app()
    except Exception as exc:  # every user-fixable problem becomes one line
        if debug:
            raise
        _report(_error_lines(exc))


def _report(lines: list[str]) -> None:
    for line in lines:
        print(f"swarmscene: {line}", file=sys.stderr)
    sys.exit(EXIT_CONFIG)


def _error_lines(exc: BaseException) -> list[str]:
    from .core.errors import ConfigError
    from .hydra_errors import hydra_error_line

    if isinstance(exc, ConfigError):
        return exc.lines
    line = hydra_error_line(exc)
    if line is not None:
        return [line]
    return [f"{type(exc).__name__}: {exc}".splitlines()[0] + f" (set {DEBUG_ENV}=1 for a traceback)"]


def _task(cfg: Any) -> Any:
    """Hydra task: validate, run, write the run directory, print the summary."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from . import api
    from .core.errors import ConfigError
    from .summary import Progress, summary_text

    hydra_cfg = HydraConfig.get()
    run_dir = Path(hydra_cfg.runtime.output_dir)
    sweep = hydra_cfg.mode == RunMode.MULTIRUN
    data = OmegaConf.to_container(cfg, resolve=True)
    try:
        sim = api.build(data)
    except ConfigError as exc:
        if sweep or os.environ.get(DEBUG_ENV):
            raise  # an ordinary exception: the launcher records it and runs the other jobs
        _remove_unfinished(run_dir)
        # Exit here: an exception would pass through Hydra's job runner, which adds its own line.
        _report(exc.lines)
    output = sim.config.output
    progress = Progress.maybe(output.progress, enabled=not sweep)
    result = sim.run(progress=progress)
    if progress is not None:
        progress.close()
    api.write_outputs(sim, result, run_dir)
    if output.summary:
        print(summary_text(sim, result, run_dir))
    return result.metrics


def _remove_unfinished(run_dir: Path) -> None:
    """Remove the directory Hydra made for a run that never started (it holds only .hydra/)."""
    if run_dir.is_dir() and all(p.name == ".hydra" for p in run_dir.iterdir()):
        shutil.rmtree(run_dir)
        parent = run_dir.parent
        if parent.is_dir() and not any(parent.iterdir()):
            parent.rmdir()
