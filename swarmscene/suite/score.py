"""Score a sweep's runs against their tasks: the raw score, its normalised value and the pass rule.

A run is scored when its directory is complete and its ``config.yaml`` declares a ``task`` of a
frozen version whose definition it still holds: every value the task's composition sets is the
value the run used (so ``clock.duration=5`` on the command line, or an edited task file, gives no
score), its horizon is the task's and its seed one of the task's seeds. Every other option the run
used, the plugins' defaults included, must also be what the task gives in this engine
(:func:`effective_definition`), so ``formation.match=1.0`` or ``observers.swarmlab.every=1000``
on the command line gives no score either; only the method (``avoidance``), the seed and
``output`` (what is written, not what is flown; ``output.objective`` is in the definition) may
differ. A job whose method raised (status ``failed``) scores the worst value, 0 normalised, on its
task, as ``suite_v1.yaml`` promises ("a method that cannot fly a task scores 0 there"): its task,
method and seed are composed from its overrides. Any other run is listed with the reason it was
not scored, never silently dropped; a job folder that is a symbolic link is not read. Both are
compared in the canonical form of :mod:`.definition`: a run that recorded an event's kind as
``name`` or as ``kind`` (until 0.6.0) holds the same definition.

Score of a run (:class:`~swarmscene.core.task.ScoreConfig`): ``raw`` is ``metrics[score.metric]``
(a metric the run left undefined, e.g. ``hex.formed_at`` of a lattice never formed, is the worst
value); ``normalised = clip((raw - worst) / (best - worst), 0, 1)``, 0 when ``zero_unless_success``
and the run is not a success; ``passed`` when raw meets ``pass_threshold`` in the better direction
(and the run is a success where that is required).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path
from typing import Any

from ..core.errors import ConfigError
from ..core.spelling import current_names
from ..runs.rundir import RunDir, RunFileError, finite_or_none
from ..sweeps.records import job_dirs
from .definition import METHOD_FREE, SUITE, VERSIONS, canonical, frozen

FREE_SECTIONS = (*METHOD_FREE, "output")
"""What a scored run may set otherwise than its task: the method, the seed, and what is written
(``output.objective``, part of every definition, is checked there)."""


@dataclass(frozen=True)
class RunScore:
    """One run's score on its task (the row of ``scores.csv``)."""

    suite: str
    version: str
    task: str
    family: str
    method: str
    seed: int
    raw: float
    normalised: float
    passed: bool
    success: bool
    run: str

    def row(self) -> dict[str, Any]:
        """As a flat dict (CSV and JSON)."""
        return asdict(self)


@dataclass(frozen=True)
class Unscored:
    """A run that was not scored, and why (one line)."""

    run: str
    reason: str


def normalised_score(raw: float | None, score: dict[str, Any], success: bool) -> tuple[float, float, bool]:
    """(raw, normalised, passed) of one run from the task's ``score`` section; ``raw`` None (the
    metric undefined) counts as the worst value."""
    worst, best = float(score["worst"]), float(score["best"])
    value = worst if raw is None else float(raw)
    fraction = (value - worst) / (best - worst)
    normalised = min(1.0, max(0.0, fraction))
    if score.get("zero_unless_success", True) and not success:
        normalised = 0.0
    threshold = float(score["pass_threshold"])
    meets = value >= threshold if score["higher_is_better"] else value <= threshold
    passed = bool(meets and (success or not score.get("zero_unless_success", True)))
    return value, normalised, passed


def holds_definition(config: dict[str, Any], defined: dict[str, Any]) -> str | None:
    """None when the run's effective ``config`` holds every value of the task's definition, else
    the first dotted key that differs (keys the definition does not set are not compared)."""
    return first_difference(defined, config, subset=True)


_MISSING = object()


def first_difference(want: Any, have: Any, key: str = "", subset: bool = False) -> str | None:
    """The first dotted key where ``have`` differs from ``want``, or None: a value changed, a key
    either lacks (with ``subset``, only keys ``want`` holds are compared), a list of another length.
    Numbers agree by value (1 and 1.0), a flag only with a flag (``True == 1`` in Python)."""
    if isinstance(want, dict):
        if not isinstance(have, dict):
            return key or "(the whole configuration)"
        for k in want if subset else sorted(set(want) | set(have), key=str):
            found = first_difference(want.get(k, _MISSING), have.get(k, _MISSING), f"{key}.{k}" if key else str(k),
                                     subset)
            if found is not None:
                return found
        return None
    if isinstance(want, list):
        if not isinstance(have, list) or len(have) != len(want):
            return key
        for i, (w, h) in enumerate(zip(want, have, strict=True)):
            found = first_difference(w, h, f"{key}.{i}", subset)
            if found is not None:
                return found
        return None
    same = want == have and isinstance(want, bool) == isinstance(have, bool)
    return None if same else key or "(the whole configuration)"


@cache
def _effective_text(version: str, task_id: str) -> str:
    """JSON of :func:`effective_definition` (cached: a sweep scores each task's runs against it)."""
    from ..runs.build import load

    data = {**current_names(frozen(version)["tasks"][task_id]["definition"]), "avoidance": {"name": "none"}, "seed": 0}
    with warnings.catch_warnings():  # what validation warns about here is the task's, not the run's
        warnings.simplefilter("ignore")
        effective = canonical(load(data).data)
    return json.dumps({k: v for k, v in effective.items() if k not in FREE_SECTIONS})


def effective_definition(version: str, task_id: str) -> dict[str, Any]:
    """Every option a run of the task uses in this engine, the plugins' defaults included, in the
    canonical form, without :data:`FREE_SECTIONS`: the task's frozen definition validated as a run
    of it is (with the ``none`` method)."""
    return json.loads(_effective_text(version, task_id))


def score_run(run_dir: Path) -> RunScore | Unscored:
    """Score one run directory against its task's frozen definition (see the module docstring)."""
    if Path(run_dir).is_symlink():  # planted where a job's folder goes: never read
        return Unscored(str(run_dir), "a symbolic link (not read: a job's folder is a directory of the sweep)")
    try:
        run = RunDir(run_dir)
        manifest = run.manifest()
        if manifest.get("status") == "failed":
            return _score_failed(run, Path(run_dir))
        config = run.config()
        metrics = run.metrics()
    except RunFileError as exc:
        return Unscored(str(run_dir), str(exc))
    if not manifest.get("complete"):
        return Unscored(str(run_dir), "the run did not complete")
    task = _task_held(config, Path(run_dir))
    if isinstance(task, Unscored):
        return task
    try:
        effective = effective_definition(task["version"], task["id"])
    except ConfigError as exc:
        return Unscored(str(run_dir), f"task {task['id']!r} of {task['version']} does not build in this engine ({exc})")
    differs = first_difference(effective, {k: v for k, v in canonical(config).items() if k not in FREE_SECTIONS})
    if differs is not None:
        return Unscored(str(run_dir), f"{differs}: differs from what task {task['id']!r} of {task['version']} "
                                      "uses in this engine (its defaults included)")
    score = task["score"]
    success = bool(metrics.get("success"))
    raw, normalised, passed = normalised_score(finite_or_none(metrics.get(score["metric"])), score, success)
    return _scored(config, task, raw, normalised, passed, success, Path(run_dir))


def _task_held(config: dict[str, Any], run_dir: Path) -> dict[str, Any] | Unscored:
    """The run's ``task`` section when it is a task of a frozen version whose definition the run
    holds, with one of its seeds; else why not."""
    task = config.get("task")
    if not isinstance(task, dict):
        return Unscored(str(run_dir), "no task section (not a suite run)")
    version, task_id = task.get("version"), task.get("id")
    if task.get("suite") != SUITE or version not in VERSIONS or task_id not in frozen(version)["tasks"]:
        return Unscored(str(run_dir), f"task {task.get('suite')} {version} {task_id!r} is not part of a frozen version")
    differs = holds_definition(canonical(config), frozen(version)["tasks"][task_id]["definition"])
    if differs is not None:
        return Unscored(str(run_dir), f"{differs}: differs from task {task_id!r} of {version}")
    seed = config.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed not in task["seeds"]:
        return Unscored(str(run_dir), f"seed {seed} is not one of task {task_id!r}'s seeds")
    return task


def _scored(config: dict[str, Any], task: dict[str, Any], raw: float, normalised: float, passed: bool,
            success: bool, run_dir: Path) -> RunScore:
    method = (config.get("avoidance") or {}).get("name", "?")
    return RunScore(SUITE, str(task["version"]), str(task["id"]), task["family"], method, int(config["seed"]), raw,
                    normalised, passed, success, run_dir.name)


def _score_failed(run: RunDir, run_dir: Path) -> RunScore | Unscored:
    """A job whose method raised: the worst score on its task (composed from the job's overrides,
    since such a job wrote no ``config.yaml``), or why it cannot be placed."""
    from ..composition.compose import compose

    try:
        config = compose(run.overrides())
    except (RunFileError, ConfigError) as exc:
        return Unscored(str(run_dir), f"the job failed, and its task cannot be told from its overrides ({exc})")
    task = _task_held(config, run_dir)
    if isinstance(task, Unscored):
        return Unscored(str(run_dir), f"the job failed; {task.reason}")
    raw, normalised, passed = normalised_score(None, task["score"], False)
    return _scored(config, task, raw, normalised, passed, False, run_dir)


def score_sweep(sweep_dir: Path) -> tuple[list[RunScore], list[Unscored]]:
    """Every job of a sweep directory scored, and the runs that could not be (with why)."""
    scored: list[RunScore] = []
    unscored: list[Unscored] = []
    for run_dir in job_dirs(Path(sweep_dir)):
        outcome = score_run(run_dir)
        (scored if isinstance(outcome, RunScore) else unscored).append(outcome)  # type: ignore[arg-type]
    return scored, unscored
