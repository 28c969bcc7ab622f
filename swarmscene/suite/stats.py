"""The statistics the field reports, with rliable (Agarwal et al., "Deep Reinforcement Learning at
the Edge of the Statistical Precipice", NeurIPS 2021): the ``suite`` extra.

For each method a score matrix of shape (runs, tasks): the normalised scores in [0, 1], one row per
seed (the tasks' common seed list, in order), one column per task (sorted ids). From it:

* **aggregates across tasks**: the interquartile mean (IQM: the mean of the middle 50 % of all runs'
  scores) and the mean, each with a 95 % stratified bootstrap interval (runs resampled within each
  task; ``AGGREGATE_REPS`` replications);
* **per task**: the IQM and mean of the raw score over seeds, with a 95 % bootstrap interval;
* **probability of improvement** P(X > Y) for every ordered pair of methods (the Mann-Whitney
  statistic averaged over tasks), with its stratified independent bootstrap interval;
* **performance profiles**: the fraction of runs whose normalised score exceeds tau, for tau in
  :data:`TAUS`, with bootstrap intervals.

Every bootstrap draws from ``numpy.random.RandomState(SEED)`` afresh for each method (or pair), so
a method's numbers do not depend on which other methods are in the table.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

SEED = 0
"""The bootstrap's seed."""
AGGREGATE_REPS = 10_000
"""Bootstrap replications of the aggregate intervals (rliable's default is 50,000; 10,000 keeps the
four built-ins' table to a few seconds each on a loaded 2-core machine)."""
REPS = 2_000
"""Bootstrap replications of the per-task, improvement and profile intervals (rliable's profile default)."""
TAUS = np.linspace(0.0, 1.0, 21)
"""The thresholds of the performance profiles (normalised score)."""


def require_rliable() -> None:
    """A one-line error naming the extra when rliable is not installed."""
    import importlib.util

    if importlib.util.find_spec("rliable") is None:
        raise ImportError("the suite's statistics need the 'suite' extra: pip install 'swarmscene[suite]'")


def score_matrices(rows: Sequence[dict[str, Any]], key: str = "normalised"
                   ) -> tuple[dict[str, np.ndarray], list[str], list[int]]:
    """{method: (runs, tasks) array of ``key``}, the task ids (columns) and seeds (rows).

    Only the seeds every method ran, and of them the tasks every method ran on every such seed,
    enter (a missing cell would bias the aggregate): a new method scored on fewer seeds or tasks
    is compared with the reference on those.
    """
    methods = sorted({r["method"] for r in rows})
    cells = {(r["method"], r["task"], r["seed"]): float(r[key]) for r in rows}
    seeds = sorted(set.intersection(*({r["seed"] for r in rows if r["method"] == m} for m in methods)))
    tasks = sorted({r["task"] for r in rows})
    tasks = [t for t in tasks if all((m, t, s) in cells for m in methods for s in seeds)]
    matrices = {m: np.array([[cells[(m, t, s)] for t in tasks] for s in seeds], dtype=float) for m in methods}
    return matrices, tasks, seeds


def _interval(scores: Any, func: Any, reps: int) -> tuple[Any, Any]:
    """rliable's point estimate and interval of ``func`` for one score matrix (or a list of them)."""
    from absl import logging as absl_logging  # rliable logs one INFO line per estimate
    from rliable import library as rly

    absl_logging.set_verbosity(absl_logging.WARNING)
    with warnings.catch_warnings():  # arch deprecates random_state, which rliable 1.2 passes on
        warnings.simplefilter("ignore", FutureWarning)
        point, interval = rly.get_interval_estimates(
            {"x": scores}, func, reps=reps, random_state=np.random.RandomState(SEED))
    return point["x"], interval["x"]


def aggregates(matrices: dict[str, np.ndarray], reps: int = AGGREGATE_REPS) -> dict[str, dict[str, Any]]:
    """{method: {"iqm": x, "iqm_ci": [lo, hi], "mean": x, "mean_ci": [lo, hi]}} across tasks."""
    from rliable import metrics

    def func(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x)])

    out = {}
    for method, scores in matrices.items():
        point, ci = _interval(scores, func, reps)
        out[method] = {"iqm": float(point[0]), "iqm_ci": [float(ci[0, 0]), float(ci[1, 0])],
                       "mean": float(point[1]), "mean_ci": [float(ci[0, 1]), float(ci[1, 1])]}
    return out


def per_task(raw: dict[str, np.ndarray], tasks: list[str], reps: int = REPS) -> dict[str, dict[str, dict[str, Any]]]:
    """{task: {method: {"iqm", "iqm_ci", "mean", "mean_ci"}}} of the raw score over seeds."""
    from rliable import metrics

    def func(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x), metrics.aggregate_mean(x)])

    out: dict[str, dict[str, dict[str, Any]]] = {t: {} for t in tasks}
    for method, scores in raw.items():
        for j, task in enumerate(tasks):
            point, ci = _interval(scores[:, j : j + 1], func, reps)
            out[task][method] = {"iqm": float(point[0]), "iqm_ci": [float(ci[0, 0]), float(ci[1, 0])],
                                 "mean": float(point[1]), "mean_ci": [float(ci[0, 1]), float(ci[1, 1])]}
    return out


def improvement(matrices: dict[str, np.ndarray], reps: int = REPS) -> dict[str, dict[str, Any]]:
    """{"X>Y": {"p": P(X > Y), "ci": [lo, hi]}} for every ordered pair of methods X != Y."""
    from rliable import metrics

    out = {}
    for x in matrices:
        for y in matrices:
            if x == y:
                continue
            point, ci = _interval([matrices[x], matrices[y]], metrics.probability_of_improvement, reps)
            low, high = np.ravel(ci)
            out[f"{x}>{y}"] = {"p": float(point), "ci": [float(low), float(high)]}
    return out


def profiles(matrices: dict[str, np.ndarray], reps: int = REPS) -> dict[str, dict[str, Any]]:
    """{method: {"tau": [...], "fraction": [...], "ci_low": [...], "ci_high": [...]}}: the score
    distribution's performance profile (rliable's ``create_performance_profile``, seeded)."""
    from rliable import library as rly

    out = {}
    for method, scores in matrices.items():
        point, ci = _interval(scores, lambda s: rly.score_distributions(s, TAUS), reps)
        out[method] = {"tau": TAUS.tolist(), "fraction": np.asarray(point).tolist(),
                       "ci_low": np.asarray(ci[0]).tolist(), "ci_high": np.asarray(ci[1]).tolist()}
    return out


def summarize(rows: Sequence[dict[str, Any]], aggregate_reps: int = AGGREGATE_REPS, reps: int = REPS) -> dict[str, Any]:
    """Every statistic above from scored rows (:class:`~.score.RunScore` rows)."""
    require_rliable()
    normalised, tasks, seeds = score_matrices(rows, "normalised")
    raw, _, _ = score_matrices(rows, "raw")
    passed, _, _ = score_matrices(rows, "passed")
    return {
        "methods": sorted(normalised),
        "tasks": tasks,
        "seeds": seeds,
        "aggregate": aggregates(normalised, aggregate_reps),
        "pass_rate": {m: float(p.mean()) for m, p in passed.items()},
        "per_task": per_task(raw, tasks, reps),
        "per_task_pass_rate": {t: {m: float(p[:, j].mean()) for m, p in passed.items()} for j, t in enumerate(tasks)},
        "probability_of_improvement": improvement(normalised, reps),
        "performance_profile": profiles(normalised, reps),
        "bootstrap": {"seed": SEED, "aggregate_reps": aggregate_reps, "reps": reps, "confidence": 0.95},
    }
