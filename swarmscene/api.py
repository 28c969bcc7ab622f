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
from typing import Any

from .composition.compose import CONFIG_MODULE, CONFIG_NAME, compose  # noqa: F401 (the public API's names)
from .core.config import Scenario
from .core.errors import ConfigError
from .core.registry import Registry
from .core.result import RunResult
from .core.simulation import Simulation
from .runpath import utc_now, write_outputs  # noqa: F401 (write_outputs: part of the api, used by tests and tools)
from .runs import build as assembly
from .runs.build import build_error_line, plugins  # noqa: F401 (the public API's names)
from .views.writers import extra_writers, files_asked, unbatched_output  # noqa: F401 (unbatched_output: public)


def load(config: Sequence[str] | dict[str, Any] = (), registry: Registry | None = None) -> Scenario:
    """Compose (if given overrides) and validate; raises ConfigError with one line per problem.

    A dict is taken as composed data: a run directory's ``config.yaml`` (the effective
    configuration) loads back to the same scenario.
    """
    return assembly.load(config if isinstance(config, dict) else compose(config), registry)


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
    if not isinstance(config, (dict, Scenario)):
        config = compose(config)
    return assembly.build(config, plugin_set)


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
    from .views.summary import Progress, summary_text

    sim = build(config)
    output = sim.config.output
    if output_dir is None:
        asked = files_asked(output)
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


# -- sweeps ---------------------------------------------------------------------------------------
LAUNCHERS = {"basic": None, "pool": "hydra/launcher=pool", "batch": "hydra/launcher=batch",
             "joblib": "hydra/launcher=joblib",
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
            start warm: the fastest on one machine), ``batch`` (the pool's workers, a grid's jobs
            that differ only in their seed flown as batches of worlds), ``joblib`` (all cores), ``ray``
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
