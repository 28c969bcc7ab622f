"""Hydra's basic sweeper, validating a sweep's configs up front only as far as they can differ.

Before launching anything, Hydra's ``BasicSweeper`` composes the config of every job of the sweep
in the main process, so that a bad override fails at once instead of in the middle of the sweep.
At ~0.1 s per composition of swarmscene's config tree this is serial time no launcher can
spread: 15 s before the first job of the thesis' 150-job corridor sweep, 100 s for 1,000 jobs
(hydra#1324; Hydra's own code notes it "can be a bit slow for large jobs").

Composition can only fail through an override: a config group option that does not exist, or a
key that does not exist. Which option a group takes matters, so every distinct override is
composed in at least one job; a number is a plain value (our config nodes are untyped), so for a
numeric override only its key needs composing once. The thesis sweep (5 widths x 30 seeds) then
composes 5 jobs up front instead of 150. ``hydra.sweeper.validate: all`` restores Hydra's check
of every job; everything else is the basic sweeper unchanged (``params``, ``max_batch_size``).
Selected with ``hydra/sweeper=swarmscene`` (the grid presets in ``scenarios/sweep`` do).

A job whose config still fails to compose at launch is reported by the launcher as usual.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hydra.plugins.sweeper import Sweeper

VALIDATE = ("each_value", "all")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def jobs_to_validate(batch: Sequence[Sequence[str]]) -> list[Sequence[str]]:
    """The jobs whose composition covers every override of ``batch`` (first come, in order).

    Each override ``key=value`` must appear in a chosen job; a numeric value counts as just its
    key (``seed=0`` covers ``seed=17``).
    """
    seen: set[str] = set()
    chosen = []
    for overrides in batch:
        keys = set()
        for override in overrides:
            key, _, value = override.partition("=")
            keys.add(f"{key}=<number>" if _is_number(value) else override)
        if not keys <= seen:
            seen |= keys
            chosen.append(overrides)
    return chosen


class SwarmsceneSweeper(Sweeper):
    """Hydra's ``BasicSweeper`` whose up-front validation composes one job per distinct override.

    It wraps a ``BasicSweeper`` rather than subclassing it: Hydra's plugin scan re-executes the
    module of its core plugins, so a subclass made at import time can end up with a stale base.
    """

    def __init__(
        self, max_batch_size: int | None, params: dict[str, str] | None = None, validate: str = "each_value"
    ) -> None:
        from hydra._internal.core_plugins import basic_sweeper

        if validate not in VALIDATE:
            raise ValueError(f"hydra.sweeper.validate: must be one of {VALIDATE} (got {validate!r})")
        self.basic = basic_sweeper.BasicSweeper(max_batch_size=max_batch_size, params=params)
        if validate == "each_value":
            check_all = self.basic.validate_batch_is_legal
            self.basic.validate_batch_is_legal = lambda batch: check_all(jobs_to_validate(batch))

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        self.basic.setup(hydra_context=hydra_context, task_function=task_function, config=config)

    def sweep(self, arguments: list[str]) -> Any:
        return self.basic.sweep(arguments)


def register() -> None:
    """Make Hydra know the sweeper (its scan of ``hydra_plugins`` misses editable installs)."""
    from hydra.core.plugins import Plugins

    plugins = Plugins.instance()
    if SwarmsceneSweeper not in plugins.class_name_to_class.values():
        plugins.register(SwarmsceneSweeper)
