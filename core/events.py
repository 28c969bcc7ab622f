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
from typing import Literal

import numpy as np
from pydantic import Field

from .fields import MAX_DURATION, StrictModel
from .state import WorldState


class EventConfig(StrictModel):
    """One scheduled event (see :mod:`swarmscene.core.events`)."""

    at: float = Field(ge=0, le=MAX_DURATION, description="time, s")
    agents: list[int] = Field(min_length=1, description="indices of the agents hit")
    kind: Literal["hover", "comm_loss"] = Field(description="hover: failure, holds position")


def check_events(events: list[EventConfig], n: int) -> list[str]:
    """One error line per event naming an agent outside 0..n-1 (checks across config sections)."""
    errors = []
    for k, event in enumerate(events):
        bad = [a for a in event.agents if not 0 <= a < n]
        if bad:
            errors.append(f"events.{k}.agents: agents are 0..{n - 1} (got {bad})")
    return errors


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
    """Events sorted by time; the kernel applies them (:meth:`apply_due`) in the events phase of
    a tick and enforces what they leave behind (:meth:`hold`) after the dynamics."""

    def __init__(self, events: list[Event]) -> None:
        self._events = sorted(events, key=lambda e: e.at)
        self._next = 0
        self._hover_pos: np.ndarray | None = None

    @classmethod
    def from_config(cls, events: list[EventConfig]) -> "EventQueue":
        """The queue of a scenario's ``events`` list."""
        return cls([Event(e.at, tuple(e.agents), EventKind(e.kind)) for e in events])

    def due(self, t: float, tol: float = 1e-9) -> list[Event]:
        """Events with ``at <= t`` (within ``tol``) not yet returned, in time order."""
        start = self._next
        while self._next < len(self._events) and self._events[self._next].at <= t + tol:
            self._next += 1
        return self._events[start : self._next]

    def apply_due(self, world: WorldState) -> list[Event]:
        """Apply the events due at ``world.t`` to ``world``; return them, in time order."""
        applied = self.due(world.t)
        for event in applied:
            event.apply(world)
            if event.kind is EventKind.HOVER:
                if self._hover_pos is None:
                    self._hover_pos = world.pos.copy()
                idx = list(event.agents)
                self._hover_pos[idx] = world.pos[idx]
        return applied

    def hold(self, world: WorldState) -> None:
        """Failed vehicles hover where they failed, whatever the dynamics model did."""
        failed = ~world.healthy
        if failed.any() and self._hover_pos is not None:
            world.pos[failed] = self._hover_pos[failed]
            world.vel[failed] = 0.0
