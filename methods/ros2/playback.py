"""Recorded positions played back as reference paths, with velocity and acceleration feed-forward.

Each vehicle's samples p_k at stamps t_k (a :class:`~swarmscene.methods.ros2.bag.Track`) are
interpolated by the cubic spline through all of them, not-a-knot ends
(``scipy.interpolate.make_interp_spline``, k = 3; fewer than 4 samples: degree K - 1); velocity and
acceleration feed-forward are its first and second derivatives. For a path with a bounded fourth
derivative and sample spacing h, the complete cubic spline's errors are at most
5/384 h^4 max|p''''|, 1/24 h^3 max|p''''| and 3/8 h^2 max|p''''| for position, velocity and
acceleration (Hall and Meyer 1976, "Optimal error bounds for cubic spline interpolation", J.
Approx. Theory 16); the not-a-knot spline keeps them away from its ends (measured: about a
quarter of them in the interior; within three samples of an end, up to about twice the position
bound and four times the velocity one). The spline runs through every sample, not only the
window's, so the window's ends lie inside it.

Time: the window starts ``start`` s after the recording's first sample (of any vehicle) and ends
``end`` s after it (null: at the last sample); simulated time t plays recording time
tau = first + start + t. Outside the window (or a vehicle's samples) its reference holds the
nearest end, with zero velocity and acceleration.

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
    lo: float  # s, recording time where the group's played window starts
    hi: float  # ... and ends
    spline: object  # BSpline of (K, G * 3) through every sample


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
        last = max(float(tr.t[-1]) for tr in tracks)
        self.begin = float(start)
        self.end = float(end) if end is not None else last
        if end is not None and self.end <= self.begin:
            raise ValueError(f"end: must be after start (got {end:g} s <= {start:g} s)")
        if self.begin >= last:
            raise ValueError(f"start: {start:g} s is past the recording's last sample ({last:g} s after its first)")
        self.n = len(tracks)
        self.shift = np.asarray(offset, float)
        groups: dict[bytes, list[int]] = {}
        for i, tr in enumerate(tracks):
            inside = np.count_nonzero((tr.t >= self.begin) & (tr.t <= self.end))
            if inside < 2:
                raise ValueError(f"start: {tr.name} has {inside} sample(s) in the window ({start:g} s to "
                                 f"{self.end:g} s after the first sample); at least 2 are needed")
            groups.setdefault(tr.t.tobytes(), []).append(i)
        self.groups = []
        for members in groups.values():
            # through every sample, not only the window's: the window's ends are then inside the
            # spline, away from its not-a-knot ends (where its error is about twice the interior's)
            t = tracks[members[0]].t
            y = np.concatenate([tracks[i].pos for i in members], axis=1)  # (K, G * 3)
            spline = make_interp_spline(t, y, k=min(3, len(t) - 1))
            lo, hi = max(self.begin, float(t[0])), min(self.end, float(t[-1]))
            self.groups.append(_Group(np.asarray(members), lo, hi, spline))

    @property
    def duration(self) -> float:
        """Length of the played window, s."""
        return self.end - self.begin

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos, vel, acc), each (N, 3), of the reference at simulated time ``t``."""
        pos, vel, acc = (np.zeros((self.n, 3)) for _ in range(3))
        tau = self.begin + t  # recording time, from its first sample
        for g in self.groups:
            at = min(max(tau, g.lo), g.hi)
            pos[g.members] = g.spline(at).reshape(-1, 3)  # type: ignore[operator]
            if at == tau:  # playing: the path's velocity and acceleration as feed-forward
                vel[g.members] = g.spline(at, 1).reshape(-1, 3)  # type: ignore[operator]
                acc[g.members] = g.spline(at, 2).reshape(-1, 3)  # type: ignore[operator]
        return pos + self.shift, vel, acc

    def first_positions(self) -> np.ndarray:
        """(N, 3) m: where each vehicle's reference starts (the swarm's start for a faithful replay)."""
        return self.at(0.0)[0]
