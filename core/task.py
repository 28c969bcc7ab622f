"""A benchmark task's declaration: the ``task`` section a ``task/<name>.yaml`` file adds to its
scenario (docs/suite.md).

A task is a scenario plus its score: which metric of ``metrics.json`` scores a run, in what unit,
which way is better, the range that maps it onto [0, 1] for aggregates across tasks, the rule a
run passes by, the fixed horizon and the seeds it is scored on. The engine only validates the
section and records it in the run's effective configuration (so its hash covers the task's
definition); ``swarmscene.suite`` scores the runs and freezes each suite version's definitions.
"""

from __future__ import annotations

from typing import Literal, get_args

from pydantic import Field, model_validator

from .fields import MAX_DURATION, StrictModel

Family = Literal["formation", "navigation", "resilience", "dense", "flocking"]
FAMILIES: tuple[str, ...] = get_args(Family)
"""The task families (docs/suite.md): formation, navigation, resilience, dense interaction,
flocking and coverage."""


class ScoreConfig(StrictModel):
    """How a run of the task is scored, from its ``metrics.json``.

    The normalised score ``(x - worst) / (best - worst)``, clipped to [0, 1], is what aggregates
    across tasks (IQM, performance profiles); a run that is not a ``success`` (a collision, a
    clearance violation, a mission not completed) scores 0 there when ``zero_unless_success``.
    """

    metric: str = Field(min_length=1, description="the metrics.json key scored (e.g. duration, swarmlab.order)")
    unit: str = Field("", description="its unit (SI; empty: dimensionless)")
    higher_is_better: bool = Field(description="whether a larger value is better")
    description: str = Field(min_length=1, description="what the score measures, one line")
    worst: float = Field(description="the value normalised to 0 (values beyond it clip to 0)")
    best: float = Field(description="the value normalised to 1 (values beyond it clip to 1)")
    zero_unless_success: bool = Field(
        True, description="a run whose metrics.json says success: false scores 0 (normalised)")
    pass_threshold: float = Field(
        description="a run passes when its score is at least this (higher_is_better) or at most "
        "this (lower is better), and it is a success when zero_unless_success")

    @model_validator(mode="after")
    def _direction(self) -> ScoreConfig:
        if self.best == self.worst:
            raise ValueError(f"best: must differ from worst (got both {self.best})")
        if (self.best > self.worst) != self.higher_is_better:
            raise ValueError(f"best: must be {'above' if self.higher_is_better else 'below'} worst when "
                             f"higher_is_better is {str(self.higher_is_better).lower()} "
                             f"(got best {self.best}, worst {self.worst})")
        return self


class TaskConfig(StrictModel):
    """A benchmark task: the suite and version it belongs to, its family, score, horizon and seeds."""

    suite: str = Field(min_length=1, description="the suite (swarmscene-bench)")
    version: str = Field(min_length=1, description="the suite's version whose frozen definition this is (v1)")
    id: str = Field(min_length=1, description="the task's name in its suite (its group file's name)")
    family: Family = Field(description="formation | navigation | resilience | dense | flocking")
    description: str = Field(min_length=1, description="what the swarm must do, one line")
    horizon: float = Field(gt=0, le=MAX_DURATION, description="the fixed horizon, s (clock.duration)")
    seeds: list[int] = Field(min_length=1, description="the seeds a method is scored on")
    score: ScoreConfig = Field(description="how a run is scored (metric, unit, direction, pass rule)")
