"""Reference paths: a polyline of way-points flown at constant speed."""

from __future__ import annotations

from bisect import bisect_right

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
        # Called every tick: the leg search runs on Python floats (bisect), which costs less than
        # numpy's searchsorted on a few values and finds the same leg from the same doubles.
        self._starts = self.cumulative.tolist()
        self._length = self._starts[-1]
        self._legs = len(self.lengths)

    @property
    def length(self) -> float:
        """Total length of the path, m (the sum of its legs)."""
        return self._length

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, int, bool]:
        """Reference position (3,), velocity (3,), current leg and whether the end is reached."""
        s = min(self.speed * t, self._length)
        if self._legs == 0 or s >= self._length:
            return self.points[-1].copy(), np.zeros(3), max(self._legs - 1, 0), True
        leg = bisect_right(self._starts, s) - 1
        pos = self.points[leg] + self.directions[leg] * (s - self._starts[leg])
        return pos, self.directions[leg] * self.speed, leg, False
