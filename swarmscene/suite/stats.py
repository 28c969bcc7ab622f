"""The statistics the field reports, as rliable computes them (Agarwal et al., "Deep Reinforcement
Learning at the Edge of the Statistical Precipice", NeurIPS 2021): the ``suite`` extra.

For each method a score matrix of shape (runs, tasks): the normalised scores in [0, 1], one row per
seed (the tasks' common seed list, in order), one column per task (sorted ids). From it:

* **aggregates across tasks**: the interquartile mean (IQM: the mean of the middle 50 % of all runs'
  scores) and the mean, each with a 95 % stratified bootstrap interval (runs resampled within each
  task; ``AGGREGATE_REPS`` replications, rliable's default);
* **per task**: the IQM and mean of the raw score over seeds, with a 95 % bootstrap interval;
* **probability of improvement** P(X > Y) for every ordered pair of methods (the Mann-Whitney
  statistic averaged over tasks), with its stratified independent bootstrap interval;
* **performance profiles**: the fraction of runs whose normalised score exceeds tau, for tau in
  :data:`TAUS`, with bootstrap intervals.

The point estimates are rliable's functions (``aggregate_iqm``, ``aggregate_mean``,
``probability_of_improvement``, ``score_distributions``). The intervals are rliable's bootstraps
(stratified: runs resampled within each task; independent for a pair; percentile intervals),
drawn vectorised here: rliable's own loop (arch, one call per replication, scipy's Mann-Whitney per
task) took ~50 min for the probability of improvement of four methods on a loaded 2-core machine.
Every bootstrap draws from ``numpy.random.RandomState(SEED)`` afresh for each method (or pair), so
a method's numbers do not depend on which other methods are in the table.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

SEED = 0
"""The bootstrap's seed."""
AGGREGATE_REPS = 50_000
"""Bootstrap replications of the aggregate intervals (rliable's default)."""
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
    if not methods:
        raise ValueError("no scored run to compare")
    cells = {(r["method"], r["task"], r["seed"]): float(r[key]) for r in rows}
    seeds = sorted(set.intersection(*({r["seed"] for r in rows if r["method"] == m} for m in methods)))
    tasks = sorted({r["task"] for r in rows})
    tasks = [t for t in tasks if all((m, t, s) in cells for m in methods for s in seeds)]
    if not seeds or not tasks:  # nothing in common: an aggregate over it would be NaN
        raise ValueError(f"no task that every method ({', '.join(methods)}) ran on the same seeds: "
                         "nothing to compare (score the methods' sweeps apart, or run the missing tasks)")
    matrices = {m: np.array([[cells[(m, t, s)] for t in tasks] for s in seeds], dtype=float) for m in methods}
    return matrices, tasks, seeds


def _trimmed(x: np.ndarray) -> np.ndarray:
    """The interquartile mean along the last axis: scipy's ``trim_mean(x, 0.25)``, which rliable's
    ``aggregate_iqm`` is (the lowest and highest ``int(0.25 n)`` values cut)."""
    n = x.shape[-1]
    cut = int(0.25 * n)
    return np.sort(x, axis=-1)[..., cut : n - cut].mean(axis=-1)


def _resampled(scores: np.ndarray, reps: int) -> np.ndarray:
    """(reps, runs, tasks): the runs of each task drawn with replacement, independently per task
    (rliable's stratified bootstrap), from a generator seeded with :data:`SEED`."""
    rng = np.random.RandomState(SEED)
    runs, tasks = scores.shape
    idx = rng.randint(0, runs, size=(reps, runs, tasks))
    return np.take_along_axis(np.broadcast_to(scores, (reps, runs, tasks)), idx, axis=1)


def _percentiles(samples: np.ndarray) -> list[list[float]] | list[float]:
    """The 95 % percentile interval of bootstrap samples (axis 0): [low, high] (per column)."""
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)
    return [np.asarray(low).tolist(), np.asarray(high).tolist()] if np.ndim(low) else [float(low), float(high)]


def _iqm_and_mean(scores: np.ndarray, reps: int) -> dict[str, Any]:
    """IQM and mean of a (runs, tasks) matrix with their stratified bootstrap intervals."""
    from rliable import metrics

    boot = _resampled(scores, reps).reshape(reps, -1)
    return {"iqm": float(metrics.aggregate_iqm(scores)), "iqm_ci": _percentiles(_trimmed(boot)),
            "mean": float(metrics.aggregate_mean(scores)), "mean_ci": _percentiles(boot.mean(axis=1))}


def aggregates(matrices: dict[str, np.ndarray], reps: int = AGGREGATE_REPS) -> dict[str, dict[str, Any]]:
    """{method: {"iqm": x, "iqm_ci": [lo, hi], "mean": x, "mean_ci": [lo, hi]}} across tasks."""
    return {method: _iqm_and_mean(scores, reps) for method, scores in matrices.items()}


def per_task(raw: dict[str, np.ndarray], tasks: list[str], reps: int = REPS) -> dict[str, dict[str, dict[str, Any]]]:
    """{task: {method: {"iqm", "iqm_ci", "mean", "mean_ci"}}} of the raw score over seeds."""
    return {task: {method: _iqm_and_mean(scores[:, j : j + 1], reps) for method, scores in raw.items()}
            for j, task in enumerate(tasks)}


def _improvement_samples(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X > Y) of (..., runs, tasks) samples: per task the Mann-Whitney U / (n_x n_y) (pairs with
    x > y, ties counting a half), averaged over tasks."""
    greater = (x[..., :, None, :] > y[..., None, :, :]).mean(axis=(-3, -2))
    ties = (x[..., :, None, :] == y[..., None, :, :]).mean(axis=(-3, -2))
    return (greater + 0.5 * ties).mean(axis=-1)


def improvement(matrices: dict[str, np.ndarray], reps: int = REPS) -> dict[str, dict[str, Any]]:
    """{"X>Y": {"p": P(X > Y), "ci": [lo, hi]}} for every ordered pair of methods X != Y; the runs
    of X and Y resampled independently within each task (rliable's StratifiedIndependentBootstrap)."""
    from rliable import metrics

    out = {}
    for x in matrices:
        for y in matrices:
            if x == y:
                continue
            bx = _resampled(matrices[x], reps)
            rng = np.random.RandomState(SEED + 1)
            by = np.take_along_axis(np.broadcast_to(matrices[y], (reps, *matrices[y].shape)),
                                    rng.randint(0, matrices[y].shape[0], size=(reps, *matrices[y].shape)), axis=1)
            p = float(metrics.probability_of_improvement(matrices[x], matrices[y]))
            out[f"{x}>{y}"] = {"p": p, "ci": _percentiles(_improvement_samples(bx, by))}
    return out


def profiles(matrices: dict[str, np.ndarray], reps: int = REPS) -> dict[str, dict[str, Any]]:
    """{method: {"tau": [...], "fraction": [...], "ci_low": [...], "ci_high": [...]}}: the score
    distribution's performance profile (rliable's ``score_distributions``), stratified bootstrap bands."""
    from rliable import library as rly

    out = {}
    for method, scores in matrices.items():
        boot = _resampled(scores, reps).reshape(reps, -1)
        fractions = (boot[:, :, None] > TAUS[None, None, :]).mean(axis=1)
        low, high = _percentiles(fractions)
        out[method] = {"tau": TAUS.tolist(), "fraction": np.asarray(rly.score_distributions(scores, TAUS)).tolist(),
                       "ci_low": low, "ci_high": high}
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
