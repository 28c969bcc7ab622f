"""Scheduled events: failures and communication losses applied by the kernel.

In config (``events`` list)::

    events:
      - {at: 5.0, agents: [0], kind: hover}       # agent 0 stops where it is and stays (CEM paper)
      - {at: 9.0, agents: [3, 4], kind: comm_loss} # agents 3 and 4 drop out of the comm graph

The kernel applies an event at the first guidance tick whose time reaches ``at``, changes the world
state, then calls the ``swarmscene_event`` hook so plugins (e.g. CEM) can react.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from .state import WorldState


class EventKind(str, Enum):
    """What happens to the event's agents.

    HOVER: abrupt failure; the vehicle stops where it is (velocity zero) and stays there for the
        rest of the run (``healthy`` False). It remains a physical obstacle.
    COMM_LOSS: the agent's radio fails (``comm_ok`` False): it leaves the communication graph but
        keeps flying on its last information.
    """

    HOVER = "hover"
    COMM_LOSS = "comm_loss"


@dataclass(frozen=True)
class Event:
    """One scheduled event.

    Attributes:
        at: time at which it happens, s (applied at the first guidance tick with t >= at).
        agents: indices of the agents it hits.
        kind: :class:`EventKind`.
    """

    at: float
    agents: tuple[int, ...]
    kind: EventKind

    def apply(self, world: WorldState) -> None:
        """Change ``world`` as this event says."""
        idx = np.asarray(self.agents, dtype=int)
        if self.kind is EventKind.HOVER:
            world.healthy[idx] = False
            world.vel[idx] = 0.0
        elif self.kind is EventKind.COMM_LOSS:
            world.comm_ok[idx] = False


class EventQueue:
    """Events sorted by time; ``due(t)`` pops those whose time has come."""

    def __init__(self, events: list[Event]) -> None:
        self._events = sorted(events, key=lambda e: e.at)
        self._next = 0

    def due(self, t: float, tol: float = 1e-9) -> list[Event]:
        """Events with ``at <= t`` (within ``tol``) not yet returned, in time order."""
        start = self._next
        while self._next < len(self._events) and self._events[self._next].at <= t + tol:
            self._next += 1
        return self._events[start : self._next]
