"""Falsification: search a scenario's disturbance space for the failure that breaks the swarm.

The falsification tools for cyber-physical systems (S-TaLiRo, Breach, VerifAI) turn "find a
counter-example" into an optimisation: the property's *robustness* rho (a real number, positive
when the property holds with margin, negative when it is violated, its magnitude how far) is
minimised over the disturbances, and the first run with rho < 0 is a counter-example. For the
swarm's separation property, always ||p_i(t) - p_j(t)|| >= d_sep, the robustness of a run is

    rho = min_t min_{i<j} ||p_i(t) - p_j(t)|| - d_sep = min_separation - safety.separation_limit

(the spatial robustness of the signal temporal logic formula G (sep >= d_sep), Fainekos and
Pappas 2009; S-TaLiRo minimises it). Minimising ``min_separation`` is minimising rho, so
a violating run ranks below every safe one, the deepest violation first.

``+sweep=falsify`` (scenarios/sweep/falsify.yaml) runs this with Hydra's Optuna sweeper (TPE),
``+sweep=falsify_random`` the same budget with Optuna's RandomSampler. Two pieces live here:

- :func:`failure_search_space`, the sweeper's ``custom_search_space``: it adds the parts of the
  search space that depend on the composed scenario (the failure time, 0 ... ``clock.duration``,
  and the failing agent, 0 ... ``swarm.n`` - 1); the rest (wind, packet loss) is named in the
  preset's ``hydra.sweeper.params`` by its config key;
- :class:`WorstCase`, a Hydra callback that at the end of the study ranks the trials by rho and
  writes the worst one as a runnable scenario file (``worst_case.yaml``: the trial's effective
  configuration, every default resolved, so it reproduces the run exactly) and its record
  (``worst_case.json``).
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

try:
    from hydra.experimental.callback import Callback as _Callback
except ImportError:  # pragma: no cover - hydra-core is a dependency
    _Callback = object  # type: ignore[misc,assignment]  # a plain base when hydra is absent

FAILURE_TIME = "events.0.at"
"""Override key of the searched failure's time, s."""
FAILURE_AGENT = "events.0.agents.0"
"""Override key of the searched failure's agent index."""
WORST_CASE_FILE = "worst_case.yaml"
WORST_CASE_RECORD = "worst_case.json"


# -- the search space ---------------------------------------------------------------------------
def failure_search_space(config: Any, trial: Any) -> None:
    """The scenario-dependent part of the falsifier's search space (``custom_search_space``).

    Called by Hydra's Optuna sweeper for every trial, after the ``hydra.sweeper.params``
    distributions were drawn. Adds the failure time ``events.0.at`` ~ U[0, ``clock.duration``] s
    and the failing agent ``events.0.agents.0`` among 0 ... ``swarm.n`` - 1 (categorical: agent
    indices have no order that a sampler could exploit), each unless the params or the command
    line already name it.

    Args:
        config: the study's composed config (the chosen scenario, hydra node included).
        trial: the Optuna trial being configured; its params become the job's overrides.

    Raises:
        ConfigError: one line when the config holds no event with a list of agents to search.
    """
    # The command line spells a plain value `++key=...` (swarmscene.composition.searchpath.plain_overrides).
    taken = {name.lstrip("+~") for name in (*trial.params, *trial.user_attrs)}
    duration, n = failure_bounds(config)
    if FAILURE_TIME not in taken:
        trial.suggest_float(FAILURE_TIME, 0.0, duration)
    if FAILURE_AGENT not in taken:
        trial.suggest_categorical(FAILURE_AGENT, list(range(n)))


def failure_bounds(config: Any) -> tuple[float, int]:
    """(``clock.duration``, ``swarm.n``) of the composed config, checked to hold a searchable event."""
    from ..core.errors import ConfigError

    events = config.get("events") or []
    agents = events[0].get("agents") if len(events) else None
    if agents is None or isinstance(agents, (str, int, float)) or hasattr(agents, "keys") or not len(agents):
        shown = list(events) if len(events) else "[]"
        raise ConfigError([
            f"events: the falsifier searches the first event's time and agent, so it needs one with a "
            f"list of agents, e.g. {{at: 2.0, agents: [0], name: hover}} (got {shown})"
        ])
    return float(config.clock.duration), int(config.swarm.n)


# -- the verdict --------------------------------------------------------------------------------
def robustness(min_separation: float | None, separation_limit: float) -> float:
    """rho = min_separation - d_sep, m: negative when the run violated separation (NaN: no value)."""
    if min_separation is None:
        return math.nan
    return float(min_separation) - float(separation_limit)


@dataclass
class Trial:
    """One trial of the study, read back from its run directory."""

    trial: int
    """job number in the sweep directory (= Optuna's trial number)"""
    overrides: list[str]
    """the trial's overrides: the searched values, and the command line's"""
    status: str
    """``complete``, or why not (``failed``: the run blew up, error.json says how)"""
    min_separation: float | None = None
    """m, the run's smallest distance between two agents"""
    separation_limit: float | None = None
    """m, ``safety.separation_limit``"""
    robustness: float = math.nan
    """m, rho = min_separation - separation_limit"""
    first_violation: float | None = None
    """s, ``violations.separation.first_time`` (null: separation held)"""
    violation_agents: list[int] = field(default_factory=list)
    """the agents involved at that time"""

    @property
    def rank_key(self) -> tuple[float, float]:
        """Worst first: the smallest rho, then the earliest violation; trials without a value last."""
        rho = math.inf if math.isnan(self.robustness) else self.robustness
        return (rho, math.inf if self.first_violation is None else self.first_violation)


def read_trial(run_dir: Path) -> Trial:
    """The trial of one run directory (its overrides, metrics and limit), read through
    :mod:`swarmscene.runs.rundir`: a trial whose files are missing or damaged is not complete
    (``status`` ``damaged``), never a crash of the study's end."""
    from ..runs.rundir import CONFIG, MANIFEST, METRICS, OVERRIDES, RunDir, RunFileError, finite_or_none

    run_dir = Path(run_dir)
    trial = Trial(trial=int(run_dir.name), overrides=[], status="unfinished")
    try:
        run = RunDir(run_dir)
        trial.overrides = run.overrides() if run.has(OVERRIDES) else []
        manifest = run.manifest() if run.has(MANIFEST) else {}
        status = manifest.get("status") or ("complete" if manifest.get("complete") is True else "unfinished")
        trial.status = str(status)
        if status != "complete" or not run.has(METRICS):
            return trial
        metrics, config = run.metrics(), run.config() if run.has(CONFIG) else {}
    except RunFileError:
        trial.status = "damaged"
        return trial
    limit = finite_or_none((config.get("safety") or {}).get("separation_limit")
                           if isinstance(config.get("safety"), dict) else None)
    if limit is None:
        trial.status = "damaged"  # a complete run always records its limit
        return trial
    trial.min_separation = finite_or_none(metrics.get("min_separation"))
    trial.separation_limit = limit
    trial.robustness = robustness(trial.min_separation, trial.separation_limit)
    trial.first_violation = finite_or_none(metrics.get("violations.separation.first_time"))
    agents = metrics.get("violations.separation.agents")
    trial.violation_agents = [int(a) for a in agents if isinstance(a, int)] if isinstance(agents, list) else []
    return trial


def read_trials(sweep_dir: Path) -> list[Trial]:
    """Every trial of a study's sweep directory, in trial order."""
    from ..sweeps.records import job_dirs

    return [read_trial(d) for d in job_dirs(Path(sweep_dir)) if d.name.isdigit()]


def worst(trials: list[Trial]) -> Trial | None:
    """The worst complete trial (smallest rho, then earliest violation; the first of equals)."""
    done = [t for t in trials if not math.isnan(t.robustness)]
    return min(done, key=lambda t: (t.rank_key, t.trial)) if done else None


def running_worst(trials: list[Trial]) -> list[float | None]:
    """The smallest min_separation found after each trial (the study's progress curve), m."""
    out: list[float | None] = []
    best: float | None = None
    for t in sorted(trials, key=lambda t: t.trial):
        if t.min_separation is not None and (best is None or t.min_separation < best):
            best = float(t.min_separation)
        out.append(best)
    return out


# -- the study's options --------------------------------------------------------------------------
def study_problem(sweeper: Any) -> str | None:
    """One line naming the first sweeper option the falsifier cannot run with, else None:
    ``hydra.sweeper.n_trials`` (the budget) must be an integer >= 1, and each searched
    ``interval(low, high)`` / ``range(start, stop)`` of ``hydra.sweeper.params`` must have low < high
    (``tag(log, ...)``: low > 0)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import IntervalSweep, RangeSweep

    budget = sweeper.get("n_trials")
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
        return f"hydra.sweeper.n_trials: the falsifier's budget must be an integer >= 1 (got {budget!r})"
    parser = OverridesParser.create()
    for key, text in (sweeper.get("params") or {}).items():
        name = str(key).lstrip("+~")
        try:
            value = parser.parse_override(f"{name}={text}").value()
        except Exception as exc:  # Hydra's grammar: say which parameter does not parse
            return f"hydra.sweeper.params.{name}: cannot parse {text!r} ({' '.join(str(exc).split())[:120]})"
        if isinstance(value, IntervalSweep):
            low, high = value.start, value.end
        elif isinstance(value, RangeSweep):
            low, high = value.start, value.stop
        else:
            continue
        if low is None or high is None or not (math.isfinite(low) and math.isfinite(high) and low < high):
            return f"hydra.sweeper.params.{name}: the interval must have low < high, both finite (got {text})"
        if "log" in value.tags and low <= 0:
            return f"hydra.sweeper.params.{name}: a log-scaled interval needs low > 0 (got {text})"
    return None


# -- the worst case as a scenario file ------------------------------------------------------------
def write_worst_case(sweep_dir: Path, sampler: str = "", command: str = "swarmscene") -> dict[str, Any] | None:
    """Write ``worst_case.yaml`` and ``worst_case.json`` in ``sweep_dir``; return the record.

    ``worst_case.yaml`` is the worst trial's ``config.yaml`` (its effective configuration: the
    searched values in place, every default resolved) under a comment saying how to run it;
    ``worst_case.json`` records the trial, its searched values, rho, the first violation, the
    number of trials and the progress curve. None (nothing written) when no trial completed.
    """
    from ..runs.outputs import atomic_write_bytes
    from ..runs.rundir import CONFIG, read_text

    sweep_dir = Path(sweep_dir)
    trials = read_trials(sweep_dir)
    found = worst(trials)
    if found is None:
        return None
    run = sweep_dir / str(found.trial)
    reproduce = f"{command} --config-path {sweep_dir} --config-name {Path(WORST_CASE_FILE).stem}"
    record = {
        "trial": found.trial,
        "run_dir": str(run),
        "sampler": sampler,
        "trials": len(trials),
        "complete": sum(t.status == "complete" for t in trials),
        "failed": [t.trial for t in trials if t.status == "failed"],
        "violated": found.robustness < 0,
        "violating_trials": sum(t.robustness < 0 for t in trials),
        "first_violating_trial": next(
            (t.trial for t in sorted(trials, key=lambda t: t.trial) if t.robustness < 0), None),
        **{k: v for k, v in asdict(found).items() if k not in ("trial",)},
        "running_worst": running_worst(trials),
        "reproduce": reproduce,
    }
    verdict = (
        f"separation violated at t = {found.first_violation:.2f} s by agents {found.violation_agents}"
        if found.first_violation is not None else "separation held"
    )
    header = [
        f"# The worst case of the falsification study in {sweep_dir} ({sampler or 'Optuna'}, {len(trials)} trials):",
        f"# trial {found.trial}: {' '.join(found.overrides)}",
        f"# min separation {found.min_separation:.6g} m (limit {found.separation_limit:g} m, "
        f"robustness {found.robustness:+.6g} m); {verdict}.",
        "# The trial's effective configuration (every default resolved). Run it again:",
        f"#   {reproduce}",
    ]
    body = read_text(run / CONFIG).splitlines(keepends=True)  # checked: size, a plain file, UTF-8
    while body and body[0].startswith("#"):  # the run's own header names its own directory
        body.pop(0)
    # atomic, through a private temporary file: a link planted at either name is replaced
    atomic_write_bytes(sweep_dir / WORST_CASE_FILE, ("\n".join(header) + "\n" + "".join(body)).encode())
    atomic_write_bytes(sweep_dir / WORST_CASE_RECORD, (json.dumps(record, indent=2) + "\n").encode())
    return record


class WorstCase(_Callback):
    """Hydra callback of ``+sweep=falsify`` (``hydra.callbacks.swarmscene_falsify``).

    At the end of the study it writes the worst case (:func:`write_worst_case`) and prints one
    line: the trial, its min separation against the limit, the first violation, and the command
    that runs it again.
    """

    def on_multirun_start(self, config: Any, **kwargs: Any) -> None:
        """Refuse a budget or a search interval Optuna would reject, naming the option, before
        the first trial (Hydra turns a callback's exception into a warning, so the refusal is
        the command line's: one line and exit status 2)."""
        problem = study_problem(config.hydra.sweeper)
        if problem is not None:
            print(f"swarmscene: {problem}", file=sys.stderr)
            raise SystemExit(2)
        from ..sweeps import callback

        callback.started(self, config)  # its end runs even when every trial failed

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        """After the search: write the worst trial (``worst_case.yaml``, ``.json``) and print its verdict."""
        sweep_dir = Path(config.hydra.sweep.dir)
        sampler = str(config.hydra.sweeper.sampler.get("_target_", "")).rpartition(".")[2]
        record = write_worst_case(sweep_dir, sampler)
        if record is None:
            failed = sum(t.status != "complete" for t in read_trials(sweep_dir))
            print(f"swarmscene: falsify: no trial completed in {sweep_dir} ({failed} failed: their error.json "
                  "says why); no worst case to write", file=sys.stderr)
            return
        when = (f"separation first violated at t = {record['first_violation']:.2f} s by agents "
                f"{record['violation_agents']}" if record["violated"] else "separation held in every trial")
        print(
            f"swarmscene: falsify: worst of {record['trials']} trials is trial {record['trial']} "
            f"({' '.join(record['overrides'])}): min separation {record['min_separation']:.4g} m, limit "
            f"{record['separation_limit']:g} m, robustness {record['robustness']:+.4g} m; {when}. "
            f"Run it: {record['reproduce']}",
            file=sys.stderr,
        )
