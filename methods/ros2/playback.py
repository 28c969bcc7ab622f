"""Recorded positions played back as reference paths, with velocity and acceleration feed-forward.

Each vehicle's samples p_k at stamps t_k (a :class:`~swarmscene.methods.ros2.bag.Track`) are
interpolated by the cubic spline through them with not-a-knot ends (``scipy.interpolate.make_interp_spline``,
k = 3; fewer than 4 samples: the spline of degree K - 1). Its error for a path with a bounded
fourth derivative is O(h^4), h the sample spacing: for the clamped spline at most
5/384 h^4 max|p''''| (Hall and Meyer 1976, "Optimal error bounds for cubic spline interpolation",
J. Approx. Theory 16, Theorem 1); velocity and acceleration are the spline's first and second
derivatives (errors O(h^3), O(h^2)).

Time: the window starts ``start`` s after the recording's first sample (of any vehicle) and ends
``end`` s after it (null: at the last sample); simulated time t plays recording time
tau = first + start + t. Outside a vehicle's samples its reference holds the nearest end, with
zero velocity and acceleration.

Vehicles recorded at the same stamps (one TF message for the swarm, or stamps copied from one
clock) share one spline over all their coordinates, so a tick costs one evaluation per group of
stamps, not one per vehicle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .bag import Track


@dataclass(frozen=True)
class _Group:
    members: np.ndarray  # (G,) vehicle indices
    t: np.ndarray  # (K,) s, recording time
    spline: object  # BSpline of (K, G * 3)


class Playback:
    """The reference paths of recorded vehicles (module docstring).

    Args:
        tracks: one per vehicle, in agent order.
        start: s after the recording's first sample where playback begins (>= 0).
        end: s after the recording's first sample where it ends, or None (the last sample).
        offset: (3,) m added to every recorded position (the recording placed in the world).
    """

    def __init__(self, tracks: Sequence[Track], start: float = 0.0, end: float | None = None,
                 offset: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        from scipy.interpolate import make_interp_spline

        first = min(float(tr.t[0]) for tr in tracks)
        # times from the first sample: a lab's stamps (~1.7e9 s) would cost the spline digits
        tracks = [Track(tr.name, tr.t - first, tr.pos) for tr in tracks]
        self.begin = float(start)
        self.end = float(end) if end is not None else max(float(tr.t[-1]) for tr in tracks)
        if self.end <= self.begin:
            raise ValueError(f"end: the window is empty ({start:g} s to {self.end:g} s after the first sample)")
        self.n = len(tracks)
        shift = np.asarray(offset, float)
        groups: dict[bytes, list[int]] = {}
        windows = []
        for i, tr in enumerate(tracks):
            inside = (tr.t >= self.begin) & (tr.t <= self.end)
            if np.count_nonzero(inside) < 2:
                raise ValueError(f"start: {tr.name} has {np.count_nonzero(inside)} sample(s) in the window "
                                 f"({start:g} s to {self.end:g} s after the first sample); at least 2 are needed")
            windows.append((tr.t[inside], tr.pos[inside] + shift))
            groups.setdefault(tr.t[inside].tobytes(), []).append(i)
        self.groups = []
        for members in groups.values():
            t = windows[members[0]][0]
            y = np.concatenate([windows[i][1] for i in members], axis=1)  # (K, G * 3)
            spline = make_interp_spline(t, y, k=min(3, len(t) - 1))
            self.groups.append(_Group(np.asarray(members), t, spline))

    @property
    def duration(self) -> float:
        """Length of the played window, s."""
        return self.end - self.begin

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos, vel, acc), each (N, 3), of the reference at simulated time ``t``."""
        pos, vel, acc = (np.zeros((self.n, 3)) for _ in range(3))
        tau = self.begin + t  # recording time, from its first sample
        for g in self.groups:
            inside = g.t[0] <= tau <= g.t[-1]
            at = min(max(tau, g.t[0]), g.t[-1])
            pos[g.members] = g.spline(at).reshape(-1, 3)  # type: ignore[operator]
            if inside:
                vel[g.members] = g.spline(at, 1).reshape(-1, 3)  # type: ignore[operator]
                acc[g.members] = g.spline(at, 2).reshape(-1, 3)  # type: ignore[operator]
        return pos, vel, acc

    def first_positions(self) -> np.ndarray:
        """(N, 3) m: where each vehicle's reference starts (the swarm's start for a faithful replay)."""
        return self.at(0.0)[0]
