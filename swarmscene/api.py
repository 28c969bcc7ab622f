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

import re
from collections.abc import Callable, Sequence
from datetime import UTC
from pathlib import Path
from typing import Any, cast

from .builtins import BUILTIN_PLUGINS
from .core.config import Scenario
from .core.errors import ConfigError
from .core.registry import Registry, make_plugin_manager
from .core.result import RunResult
from .core.simulation import Simulation
from .core.validation import validate
from .runpath import utc_now, write_outputs  # noqa: F401 (write_outputs: part of the api, used by tests and tools)

CONFIG_MODULE = "swarmscene.scenarios"
CONFIG_NAME = "config"


def plugins() -> tuple[Any, Registry]:
    """A fresh plugin manager (built-ins, then entry points) and its registry."""
    return make_plugin_manager(BUILTIN_PLUGINS)


def compose(overrides: Sequence[str] = ()) -> dict[str, Any]:
    """Compose the config tree with Hydra overrides; return plain data without the ``hydra`` node.

    Every documented option is set with plain ``key=value`` (rewritten to ``++key=value``,
    :func:`swarmscene.searchpath.plain_overrides`), whether or not the composed YAML holds it.
    A composition that fails (an unknown option, a value that does not parse or resolve) raises
    :class:`~swarmscene.core.errors.ConfigError` with the command line's one-line wording.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module
    from omegaconf import OmegaConf

    from .searchpath import plain_overrides, register_search_path

    register_search_path()
    try:
        with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
            cfg = hydra_compose(config_name=CONFIG_NAME, overrides=plain_overrides(overrides))
        return cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=True))  # the root is a mapping
    except ConfigError:
        raise
    except Exception as exc:  # Hydra's multi-line wording: the command line's one line instead
        from .hydra_errors import hydra_error_line

        line = hydra_error_line(exc)  # the command line's reading (an unresolvable value included)
        if line is None:
            raise
        raise ConfigError([line]) from exc


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
    from .core.raised import zero_options

    reason = f"{type(exc).__name__}: {(str(exc).splitlines() or [''])[0]}"
    modules = {cls.__module__: kind for kind, cls in scenario.plugin_classes.items()}
    tb = exc.__traceback__
    while tb is not None:
        kind = modules.get(tb.tb_frame.f_globals.get("__name__"))
        if kind is not None:
            name = scenario.plugin_classes[kind].name
            options = zero_options(exc, tb.tb_frame.f_locals.get("self"), kind) or zero_options(
                exc, _Holder(scenario.plugin_params.get(kind)), kind)
            return (f"{kind}: {name!r} cannot be built for this scenario (swarm.n = {scenario.config.swarm.n})"
                    f"{options}: {reason}")
        tb = tb.tb_next
    return f"scenario: cannot be built: {reason}"


class _Holder:
    """A plugin's ``params`` before the plugin exists (a constructor that raised)."""

    def __init__(self, params: Any) -> None:
        self.params = params


def run(
    config: Sequence[str] | dict[str, Any] | Scenario = (),
    output_dir: str | Path | None = None,
    progress: Callable[[Simulation], None] | None = None,
) -> RunResult:
    """Run a scenario; write its run directory when ``output_dir`` is given.

    Every output option is honoured as on the command line: with ``output_dir``, ``output.plots``,
    ``output.animation``, ``output.rerun`` and ``output.mcap`` write their files (a missing extra is a one-line
    ConfigError before the run); without one, asking for files is a one-line ConfigError.
    ``output.progress`` shows the progress line (``auto``: only on a terminal) unless ``progress``
    is given; ``output.summary`` prints the run's summary (set it false to keep a notebook quiet).
    """
    from .runpath import fly, land
    from .summary import Progress, summary_text

    sim = build(config)
    output = sim.config.output
    if output_dir is None:
        asked = _files_asked(output)
        if asked:
            raise ConfigError([f"{asked[0]}: writes files, so it needs a run directory: api.run(..., output_dir=...)"])
    writers = extra_writers(sim)
    flight = fly(sim, progress or Progress.maybe(output.progress))
    result = flight.result
    if output_dir is not None:
        run_dir = Path(output_dir)
        failed = land(sim, flight, run_dir, writers)
        if failed is not None:
            from .sweeps.records import record_failure

            record_failure(run_dir, failed, sim.scenario.data)
    if flight.raised is not None:
        raise flight.raised
    if output.summary:
        print(summary_text(sim, result, result.run_dir))
    return result


def run_batch(
    config: Sequence[str] | dict[str, Any] = (),
    seeds: Sequence[int] = (0,),
    output_dir: str | Path | None = None,
    progress: Callable[[Any], None] | None = None,
) -> list[RunResult]:
    """Run one composition under several seeds as one batch of worlds (docs/batched.md).

    The worlds are stepped together (:class:`~swarmscene.core.batch.BatchSimulation`): the
    dynamics model advances every world's physics in one call where it has a batched form. Each
    world's result equals ``run(config + [f"seed={seed}"])``'s, bit for bit, except the timing
    metrics (``wall_time``, ``realtime_factor``, ``step_ms_median``), which are the batch's.

    Args:
        config: overrides or composed data, as for :func:`run` (composed once).
        seeds: one world per seed, in this order.
        output_dir: when given, world ``b`` writes its run directory to ``output_dir/<b>`` (the
            numbering of a sweep's jobs), as :func:`run` writes one.
        progress: called after every tick of the batch with the
            :class:`~swarmscene.core.batch.BatchSimulation`.

    Returns:
        One result per seed. A world a plugin's exception stopped has its ``error`` set (its
        records up to then are kept) and does not stop the others; nothing is raised for it.
        No summary is printed (``result.metrics`` holds what it would say).
    """
    from .core.batch import BatchSimulation

    if isinstance(config, Scenario):
        raise TypeError("run_batch takes overrides or composed data (each world validates its own seed)")
    seeds = [int(seed) for seed in seeds]
    if not seeds:
        raise ConfigError(["seeds: a batch needs at least one seed"])
    data = config if isinstance(config, dict) else compose(config)
    first = build({**data, "seed": seeds[0]})
    refused = unbatched_output(first.config.output)  # the same for every world: one composition
    if refused is not None:
        raise ConfigError([f"{refused}: not written by a batch of worlds (run that world alone)"])
    sims = [first, *(build({**data, "seed": seed}) for seed in seeds[1:])]
    started_at = utc_now()
    outcomes = BatchSimulation(sims).run(progress)
    results = [outcome.result for outcome in outcomes]
    if output_dir is not None:
        from .runpath import Flight, land

        for b, (sim, outcome) in enumerate(zip(sims, outcomes, strict=True)):
            run_dir = Path(output_dir) / str(b)
            failed = land(sim, Flight(outcome.result, started_at, cause=outcome.failure), run_dir)
            if failed is not None:
                from .sweeps.records import record_failure

                record_failure(run_dir, failed, sim.scenario.data)
    return results


def unbatched_output(output: Any) -> str | None:
    """The first output option of ``output`` (a scenario's ``output`` section) that a batch of
    worlds does not write (``output.plots=true``, ``output.live=window``...), None when there is
    none: :func:`run_batch` refuses such a composition, ``hydra/launcher=batch`` runs its jobs one
    by one."""
    asked = _files_asked(output) + ([f"output.live={output.live}"] if output.live != "off" else [])
    return asked[0] if asked else None


def _files_asked(output: Any) -> list[str]:
    """The output options that write files beside the run's own (``output.plots=true``...)."""
    return [f"output.{key}=true" for key in ("plots", "animation", "rerun", "mcap") if getattr(output, key)]


def extra_writers(sim: Simulation) -> list[Callable[..., Any]]:
    """The optional outputs asked for (plots, animation, Rerun replay, ROS 2 bag), as writer functions; a
    missing optional package is a one-line ConfigError now, not after the run. A live view
    (``output.live``) is attached to ``sim`` here, before its run (swarmscene.live)."""
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


# -- sweeps ---------------------------------------------------------------------------------------
LAUNCHERS = {"basic": None, "pool": "hydra/launcher=pool", "joblib": "hydra/launcher=joblib",
             "ray": "hydra/launcher=ray", "submitit_slurm": "hydra/launcher=submitit_slurm"}
"""``api.sweep``'s launcher names and the Hydra override that chooses each (basic: one process)."""


class SweepResult:
    """What :func:`sweep` returns: the sweep directory and its table.

    Attributes:
        sweep_dir: the sweep directory (one run directory per job, summary.csv/.md, sweep.json).
        rows: one dict per job (the summary.csv row: job, status, error, reason, seed, overrides,
            config_hash and every metric).
        exit_status: the command's status (0; 1 when a job failed and failures were not allowed).
    """

    def __init__(self, sweep_dir: Path, rows: list[dict[str, Any]], exit_status: int) -> None:
        self.sweep_dir, self.rows, self.exit_status = sweep_dir, rows, exit_status

    @property
    def failed(self) -> list[dict[str, Any]]:
        """The rows of the jobs that did not complete."""
        return [row for row in self.rows if row.get("status") != "complete"]

    def table(self) -> Any:
        """The tidy table: a pandas DataFrame when pandas is installed, else a pyarrow Table when
        pyarrow is, else the rows."""
        import importlib.util

        if importlib.util.find_spec("pandas") is not None:
            import pandas

            return pandas.DataFrame(self.rows)
        if importlib.util.find_spec("pyarrow") is not None:
            import pyarrow

            return pyarrow.Table.from_pylist(self.rows)
        return self.rows


def sweep(
    grid: dict[str, Sequence[Any] | str],
    overrides: Sequence[str] = (),
    launcher: str = "basic",
    sweep_dir: str | Path | None = None,
    allow_failed: bool = True,
) -> SweepResult:
    """Run a sweep exactly as the command line does (``swarmscene -m ...``) and return its table.

    Args:
        grid: swept keys and their values, e.g. ``{"avoidance": ["cem", "orca"], "seed": range(3)}``:
            one job per item, each item taken as a value (a string with a comma is one value, not
            two); a string instead of a sequence is Hydra's own sweep syntax (``"range(0,10)"``,
            ``"1,2,5"``).
        overrides: fixed overrides (``["scenario=cem_six_vehicle", "clock.duration=10"]``).
        launcher: ``basic`` (this machine, one job at a time), ``pool`` (all cores, workers that
            start warm: the fastest on one machine), ``joblib`` (all cores), ``ray``
            (a local Ray, or a cluster with ``hydra.launcher.ray.init.address=...`` in
            ``overrides``: docs/sweeps.md), ``submitit_slurm``.
        sweep_dir: where the jobs go (default ``multirun/api/<UTC time>`` under the working
            directory); any path, spaces and commas included. The same grid into the same
            directory resumes (complete jobs are skipped); another grid there is refused.
        allow_failed: return normally when jobs failed (they are in ``rows`` with their reason).

    Raises:
        ConfigError: the sweep was refused before any job ran (a bad value anywhere in the grid,
            a directory holding another grid), with the command line's one-line messages; or jobs
            failed and ``allow_failed`` is false.
    """
    import subprocess
    import sys
    from datetime import datetime

    from .sweeps.tables import collect_rows

    if launcher not in LAUNCHERS:
        raise ConfigError([f"launcher: must be one of {', '.join(LAUNCHERS)} (got {launcher!r})"])
    if sweep_dir is None:
        sweep_dir = Path("multirun", "api", datetime.now(UTC).strftime("%Y-%m-%d_%H-%M-%S-%f"))
    sweep_dir = Path(sweep_dir).resolve()
    swept = [f"{key}={_sweep_values(values)}" for key, values in grid.items()]
    command = [sys.executable, "-c", "from swarmscene.cli import main; main()", "--multirun",
               *overrides, *swept, f"hydra.sweep.dir={_quoted(str(sweep_dir))}",
               f"hydra.callbacks.swarmscene_summary.allow_failed={str(allow_failed).lower()}"]
    launcher_override = LAUNCHERS[launcher]  # None: Hydra's basic launcher
    if launcher_override:
        command.append(launcher_override)
    proc = subprocess.run(command, capture_output=True, text=True)
    lines = [line.removeprefix("swarmscene: ") for line in proc.stderr.splitlines() if line.startswith("swarmscene: ")]
    if proc.returncode == 2 or not (sweep_dir / "summary.csv").is_file():
        raise ConfigError(lines or [f"the sweep ended with status {proc.returncode}: {proc.stderr.strip()[-500:]}"])
    result = SweepResult(sweep_dir, collect_rows(sweep_dir), proc.returncode)
    if result.failed and not allow_failed:
        raise ConfigError([lines[-1] if lines else f"{len(result.failed)} jobs failed"])
    return result


def _sweep_values(values: Sequence[Any] | str) -> str:
    """Hydra's sweep syntax for ``values``: a string as given (Hydra's own syntax, ``range(0,10)``);
    a sequence one job per item, each item a value (:func:`_override_value`: a comma inside an
    item does not split it)."""
    if isinstance(values, str):
        return values
    items = [_override_value(v) for v in values]
    if len(items) == 1:  # one value: a plain override (a sweep of one job)
        return items[0]
    return ",".join(items)


_BARE = re.compile(r"[A-Za-z0-9_.+\-/@]+")
"""Characters a bare value of Hydra's override grammar may hold as they are."""


def _override_value(value: Any) -> str:
    """One value in Hydra's override grammar: null, true/false, a number as Python prints it, a
    string bare when it holds only plain characters, else quoted (so ``"a,b"`` is one value)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return repr(value) if isinstance(value, float) else str(value)
    text = str(value)
    return text if _BARE.fullmatch(text) else _quoted(text)


def _quoted(text: str) -> str:
    """``text`` as a quoted string of Hydra's override grammar: a quote escaped, backslashes before
    a quote (or the closing quote) doubled, an interpolation ``${`` escaped (taken as text)."""
    text = text.replace("${", "\\${")
    text = re.sub(r"(\\*)('|$)", lambda m: m.group(1) * 2 + ("\\'" if m.group(2) else ""), text)
    return "'" + text + "'"
