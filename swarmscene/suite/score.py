"""Score a sweep's runs against their tasks: the raw score, its normalised value and the pass rule.

A run is scored when its directory is complete and its ``config.yaml`` declares a ``task`` of a
frozen version whose definition it still holds: every value the task's composition sets is the
value the run used (so ``clock.duration=5`` on the command line, or an edited task file, gives no
score), its horizon is the task's and its seed one of the task's seeds. Any other run is listed
with the reason it was not scored, never silently dropped. Both are compared in the canonical form
of :mod:`.definition`: a run that recorded an event's kind as ``name`` or as ``kind`` (until 0.6.0)
holds the same definition.

Score of a run (:class:`~swarmscene.core.task.ScoreConfig`): ``raw`` is ``metrics[score.metric]``
(a metric the run left undefined, e.g. ``hex.formed_at`` of a lattice never formed, is the worst
value); ``normalised = clip((raw - worst) / (best - worst), 0, 1)``, 0 when ``zero_unless_success``
and the run is not a success; ``passed`` when raw meets ``pass_threshold`` in the better direction
(and the run is a success where that is required).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..runs.rundir import RunDir, RunFileError, finite_or_none
from ..sweeps.records import job_dirs
from .definition import SUITE, VERSIONS, canonical, frozen


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
    the first dotted key that differs."""

    def walk(want: Any, have: Any, key: str) -> str | None:
        if isinstance(want, dict):
            if not isinstance(have, dict):
                return key
            for k, v in want.items():
                found = walk(v, have.get(k, _MISSING), f"{key}.{k}" if key else str(k))
                if found is not None:
                    return found
            return None
        if isinstance(want, list):
            if not isinstance(have, list) or len(have) != len(want):
                return key
            for i, (w, h) in enumerate(zip(want, have, strict=True)):
                found = walk(w, h, f"{key}.{i}")
                if found is not None:
                    return found
            return None
        if isinstance(want, (int, float)) and not isinstance(want, bool) and isinstance(have, (int, float)):
            return None if math.isclose(float(want), float(have), rel_tol=0, abs_tol=0) else key
        return None if want == have else key

    return walk(defined, config, "")


_MISSING = object()


def score_run(run_dir: Path) -> RunScore | Unscored:
    """Score one run directory against its task's frozen definition (see the module docstring)."""
    try:
        run = RunDir(run_dir)
        manifest = run.manifest()
        config = run.config()
        metrics = run.metrics()
    except RunFileError as exc:
        return Unscored(str(run_dir), str(exc))
    if not manifest.get("complete") or manifest.get("status") == "failed":
        return Unscored(str(run_dir), "the run did not complete")
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
    if not isinstance(seed, int) or seed not in task["seeds"]:
        return Unscored(str(run_dir), f"seed {seed} is not one of task {task_id!r}'s seeds")
    score = task["score"]
    success = bool(metrics.get("success"))
    raw, normalised, passed = normalised_score(finite_or_none(metrics.get(score["metric"])), score, success)
    method = (config.get("avoidance") or {}).get("name", "?")
    return RunScore(SUITE, str(version), str(task_id), task["family"], method, seed, raw, normalised, passed,
                    success, Path(run_dir).name)


def score_sweep(sweep_dir: Path) -> tuple[list[RunScore], list[Unscored]]:
    """Every job of a sweep directory scored, and the runs that could not be (with why)."""
    scored: list[RunScore] = []
    unscored: list[Unscored] = []
    for run_dir in job_dirs(Path(sweep_dir)):
        outcome = score_run(run_dir)
        (scored if isinstance(outcome, RunScore) else unscored).append(outcome)  # type: ignore[arg-type]
    return scored, unscored
