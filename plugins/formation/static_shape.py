"""Static shape: a fixed formation (line, grid, circle, V, triangle) carried along waypoints.

A virtual reference point moves along the waypoint polyline at ``speed``; each slot is the
reference plus the shape's offset, rotated with the path heading when ``rotate_with_heading``.
Agents are assigned to slots by minimum total distance (``methods.assignment.min_cost_assignment``)
at the start and, when ``reassign_on_failure``, again among the healthy agents after a failure.
Agents get TRACK setpoints: slot position, the reference's velocity as feed-forward.

The mission is complete when the reference has reached the last waypoint and every healthy agent is
within ``arrival_tolerance`` of its slot.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from swarmscene.methods.assignment import min_cost_assignment
from swarmscene.methods.paths import WaypointPath
from swarmscene.methods.shapes import shape_offsets
from swarmscene.plugin import (
    BuildContext,
    Formation,
    Mode,
    PluginParams,
    SetpointBatch,
    Setpoints,
    WorldState,
    hookimpl,
    rows_of,
)

_TRACK, _HOLD = int(Mode.TRACK), int(Mode.HOLD)


class StaticShape(Formation):
    """A fixed shape following waypoints, slots assigned by minimum total distance."""

    name = "static_shape"

    class Params(PluginParams):
        shape: Literal["line", "grid", "circle", "v", "triangle"] = Field(
            "v", description="formation shape"
        )
        spacing: float = Field(2.0, gt=0, description="distance between neighbouring slots, m")
        waypoints: list[tuple[float, float, float]] = Field(
            min_length=1, description="path of the formation's centre, [x, y, z] m"
        )
        speed: float = Field(1.0, gt=0, description="speed of the reference along the path, m/s")
        rotate_with_heading: bool = Field(
            True, description="turn the shape so its x axis follows the path heading"
        )
        reassign_on_failure: bool = Field(
            True, description="re-assign slots among healthy agents after a failure"
        )
        arrival_tolerance: float = Field(
            0.5, gt=0, description="distance to its slot at which an agent has arrived, m"
        )

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        start = ctx.initial.pos.mean(axis=0)
        self.path = WaypointPath(np.vstack([start, params.waypoints]), params.speed)
        self.offsets = shape_offsets(params.shape, ctx.n, params.spacing)
        # The heading changes only from leg to leg: each leg's, and the offsets turned by it, once.
        self._leg_heading = [self._heading(leg) for leg in range(max(len(self.path.directions), 1))]
        self.heading = self._leg_heading[0]
        self.slot_of = self.assign(ctx.initial.pos, np.ones(ctx.n, dtype=bool), start)
        self._healthy_count = ctx.n
        self._end_reached = False
        self._placed: _Placement | None = None

    def _heading(self, leg: int) -> float:
        if not self.params.rotate_with_heading or len(self.path.directions) == 0:
            return 0.0
        d = self.path.directions[min(leg, len(self.path.directions) - 1)]
        return float(np.arctan2(d[1], d[0]))

    def slots(self, center: np.ndarray, heading: float) -> np.ndarray:
        """World positions (N, 3) of the slots around ``center`` for ``heading``."""
        return center + self._turned_offsets(heading)

    def _turned_offsets(self, heading: float) -> np.ndarray:
        """The slot offsets (N, 3) turned by ``heading`` about z."""
        c, s = np.cos(heading), np.sin(heading)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return self.offsets @ rot.T

    def assign(self, pos: np.ndarray, healthy: np.ndarray, center: np.ndarray) -> np.ndarray:
        """Slot index per agent minimising total distance (healthy agents; others keep -1)."""
        slots = self.slots(center, self.heading)
        agents = np.flatnonzero(healthy)
        cost = np.linalg.norm(pos[agents, None, :] - slots[None, :, :], axis=2)
        rows, cols = min_cost_assignment(cost)
        slot_of = np.full(len(pos), -1)
        slot_of[agents[rows]] = cols
        return slot_of

    def setpoints(self, world: WorldState, sensing) -> Setpoints:
        """The shape's slots carried along the path at time t (heading of the current leg); the
        slots are reassigned after a failure when ``reassign_on_failure``."""
        center, velocity, placed = self._plan(world)
        n = world.n
        # TRACK the slot (reference + offset) at the reference's velocity; an agent without a
        # slot holds where it is (HOLD, zero feed-forward). Built directly: a few calls a tick.
        pos = center + placed.offset
        vel = np.empty((n, 3))
        vel[:] = velocity
        if not placed.every:
            pos[placed.unslotted] = world.pos[placed.unslotted]
            vel[placed.unslotted] = 0.0
        yaw = np.empty(n)
        yaw.fill(self.heading)
        sp = Setpoints(placed.mode.copy(), pos, vel, np.zeros((n, 3)), yaw)
        self._last_slots = sp.pos
        return sp

    @classmethod
    def setpoints_batch(cls, formations: Sequence[StaticShape], worlds: Sequence[WorldState],
                        sensings: Sequence[object]) -> SetpointBatch | object:
        """``setpoints`` of B worlds of N agents as one :class:`SetpointBatch`: each world's
        reference and slot placement found as its own ``setpoints`` finds them (:meth:`_plan`),
        then the slots, velocities, modes and headings of the B N agents in one elementwise pass
        over the stacked worlds, which gives every agent its single run's bits. Declined for
        worlds of different sizes."""
        n = len(worlds[0].pos)
        if any(len(world.pos) != n for world in worlds):
            return NotImplemented
        plans = [formation._plan(world) for formation, world in zip(formations, worlds, strict=True)]
        b = len(plans)
        center = np.array([plan[0] for plan in plans])
        velocity = np.array([plan[1] for plan in plans])
        pos = center[:, None, :] + np.stack([plan[2].offset for plan in plans])
        vel = np.empty((b, n, 3))
        vel[:] = velocity[:, None, :]
        for world_pos, world_vel, world, (_, _, placed) in zip(pos, vel, worlds, plans, strict=True):
            if not placed.every:
                world_pos[placed.unslotted] = world.pos[placed.unslotted]
                world_vel[placed.unslotted] = 0.0
        yaw = np.empty((b, n))
        yaw[:] = np.array([formation.heading for formation in formations])[:, None]
        mode = np.stack([plan[2].mode for plan in plans])
        for formation, world_pos in zip(formations, pos, strict=True):
            formation._last_slots = world_pos
        return SetpointBatch(Setpoints(mode.reshape(b * n), pos.reshape(b * n, 3), vel.reshape(b * n, 3),
                                       np.zeros((b * n, 3)), yaw.reshape(b * n)), b)

    def _plan(self, world: WorldState) -> tuple[np.ndarray, np.ndarray, _Placement]:
        """The reference's position and velocity (3,) at time t, and the slots' placement around
        it for the current leg's heading (kept as ``heading``); the slots are reassigned among the
        healthy agents after a failure when ``reassign_on_failure``."""
        center, velocity, leg, self._end_reached = self.path.at(world.t)
        self.heading = self._leg_heading[min(leg, len(self._leg_heading) - 1)]
        healthy_count = int(np.count_nonzero(world.healthy))
        if self.params.reassign_on_failure and healthy_count != self._healthy_count:
            self.slot_of = self.assign(world.pos, world.healthy, center)
            self._healthy_count = healthy_count
            self._placed = None
        placed = self._placed
        if placed is None or placed.heading != self.heading:
            placed = self._placed = _Placement.of(self.heading, self._turned_offsets(self.heading), self.slot_of)
        return center, velocity, placed

    def complete(self, world: WorldState) -> bool:
        """True once the path's end is reached and every healthy agent with a slot is within
        ``arrival_tolerance`` of it."""
        if not self._end_reached:
            return False
        active = world.healthy & (self.slot_of >= 0)
        error = np.linalg.norm(world.pos[active] - self._last_slots[active], axis=1)
        return bool(np.all(error <= self.params.arrival_tolerance))


@dataclass(frozen=True)
class _Placement:
    """Where each agent's slot sits around the reference for one heading: its slot's offset turned
    by the heading (slot = reference + offset, the same sum as ``slots()[slot_of]``), the agents
    with a slot and their setpoint modes. Kept until the heading or the assignment changes."""

    heading: float
    offset: np.ndarray
    """(N, 3) m; rows of agents without a slot are unused"""
    unslotted: np.ndarray | slice
    """the agents without a slot (a slice when consecutive: core.vectors.rows_of)"""
    every: bool
    mode: np.ndarray
    """(N,) int8: TRACK with a slot, HOLD without"""

    @classmethod
    def of(cls, heading: float, turned: np.ndarray, slot_of: np.ndarray) -> _Placement:
        slotted = slot_of >= 0
        mode = np.where(slotted, _TRACK, _HOLD).astype(np.int8)
        return cls(heading, turned[np.maximum(slot_of, 0)], rows_of(np.flatnonzero(~slotted)),
                   bool(slotted.all()), mode)


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Add :class:`StaticShape` to the registry, so that ``formation=static_shape`` chooses it."""
    register(StaticShape)
