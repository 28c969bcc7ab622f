"""The setpoint record: the one interface every formation, avoidance and dynamics plugin shares.

A formation fills it each guidance tick, an avoidance method returns a safe copy of it, and the
dynamics model's controller turns it into motion. All arrays have agents along the first axis and
are in the world frame (see :mod:`swarmscene.core.state`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


class Mode(IntEnum):
    """How the controller should use an agent's setpoint (``Setpoints.mode``).

    POSITION: go to ``pos`` and stay there (``vel``, ``acc`` are feed-forward, usually zero).
    VELOCITY: fly at ``vel`` (``pos`` is ignored); e.g. APF navigation, flocking.
    TRACK: follow a moving target whose state is ``pos``, ``vel`` and whose input is ``acc``
        (thesis tracker control, eq. 3.41-3.44; flat outputs of a VRB trajectory).
    HOLD: keep still where the agent is (failed vehicles, agents waiting).
    """

    POSITION = 0
    VELOCITY = 1
    TRACK = 2
    HOLD = 3


def is_mode(mode: np.ndarray, *modes: Mode) -> np.ndarray:
    """Which agents' ``mode`` (N,) is one of ``modes``, (N,) bool. Compared as plain ints: numpy
    compares an array with an enum member about 5x slower (~2.5 us against 0.5 for six agents),
    which a per-world tick pays several times."""
    hit = mode == int(modes[0])
    for other in modes[1:]:
        hit |= mode == int(other)
    return hit


@dataclass
class Setpoints:
    """Per-agent references for this guidance tick.

    Attributes:
        mode: (N,) int8, values of :class:`Mode`.
        pos: (N, 3) m, reference position.
        vel: (N, 3) m/s, reference velocity (the command in VELOCITY mode, feed-forward otherwise).
        acc: (N, 3) m/s^2, feed-forward acceleration (the target's input in TRACK mode).
        yaw: (N,) rad, heading about world z (0 = facing +x).
        jerk: (N, 3) m/s^3 or ``None``; flat-output feed-forward for attitude-level controllers.
        snap: (N, 3) m/s^4 or ``None``; flat-output feed-forward for attitude-level controllers.
    """

    mode: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    yaw: np.ndarray
    jerk: np.ndarray | None = None
    snap: np.ndarray | None = None

    @classmethod
    def hold(cls, pos: np.ndarray, yaw: np.ndarray | None = None) -> Setpoints:
        """Every agent holds ``pos`` (N, 3) with zero feed-forward."""
        n = pos.shape[0]
        return cls(
            mode=np.full(n, int(Mode.HOLD), dtype=np.int8),  # an int: numpy converts an enum slowly
            pos=np.array(pos, dtype=float, copy=True),
            vel=np.zeros((n, 3)),
            acc=np.zeros((n, 3)),
            yaw=np.zeros(n) if yaw is None else np.array(yaw, dtype=float, copy=True),
        )

    def copy(self) -> Setpoints:
        """A deep copy, so an avoidance method can edit without touching the formation's arrays."""
        # The constructor, not dataclasses.replace (twice its cost, on every avoidance's tick).
        return type(self)(
            self.mode.copy(), self.pos.copy(), self.vel.copy(), self.acc.copy(), self.yaw.copy(),
            None if self.jerk is None else self.jerk.copy(),
            None if self.snap is None else self.snap.copy(),
        )

    @property
    def n(self) -> int:
        """N, the agents these setpoints command."""
        return self.pos.shape[0]
