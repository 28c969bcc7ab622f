"""What a run returns: metrics, why it stopped, and the observers' records (trajectory, series)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class RunResult:
    """The outcome of :meth:`Simulation.run`.

    Attributes:
        metrics: flat dotted keys in SI units (see docs/outputs.md).
        stop_reason: ``duration``, ``complete``, ``collision`` or ``interrupted``.
        complete: False when the run was interrupted before its end.
        observers: this run's observer instances (the recorder holds the trajectory).
        run_dir: where the outputs were written, if they were.
    """

    metrics: dict[str, Any]
    stop_reason: str
    complete: bool
    observers: list[Any] = field(default_factory=list)
    run_dir: Path | None = None

    def observer(self, cls_name: str) -> Any:
        """This run's observer whose class is named ``cls_name``."""
        for obj in self.observers:
            if type(obj).__name__ == cls_name:
                return obj
        raise KeyError(cls_name)

    @property
    def trajectory(self) -> dict[str, np.ndarray]:
        """Recorded arrays: ``t`` (T,), ``pos`` (T, N, 3), ``vel`` (T, N, 3), ``healthy`` (T, N)."""
        return self.observer("TrajectoryRecorder").arrays()

    @property
    def series(self) -> dict[str, np.ndarray]:
        """Safety time series: ``t``, ``min_separation``, ``min_clearance``, ``connected``."""
        return self.observer("SafetyMonitor").arrays()
