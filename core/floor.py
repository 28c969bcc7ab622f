"""The ground (``environment.floor``): where a vehicle lands, or crashes.

Without a floor (``environment.floor: null``, the default) the world has no ground: a vehicle may
fly at any height, z < 0 included, and one that falls (a ``stuck`` or ``drift`` failure coasting
downwards, a dead battery) falls forever. Every preset is built that way.

With a floor at height z_f (m, world frame, z up), after the tick's physics and the events' hold
(:meth:`Floor.meet`), every vehicle below it is put back on it, at rest, and:

* a healthy vehicle that met it at most ``touchdown_speed`` (m/s, its speed) lands: it stays
  healthy and its dynamics may lift it off again (``floor.landings`` counts touchdowns);
* any vehicle faster than that crashes: a ``crash`` event (a failure: it stays where it hit, at
  rest), counted in ``floor.crashes`` and held against ``success``;
* a failed vehicle (coasting, falling) that meets it slowly comes to rest there: a ``landed``
  event (it stays, at rest).

Metrics (only with a floor): ``floor.height``, ``floor.crashes`` (distinct vehicles),
``floor.landings`` (touchdowns of healthy vehicles), ``floor.min_height`` (the lowest height above
the floor of a vehicle in the air over the ticks, m), and ``violations.floor.first_time`` /
``.agents`` at the first crash.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .events import Event, EventKindPlugin, Motion
from .hookspecs import hookimpl
from .state import WorldState


class Crash(EventKindPlugin):
    """A vehicle met the floor faster than the touchdown speed: it failed and stays where it hit."""

    name = "crash"
    motion = Motion.HOLD


class Landed(EventKindPlugin):
    """A failed vehicle came down slowly on the floor: it stays there, at rest."""

    name = "landed"
    motion = Motion.HOLD


class Floor:
    """The ground of one run (module docstring).

    Args:
        height: z_f, m.
        touchdown_speed: the fastest a vehicle may meet it and land, m/s.
        guidance_period: T_s, s (an event raised after a tick's physics is dated at its end).
    """

    def __init__(self, height: float, touchdown_speed: float, guidance_period: float) -> None:
        self.height = float(height)
        self.touchdown_speed = float(touchdown_speed)
        self.T_s = guidance_period
        self.on_ground: np.ndarray | None = None  # (N,) bool: resting on it after the last tick
        self.crashed: set[int] = set()
        self.landings = 0
        self.min_height = np.inf
        self.first: tuple[float, list[int]] | None = None

    def below_at_start(self, pos: np.ndarray) -> list[int]:
        """Agents whose start ``pos`` (N, 3) is under the floor (a config error)."""
        return np.flatnonzero(pos[:, 2] < self.height).tolist()

    def meet(self, world: WorldState) -> list[Event]:
        """Put every vehicle under the floor back on it, at rest; return the crash and landed events
        of this tick (dated at its end, ``world.t + T_s``)."""
        z = world.pos[:, 2]
        if self.on_ground is None:
            self.on_ground = z <= self.height
        below = np.flatnonzero(z < self.height)
        airborne = z > self.height
        if airborne.any():
            self.min_height = min(self.min_height, float(z[airborne].min()) - self.height)
        if not below.size:
            self.on_ground = z <= self.height
            return []
        speed = np.sqrt(np.einsum("ij,ij->i", world.vel[below], world.vel[below]))
        fast = speed > self.touchdown_speed
        healthy = world.healthy[below]
        crash = below[fast & np.array([i not in self.crashed for i in below.tolist()], dtype=bool)]
        landed = below[~fast & ~healthy]
        self.landings += int(np.count_nonzero(~fast & healthy & ~self.on_ground[below]))
        world.pos[below, 2] = self.height
        world.vel[below] = 0.0
        self.on_ground = world.pos[:, 2] <= self.height
        t = world.t + self.T_s
        events = []
        if crash.size:
            agents = tuple(int(a) for a in crash)
            self.crashed.update(agents)
            if self.first is None:
                self.first = (t, list(agents))
            events.append(Event(t, agents, Crash.name, kind_class=Crash))
        if landed.size:
            events.append(Event(t, tuple(int(a) for a in landed), Landed.name, kind_class=Landed))
        return events

    def metrics(self) -> dict[str, Any]:
        """``floor.*`` and, after a crash, ``violations.floor.*`` (module docstring)."""
        out: dict[str, Any] = {
            "floor.height": self.height,
            "floor.crashes": len(self.crashed),
            "floor.landings": self.landings,
            "floor.min_height": self.min_height if np.isfinite(self.min_height) else None,
        }
        if self.first is not None:
            out["violations.floor.first_time"] = self.first[0]
            out["violations.floor.agents"] = self.first[1]
        return out

    @hookimpl
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """Add the ``floor.*`` metrics to the run's."""
        metrics.update(self.metrics())
