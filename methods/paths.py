"""Reference paths: a polyline of way-points flown at constant speed."""

from __future__ import annotations

import numpy as np


class WaypointPath:
    """A polyline flown at constant speed: position and velocity of the reference at time t."""

    def __init__(self, waypoints: np.ndarray, speed: float) -> None:
        self.points = np.asarray(waypoints, dtype=float)
        legs = np.diff(self.points, axis=0)
        self.lengths = np.linalg.norm(legs, axis=1)
        self.cumulative = np.concatenate([[0.0], np.cumsum(self.lengths)])
        self.directions = legs / np.maximum(self.lengths, 1e-12)[:, None]
        self.speed = speed

    @property
    def length(self) -> float:
        return float(self.cumulative[-1])

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, int, bool]:
        """Reference position (3,), velocity (3,), current leg and whether the end is reached."""
        s = min(self.speed * t, self.length)
        if len(self.lengths) == 0 or s >= self.length:
            return self.points[-1].copy(), np.zeros(3), max(len(self.lengths) - 1, 0), True
        leg = int(np.searchsorted(self.cumulative, s, side="right") - 1)
        pos = self.points[leg] + self.directions[leg] * (s - self.cumulative[leg])
        return pos, self.directions[leg] * self.speed, leg, False
