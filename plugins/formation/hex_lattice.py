"""Hexagonal lattice formation around a leader flying waypoints (thesis chapter 4, section 4.3).

The leader (``world.leader``) sits on node 0 of the hexagonal pattern of
:mod:`~swarmscene.methods.outdoor.hex_pattern` (eq. 4.3-4.11, spacing d_r, yaw alpha); the
followers are assigned to its offsets by the id-ordered, decimetre-rounded rectangular assignment
with the periphery penalty (eq. 4.12-4.13). Every follower gets a TRACK setpoint on its slot
r_N + h_j with the leader's velocity and applied input (``world.acc`` when the dynamics
provides it) as feed-forward: the thesis' tracker control in FLOW (section 3.2.5).

The leader holds its home until every healthy follower is within ``arrival_tolerance`` (eps_r)
of its slot, or ``formation_timeout`` (T_for) has passed; it then tracks a reference moving at
``leader_speed`` along ``waypoints``. Getting followers to their slots without collisions (the
thesis' FORM sequence) is the avoidance plugin's job: pair it with ``apf_navigation``.

Frames: ``waypoints`` are offsets from the leader's initial position in the world frame (x east,
y north, z up): the thesis gives its path (Table 4.2) in the initial leader's NED frame, so
(north, east, down) -> (east, north, -down). ``alpha_deg`` keeps the thesis convention (from
North towards East); the pattern module converts it.

Simplifications (the full INIT/FORM/FLOW/LEAD/STOP workflow on delayed swarm maps is the formation
``outdoor_mission``, :mod:`~swarmscene.plugins.formation.outdoor_mission`):
the plugin reads the true state, not a delayed swarm map; followers are not sent home at the end;
the catch-up test (eq. 4.1-4.2) is replaced by the slot-distance test above. Slots are
re-assigned each tick only while the leader waits (the thesis' FORM; once it moves, FLOW
followers keep their slot), with a hysteresis ``switch_margin`` (see ``assign_offsets``). A
follower still navigating when the leader sets off (``formation_timeout``) chases a slot that
moves at the leader's speed with APF speed v_sat: it only catches up when the leader slows.

The mission is complete once the leader's reference has reached the last waypoint and every
healthy follower is within ``arrival_tolerance`` of its slot.

In a batch of worlds (docs/batched.md) each world plans as alone (its assignment, leader state
and slots) and the setpoints of every world are made in one pass
(:meth:`HexLattice.setpoints_batch`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from pydantic import Field

from swarmscene.methods.outdoor.hex_pattern import assign_offsets, hex_pattern
from swarmscene.methods.paths import WaypointPath
from swarmscene.plugin import (
    BuildContext,
    Formation,
    Mode,
    PluginParams,
    SetpointBatch,
    Setpoints,
    WorldState,
    hookimpl,
)


class HexLattice(Formation):
    """Followers on a pruned hexagonal lattice around a waypoint-following leader."""

    name = "hex_lattice"
    metric_prefix = "hex"
    requires_leader = True

    class Params(PluginParams):
        d_r: float = Field(5.0, gt=0, description="formation spacing d_r, m (Table 4.3: 5 m)")
        alpha_deg: float = Field(
            0.0, description="formation yaw alpha, deg, from North towards East (Table 4.3: 0)"
        )
        waypoints: list[tuple[float, float, float]] = Field(
            default_factory=lambda: [(0.0, 0.0, 0.0)],
            min_length=1,
            description="leader path as offsets from its initial position, [x east, y north, z up] m",
        )
        leader_speed: float = Field(0.5, gt=0, description="speed of the leader's reference, m/s")
        arrival_tolerance: float = Field(
            0.5, gt=0, description="eps_r: a follower this close to its slot is in place, m"
        )
        formation_timeout: float = Field(
            40.0, ge=0, description="T_for: the leader sets off after this long even if not formed, s"
        )
        reassign: Literal["while_forming", "every_tick", "on_failure"] = Field(
            "while_forming",
            description="when slots are re-assigned: each tick while the leader waits (thesis FORM), "
            "each tick, or only after a failure (always also after a failure)",
        )
        switch_margin: float = Field(
            0.5, ge=0, description="hysteresis of the re-assignment: a follower's current slot is "
            "discounted by this distance, m (0: the thesis' plain re-assignment)"
        )
        input_feedforward: bool = Field(
            True, description="add the leader's applied input (world.acc) as TRACK feed-forward"
        )

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        leader = ctx.initial.leader  # requires_leader: validation checked it
        if ctx.n < 2:
            raise ValueError("hex_lattice needs at least one follower")
        self.leader = leader
        self.home = ctx.initial.pos[leader].copy()
        self.path = WaypointPath(np.vstack([self.home, self.home + np.asarray(params.waypoints)]),
                                 params.leader_speed)
        self.pattern = hex_pattern(ctx.n, params.d_r, np.deg2rad(params.alpha_deg))
        self.followers = np.flatnonzero(np.arange(ctx.n) != leader)
        self.slot_of = np.full(ctx.n, -1)
        self._healthy = ctx.initial.healthy.copy()
        self._assign(ctx.initial)
        self.t_start: float | None = None  # when the leader set off
        self.formed_at: float | None = None
        self._end_reached = False
        self._targets = ctx.initial.pos.copy()

    # -- assignment ----------------------------------------------------------------------------

    def _assign(self, world: WorldState) -> None:
        """Eq. 4.12-4.13 over the healthy followers (ids = agent indices)."""
        ids = self.followers[world.healthy[self.followers]]
        current = self.slot_of[ids].copy()
        self.slot_of[:] = -1
        if ids.size:
            self.slot_of[ids] = assign_offsets(self.pattern, ids, world.pos[ids], world.pos[self.leader],
                                               current, self.params.switch_margin)

    def _in_place(self, world: WorldState, targets: np.ndarray) -> np.ndarray:
        active = world.healthy & (self.slot_of >= 0)
        error = np.linalg.norm(world.pos - targets, axis=1)
        return ~active | (error <= self.params.arrival_tolerance)

    # -- formation -----------------------------------------------------------------------------

    def slot_targets(self, world: WorldState) -> np.ndarray:
        """World position of every follower's slot (N, 3): r_N + h_j at the leader's altitude."""
        targets = world.pos.copy()
        f = self.slot_of >= 0
        targets[f, :2] = world.pos[self.leader, :2] + self.pattern.offsets_xy[self.slot_of[f]]
        targets[f, 2] = world.pos[self.leader, 2]
        return targets

    def setpoints(self, world: WorldState, sensing) -> Setpoints:
        """TRACK setpoints: the leader holds home until the lattice has formed (or the timeout), then
        follows the path; each follower tracks its slot with the leader's state as feed-forward.
        Slots are reassigned after a failure and as ``reassign`` says."""
        targets, ref_pos, ref_vel = self._plan(world)
        leader = np.array([self.leader])
        return self._tracked(world.pos, world.vel, world.acc, leader, self.slot_of >= 0, targets,
                             ref_pos[None, :], ref_vel[None, :])

    @classmethod
    def setpoints_batch(cls, formations: Sequence[HexLattice], worlds: Sequence[WorldState],
                        sensings: Sequence[object]) -> SetpointBatch | object:
        """``setpoints`` of B worlds of N agents as one :class:`SetpointBatch`: each world's
        assignment, leader state and slots found as its own ``setpoints`` finds them
        (:meth:`_plan`), then the modes, references and feed-forward of the B N agents in
        elementwise passes over the stacked worlds, which give every agent its single run's bits.
        Declined where the instances' options or the worlds' sizes differ."""
        first, n = formations[0], len(worlds[0].pos)
        if any(f.params != first.params for f in formations) or any(len(world.pos) != n for world in worlds):
            return NotImplemented
        if len({world.acc is None for world in worlds}) > 1:
            return NotImplemented  # the feed-forward is given to all worlds or to none
        plans = [f._plan(world) for f, world in zip(formations, worlds, strict=True)]
        rows = np.arange(len(worlds)) * n
        leaders = rows + np.array([f.leader for f in formations])
        acc = None if worlds[0].acc is None else np.concatenate([world.acc for world in worlds])
        sp = first._tracked(
            np.concatenate([world.pos for world in worlds]), np.concatenate([world.vel for world in worlds]), acc,
            leaders, np.concatenate([f.slot_of >= 0 for f in formations]), np.concatenate([plan[0] for plan in plans]),
            np.array([plan[1] for plan in plans]), np.array([plan[2] for plan in plans]))
        return SetpointBatch(sp, len(worlds))

    def _plan(self, world: WorldState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This tick's slots (N, 3) and the leader's reference position and velocity (3,): the
        slots reassigned (after a failure and as ``reassign`` says), the formation and the
        leader's start noted, the path's reference read."""
        p = self.params
        failure = not np.array_equal(world.healthy, self._healthy)
        leader_waiting = self.t_start is None
        if failure or p.reassign == "every_tick" or (leader_waiting and p.reassign == "while_forming"):
            self._assign(world)
            self._healthy = world.healthy.copy()

        targets = self.slot_targets(world)
        if self.formed_at is None and np.all(self._in_place(world, targets)):
            self.formed_at = world.t
        if leader_waiting and (self.formed_at is not None or world.t >= p.formation_timeout):
            self.t_start = world.t
        # Leader: holds home, then tracks the path reference.
        if self.t_start is None:
            ref_pos, ref_vel, self._end_reached = self.home, np.zeros(3), False
        else:
            ref_pos, ref_vel, _, self._end_reached = self.path.at(world.t - self.t_start)
        self._targets = targets
        return targets, ref_pos, ref_vel

    def _tracked(self, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray | None, leaders: np.ndarray,
                 slotted: np.ndarray, targets: np.ndarray, ref_pos: np.ndarray, ref_vel: np.ndarray) -> Setpoints:
        """The TRACK setpoints of agents at ``pos`` (rows of one world, or of stacked worlds):
        the leaders' rows on their references (one row each), every slotted follower on its slot
        with its leader's velocity and (``input_feedforward``) applied input as feed-forward;
        the others hold."""
        sp = Setpoints.hold(pos)
        sp.mode[leaders] = Mode.TRACK
        sp.pos[leaders], sp.vel[leaders] = ref_pos, ref_vel
        f = np.flatnonzero(slotted)
        whose = leaders[f // (len(slotted) // len(leaders))]  # each follower's own world's leader
        sp.mode[f] = Mode.TRACK
        sp.pos[f] = targets[f]
        sp.vel[f] = vel[whose]
        if self.params.input_feedforward and acc is not None:
            sp.acc[f] = acc[whose]
        return sp

    def complete(self, world: WorldState) -> bool:
        """True once the leader has reached the path's end and every agent is in its slot."""
        if not self._end_reached:
            return False
        return bool(np.all(self._in_place(world, self.slot_targets(world))))

    @hookimpl
    def swarmscene_run_end(self, sim, metrics: dict) -> None:
        """``hex.*`` metrics: pattern size, when the formation was reached and the leader left."""
        metrics["hex.m"] = self.pattern.m
        metrics["hex.m_max"] = self.pattern.m_max
        metrics["hex.formed_at"] = self.formed_at
        metrics["hex.leader_start"] = self.t_start
        metrics["hex.path_done"] = bool(self._end_reached)


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Add :class:`HexLattice` to the registry, so that ``formation=hex_lattice`` chooses it."""
    register(HexLattice)
