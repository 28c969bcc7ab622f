"""What a run returns: metrics, why it stopped, and the records (trajectory, safety series)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from .monitors import SafetyMonitor
    from .recorder import TrajectoryRecorder


@dataclass
class RunResult:
    """The outcome of :meth:`Simulation.run`.

    Attributes:
        metrics: flat dotted keys in SI units (see docs/outputs.md).
        stop_reason: ``duration``, ``complete``, ``collision``, ``interrupted``, ``non_finite`` or
            ``plugin_error`` (a plugin raised: :class:`~swarmscene.core.raised.PluginRaised`).
        complete: False when the run was interrupted before its end.
        error: why the run failed (one line), or ``None``; a run stopped by a non-finite state
            names the first agent and tick here, one stopped by a plugin's exception the plugin's
            kind, name and method and the time; its ``success`` is False.
        recorder: this run's trajectory recorder (``None`` when ``output.trajectory`` is off).
        monitor: this run's safety monitor (its time series).
        observers: every observer instance of this run (third-party ones included).
        run_dir: where the outputs were written, if they were.
    """

    metrics: dict[str, Any]
    stop_reason: str
    complete: bool
    error: str | None = None
    recorder: TrajectoryRecorder | None = None
    monitor: SafetyMonitor | None = None
    observers: list[Any] = field(default_factory=list)
    run_dir: Path | None = None

    @property
    def trajectory(self) -> dict[str, np.ndarray]:
        """Recorded arrays: ``t`` (T,), ``pos`` (T, N, 3), ``vel`` (T, N, 3), ``healthy`` (T, N)."""
        if self.recorder is None:
            raise LookupError("this run recorded no trajectory (output.trajectory=false)")
        return self.recorder.arrays()

    @property
    def series(self) -> dict[str, np.ndarray]:
        """Safety time series: ``t``, ``min_separation``, ``min_clearance``, ``connected``."""
        if self.monitor is None:
            raise LookupError("this run has no safety monitor")
        return self.monitor.arrays()
