"""Trajectory recorder: the agents' states over time, written as ``trajectory.npz``.

Format (one documented columnar file, numpy ``.npz``; every array has time along axis 0):
    t: (T,) s.
    pos: (T, N, 3) m, world frame (x east, y north, z up).
    vel: (T, N, 3) m/s.
    healthy: (T, N) bool.
    quat: (T, N, 4) (w, x, y, z), only when the dynamics model has attitude.
Frames are taken at t = 0 and after every ``output.trajectory_every``-th guidance tick; arrays are
float32 when ``output.float32`` is set.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .hookspecs import hookimpl

if TYPE_CHECKING:  # pragma: no cover
    from .simulation import Simulation


class TrajectoryRecorder:
    """Keeps decimated frames of the world state in preallocated arrays."""

    def __init__(self, sim: "Simulation") -> None:
        out = sim.config.output
        self.enabled = out.trajectory
        self.every = out.trajectory_every
        self.count = 0
        if not self.enabled:
            return
        frames = sim.total_steps // self.every + 1
        n = sim.world.n
        dtype = np.float32 if out.float32 else np.float64
        self.t = np.zeros(frames)
        self.pos = np.zeros((frames, n, 3), dtype=dtype)
        self.vel = np.zeros((frames, n, 3), dtype=dtype)
        self.healthy = np.zeros((frames, n), dtype=bool)
        self.quat = np.zeros((frames, n, 4), dtype=dtype) if sim.dynamics.has_attitude else None

    def _record(self, sim: "Simulation") -> None:
        k, world = self.count, sim.world
        self.t[k] = world.t
        self.pos[k] = world.pos
        self.vel[k] = world.vel
        self.healthy[k] = world.healthy
        if self.quat is not None and world.quat is not None:
            self.quat[k] = world.quat
        self.count += 1

    @hookimpl
    def swarmscene_run_start(self, sim: "Simulation") -> None:
        if self.enabled:
            self._record(sim)

    @hookimpl
    def swarmscene_step_end(self, sim: "Simulation") -> None:
        if self.enabled and sim.step_count % self.every == 0:
            self._record(sim)

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded frames (empty dict when recording is off)."""
        if not self.enabled:
            return {}
        k = self.count
        arrays = {"t": self.t[:k], "pos": self.pos[:k], "vel": self.vel[:k], "healthy": self.healthy[:k]}
        if self.quat is not None:
            arrays["quat"] = self.quat[:k]
        return arrays


@hookimpl
def swarmscene_register_observers(register: Any) -> None:
    register(TrajectoryRecorder)
