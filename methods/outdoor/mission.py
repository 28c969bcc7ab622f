"""The thesis' leader-follower mission workflow (Karydes 2020, section 4.3.1, Fig. 4.1-4.4).

Every agent runs the workflow on what its swarm map (:mod:`.swarm_map`) says, never on the true
state of the others; its own position, velocity and input are its own (GPS, controller).

States (broadcast in every message): INIT, FORM, FLOW, LEAD, STOP.

- Leader (``world.leader``): LEAD from the start, holds home. No follower in its map after
  T_led: aborts (STOP). It stands still until every follower it knows is in FLOW, then flies its
  waypoints (tracker on a reference moving at ``leader_speed``; the reference stops, "velocity
  limiter set to zero", whenever it waits). It waits T_for for followers to switch to FLOW and
  T_del for them to catch up (eq. 4.1-4.2, threshold Delta_W,th); those still failing are
  ignored for the rest of the mission. Once the last waypoint is visited it sets STOP and waits
  T_end for its followers to be STOP.
- Followers: INIT, hold home until the map has not changed (an agent added or removed) for
  T_ini; then FORM if a LEAD is in the map, or STOP after T_fol without one. FORM: every T_s the
  distributed assignment (eq. 4.12-4.13, :func:`.hex_pattern.assign_offsets`) on the map, APF
  navigation (eq. 4.21-4.28) to r_N + h_slot; arrived (eq. 4.28): FLOW, tracker on the slot with
  the leader's mapped velocity and input as feed-forward. No LEAD and at least one STOP in the
  map: STOP, APF navigation home, done on arrival.

Choices where the text is loose (figures 4.1-4.4 are missing from the copy):
- Eq. 4.1 as printed, Delta(k+1) = (Delta(k) + eps(k+1) - eps(k)) / 2, settles at the
  per-tick change of eps: a follower lagging steadily never trips a metres threshold. We read
  "integrates the variations of the barycenter with respect to the leader" as the variation
  since the reference tick k_0 (departure, or the last change of the set W): Delta(k+1) =
  (Delta(k) + eps(k+1) - eps(k_0)) / 2. After T_del above the threshold, the followers whose
  own offset drifted by more than the threshold (or else the one that drifted most) are ignored.
- The catch-up threshold defaults to d_r / 2 (the text); Table 4.3 lists 2 m (the scenario's).
- A FORM or FLOW follower with no LEAD in its map for T_fol (the leader failed or its radio
  did) runs the stop sequence, as an INIT follower without a leader does.
- "Position control" near a slot or home is the tracker on that point (with the leader's
  mapped velocity as feed-forward near a slot): the thesis' position PID (omega_r = 0.23 rad/s)
  is far slower than the hand-over needs. Holding home also uses the tracker.
- APF neighbours (F_i) are the agents of agent i's own map, at their mapped positions, on its
  flight level; candidates are pruned with the tick's k-d tree with a staleness margin.
- Only FORM followers update the assignment (the thesis: FLOW followers keep their offset), so
  a FLOW follower in the map is taken to hold the slot nearest its mapped position and the FORM
  and INIT followers share the other slots (eq. 4.12-4.13 on those). Every agent with the same
  map computes the same answer; without this a FORM agent could be sent onto a FLOW agent's
  slot. Assignments are cached per identical (decimetre-rounded) view.

Like the thesis, the workflow assumes a connected communication graph: with d_com below the
formation spacing d_r the maps split, followers disagree on the assignment and lose the leader.

The numerics of the ``outdoor_mission`` formation, importable without the plugin machinery:
:class:`MissionWorkflow` is every agent's workflow for one tick (the followers' states,
assignment and navigation, and the leader's :class:`LeaderLogic`), on the swarm maps of
:mod:`.swarm_map`, with its parameters in :class:`WorkflowParameters` (Table 4.3's symbols).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy  # its submodules load on first use: registering the plugin must not import them

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.outdoor.apf_navigation import (
    LEVEL_BAND,
    arrived_on_target,
    attraction_velocity,
    close_to_target,
    flight_level_altitude,
    saturate,
)
from swarmscene.methods.outdoor.hex_pattern import (
    DECIMETRE,
    assign_offsets,
    assignment_cost,
    formation_graph,
    hex_pattern,
    solve_assignment,
)
from swarmscene.methods.outdoor.swarm_map import SwarmMap, hop_matrix, map_repulsion
from swarmscene.methods.paths import WaypointPath

if TYPE_CHECKING:  # pragma: no cover
    from swarmscene.core.sensing import Sensing


@dataclass(frozen=True)
class WorkflowParameters:
    """The workflow's parameters, Table 4.3's symbols (lengths in m, times in s, speeds in m/s)."""

    d_r: float = 5.0  # formation spacing d_r
    alpha_deg: float = 0.0  # formation yaw alpha, deg from North towards East
    d_c: float = 1.65  # collision-free distance d_c
    v_sat: float = 0.5  # APF speed bound v_sat (eq. 4.21)
    eps_r: float = 0.5  # control tolerance eps_r (eq. 4.28)
    waypoints: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),)  # offsets from home
    leader_speed: float = 0.5  # speed of the leader's path reference
    catchup_threshold: float | None = None  # Delta_W,th of eq. 4.1 (None: d_r / 2)
    T_msg: float = 2.0  # data storage time: map entries expire
    T_ini: float = 5.0  # initialization delay (stable map)
    T_fol: float = 10.0  # follower delay (no leader: stop)
    T_led: float = 10.0  # leader delay (no follower: abort)
    T_del: float = 5.0  # catch-up delay
    T_for: float = 40.0  # formation delay (followers to FLOW)
    T_end: float = 10.0  # end delay (followers to STOP)
    tau_com: float = 0.2  # single-hop delay tau_com (section 4.2)
    self_hops: int = 1  # hops of an agent's own message to its own map
    level_offset: float = 1.0  # navigation flight level above the target, in d_c
    altitude_gain: float = 1.0  # vertical speed per m off the flight level, 1/s


class Task(IntEnum):
    """taskState of the swarm map (section 4.3.1)."""

    INIT = 0
    FORM = 1
    FLOW = 2
    LEAD = 3
    STOP = 4


class LeaderLogic:
    """The leader's side of the workflow (Fig. 4.1-4.4): wait, fly the path, stop.

    Phases: ``home`` (LEAD, holding home until its followers are in FLOW), ``path`` (LEAD,
    flying; the reference stops while it waits), ``stop`` (STOP, T_end for the followers to
    stop), ``done`` (holds; the mission manager's turn). ``aborted``: no follower within T_led.
    """

    def __init__(self, home: np.ndarray, waypoints: np.ndarray, params: WorkflowParameters,
                 threshold: float, n: int, leader: int, T_s: float) -> None:
        self.p, self.th, self.L, self.T_s = params, threshold, leader, T_s
        self.waiting = True
        self.path = WaypointPath(np.vstack([home, home + waypoints]), params.leader_speed)
        self.home = np.asarray(home, dtype=float)
        self.others = np.arange(n) != leader
        self.phase = "home"
        self.s = 0.0  # time along the path reference (advances only while not waiting)
        self.visited = np.zeros(len(waypoints), dtype=bool)
        self.expected = np.zeros(n, dtype=bool)
        self.ignored = np.zeros(n, dtype=bool)
        self.ignored_at: list[tuple[float, list[int]]] = []
        self.form_since: float | None = None
        self.del_since: float | None = None
        self.W = np.zeros(n, dtype=bool)
        self.rel0 = np.zeros((n, 3))
        self.delta = np.zeros(3)
        self.formed_at: float | None = None
        self.departed_at: float | None = None
        self.path_done_at: float | None = None
        self.done_at: float | None = None
        self.aborted = False
        self.ref = self.home.copy()

    @property
    def following(self) -> bool:
        """The following sequence: the leader is on its path."""
        return self.phase == "path"

    def _ignore(self, agents: np.ndarray, t: float) -> None:
        self.ignored[agents] = True
        self.ignored_at.append((float(t), [int(a) for a in agents]))

    def _catch_up(self, world: WorldState, m: SwarmMap, flow: np.ndarray) -> bool:
        """Eq. 4.1-4.2 on W = ``flow`` (see the module docstring for the reading of 4.1)."""
        t, p = world.t, self.p
        rel = m.positions(self.L, slice(None)) - world.pos[self.L]
        if not flow.any():
            self.W[:] = False
            self.del_since = None
            return True
        if not np.array_equal(flow, self.W):  # a new set W: new reference k_0
            self.W, self.rel0, self.delta = flow.copy(), rel.copy(), np.zeros(3)
        eps, eps0 = rel[flow].mean(axis=0), self.rel0[flow].mean(axis=0)
        self.delta = 0.5 * (self.delta + eps - eps0)
        if np.linalg.norm(self.delta) < self.th:
            self.del_since = None
            return True
        if self.del_since is None:
            self.del_since = t
        elif t - self.del_since >= p.T_del:
            ids = np.flatnonzero(flow)
            lag = np.linalg.norm(rel[ids] - self.rel0[ids], axis=1)
            bad = ids[lag >= self.th] if (lag >= self.th).any() else ids[[lag.argmax()]]
            self._ignore(bad, t)
            self.del_since = None
        return False

    def _wait_for_flow(self, t: float, not_flow: np.ndarray) -> bool:
        """T_for: followers not in FLOW are waited for, then ignored."""
        if not not_flow.any():
            self.form_since = None
            return False
        if self.form_since is None:
            self.form_since = t
        elif t - self.form_since >= self.p.T_for:
            self._ignore(np.flatnonzero(not_flow), t)
            self.form_since = None
        return True

    def update(self, world: WorldState, present: np.ndarray, m: SwarmMap, task: np.ndarray,
               sp: Setpoints) -> None:
        """Advance the leader's workflow one tick and write its setpoint into ``sp``."""
        L, p, t = self.L, self.p, world.t
        if not world.healthy[L]:
            return
        row, st = present[L], m.state[L]
        if self.phase in ("home", "path"):
            self.expected |= row & self.others & (st != Task.LEAD)
            if self.phase == "home" and not self.expected.any():
                if t >= p.T_led:  # nobody answered: abort the swarming mission
                    self.phase, self.aborted, task[L] = "done", True, Task.STOP
            else:
                active = self.expected & ~self.ignored
                flow = active & row & (st == Task.FLOW)
                waiting = self._wait_for_flow(t, active & ~flow)
                self.waiting = (not self._catch_up(world, m, flow)) or waiting
                if self.phase == "home" and not self.waiting:
                    self.phase, self.formed_at, self.departed_at = "path", t, t
        vel = np.zeros(3)
        if self.phase == "path":
            if not self.waiting:
                self.s += self.T_s
                self.ref, vel, _, _ = self.path.at(self.s)
            else:  # waiting: the reference stops (velocity limiter set to zero)
                self.ref = self.path.at(self.s)[0]
            self._visit(world.pos[L])
            if self.visited.all():
                self.phase, self.path_done_at, task[L] = "stop", t, Task.STOP
        elif self.phase == "stop":
            active = self.expected & ~self.ignored
            stopped = active & row & (st == Task.STOP)
            assert self.path_done_at is not None  # set on entering "stop"
            if np.array_equal(stopped, active) or t - self.path_done_at >= p.T_end:
                self.phase, self.done_at = "done", t
        sp.mode[L] = Mode.TRACK
        sp.pos[L], sp.vel[L], sp.acc[L] = self.ref, vel, 0.0

    def _visit(self, pos: np.ndarray) -> None:
        """Waypoints in order: visited once the reference has reached it and the leader is within eps_r."""
        cum = self.path.cumulative
        for w in np.flatnonzero(~self.visited):
            reached = self.s * self.path.speed >= cum[w + 1] - 1e-9
            if not (reached and np.linalg.norm(pos - self.path.points[w + 1]) < self.p.eps_r):
                return
            self.visited[w] = True



class MissionWorkflow:
    """Every agent's side of the workflow for one swarm (section 4.3.1), as arrays over agents.

    Args:
        home: (N, 3) initial positions, m: each follower's home, the leader's path start.
        leader: index of the leader.
        T_s: guidance period, s (one message per agent per tick).
        params: the workflow's parameters (Table 4.3).
        comm_range: d_com, m: the range of one communication hop.
        link_delay: the engine's per-link delay model in ticks (``None``: hops x tau_com).
        link_loss: ``link_loss(world, sensing) -> (N, N) bool`` messages lost this tick, or ``None``.
    """

    def __init__(self, home: np.ndarray, leader: int, T_s: float, params: WorkflowParameters,
                 comm_range: float, link_delay: Callable[[np.ndarray], np.ndarray] | None = None,
                 link_loss: Callable[[WorldState, Any], np.ndarray] | None = None) -> None:
        p = params
        n = len(home)
        self.p, self.comm_range, self.link_loss = p, comm_range, link_loss
        self.n, self.L, self.T_s = n, leader, T_s
        self.home = np.array(home, dtype=float)
        self.pattern = hex_pattern(n, p.d_r, np.deg2rad(p.alpha_deg))
        self.edges = np.array(formation_graph(self.pattern).edges(), dtype=int).reshape(-1, 2)
        self.map = SwarmMap(n, self.T_s, p.tau_com, p.T_msg, self_hops=p.self_hops,
                            link_delay=link_delay)
        self.task = np.full(n, Task.INIT, dtype=np.int8)
        self.task[leader] = Task.LEAD
        self.is_follower = np.arange(n) != leader
        self.slot = np.full(n, -1)
        self.leader_of = np.full(n, -1)
        self.home_done = np.zeros(n, dtype=bool)
        self.last_change = np.zeros(n)
        self.last_lead_seen = np.zeros(n)
        self._prev_present = np.zeros((n, n), dtype=bool)
        self._others = ~np.eye(n, dtype=bool)
        self._cache: dict[int, np.ndarray] = {}
        self._hops: np.ndarray | None = None
        self._one_hop = False
        self._members: np.ndarray | None = None
        self._hash_w = np.random.default_rng(12345).integers(1, 2**62, size=4 * n + 3)
        th = p.catchup_threshold if p.catchup_threshold is not None else p.d_r / 2
        self.leader = LeaderLogic(self.home[leader], np.asarray(p.waypoints, dtype=float), p, th,
                                  n, leader, self.T_s)
        self.k = 0
        self.stats: dict[str, Any] = {
            "neighbour_mean": [], "neighbour_min": np.inf, "neighbour_max": 0.0, "tracking": [],
            "solves": 0, "flow_at": np.full(n, np.nan), "home_at": np.full(n, np.nan)}

    # -- communication ------------------------------------------------------------------------

    def _communicate(self, world: WorldState, sensing: Sensing | None) -> np.ndarray:
        """Broadcast, relay over the hops of this tick's graph, deliver: who is in each map."""
        members = world.healthy & world.comm_ok
        u = world.acc if world.acc is not None else np.zeros_like(world.pos)
        self.map.broadcast(self.k, world.healthy, self.task, world.pos, world.vel, u)
        d_com = self.comm_range
        box = world.pos[members].max(axis=0) - world.pos[members].min(axis=0) if members.any() else 0
        one_hop = bool(np.linalg.norm(box) <= d_com)  # everyone in range of everyone
        hops = self._hops
        same = self._members is not None and np.array_equal(members, self._members)
        if hops is None or not (one_hop and self._one_hop and same):
            tree = sensing.tree if sensing is not None else None
            hops = self._hops = hop_matrix(world.pos, members, d_com, tree)
        self._one_hop, self._members = one_hop, members
        lost = self.link_loss(world, sensing) if self.link_loss is not None else None
        return self.map.deliver(hops, lost)

    # -- assignment (eq. 4.12-4.13) on each agent's map ------------------------------------------

    def _assign(self, rows: np.ndarray, present: np.ndarray) -> None:
        """Slot of every FORM follower in ``rows``, from its own map (cached per identical view)."""
        m = self.map
        lead = self.leader_of[rows]
        states = m.state[rows]
        view = present[rows] & (states != Task.LEAD) & (states != Task.STOP)
        view[np.arange(rows.size), lead] = False
        # Maps holding the same messages are the same view: group rows by their stamps first,
        # then key each distinct view on its decimetre-rounded content (hits across ticks too).
        same = np.concatenate([view * (1 + states), m.stamp[rows], lead[:, None]], axis=1)
        groups = same @ self._hash_w[: 2 * self.n + 1]
        for group in np.unique(groups):
            at = np.flatnonzero(groups == group)
            r, v, lr = rows[at[0]], view[at[0]], lead[at[0]]
            pos = m.positions(r, slice(None))
            dm = np.rint(pos * 10).astype(np.int64) * v[:, None]
            key = int(np.concatenate([v * (1 + states[at[0]]), dm.ravel(),
                                      np.rint(pos[lr] * 10).astype(np.int64)]) @ self._hash_w)
            slots = self._cache.get(key)
            if slots is None:
                slots = self._solve(v, states[at[0]] == Task.FLOW, pos, pos[lr])
                self._cache[key] = slots
            self.slot[rows[at]] = np.where(slots[rows[at]] >= 0, slots[rows[at]], self.slot[rows[at]])
        if len(self._cache) > 512:
            self._cache.clear()

    def _solve(self, view: np.ndarray, flow: np.ndarray, pos: np.ndarray,
               leader_pos: np.ndarray) -> np.ndarray:
        """Eq. 4.12-4.13 on one map: FLOW followers keep the slot they are on (they no longer
        re-assign), the others share the remaining slots. Returns the slot of every agent (-1)."""
        self.stats["solves"] += 1
        out = np.full(self.n, -1)
        flowing = np.flatnonzero(view & flow)
        if flowing.size:
            rel = scipy.spatial.distance.cdist(pos[flowing, :2] - leader_pos[:2], self.pattern.offsets_xy)
            out[flowing] = rel.argmin(axis=1)
        free = np.setdiff1d(np.arange(self.pattern.m), out[flowing])
        ids = np.flatnonzero(view & ~flow)  # ascending ids: the thesis' deterministic order
        if ids.size and ids.size <= free.size:
            cost = assignment_cost(self.pattern, pos[ids], leader_pos)[:, free]
            penalty = np.rint(self.pattern.periphery_penalty[free] / DECIMETRE)
            out[ids] = free[solve_assignment(cost, penalty)]
        elif ids.size:  # more followers than free slots (a stale map): plain assignment
            out[ids] = assign_offsets(self.pattern, ids, pos[ids], leader_pos)
        return out

    # -- the tick -----------------------------------------------------------------------------

    def setpoints(self, world: WorldState, sensing: Sensing | None) -> Setpoints:
        """Every agent's setpoint for this tick (Fig. 4.1-4.4): communicate, update the states,
        assign (FORM), navigate (eq. 4.21-4.28) or track the slot (FLOW), then the leader."""
        p, m, t = self.p, self.map, world.t
        present = self._communicate(world, sensing)
        self.k += 1
        n, alive = self.n, world.healthy
        changed = (present != self._prev_present).any(axis=1)
        self.last_change[changed] = t
        self._prev_present = present.copy()

        lead_here = present & (m.state == Task.LEAD)
        lead_any = lead_here.any(axis=1)
        stop_any = (present & self._others & (m.state == Task.STOP)).any(axis=1)
        self.last_lead_seen[lead_any] = t
        f = self.is_follower & alive
        task = self.task

        # Stop triggers (Fig. 4.1/4.3): no LEAD and one STOP; or no leader for T_fol.
        running = f & (task <= Task.FLOW)  # INIT, FORM or FLOW
        lost = (t - self.last_lead_seen >= p.T_fol) & ~lead_any
        task[running & ((~lead_any & stop_any) | lost)] = Task.STOP
        # INIT -> FORM once the map is stable for T_ini and shows a leader.
        init = f & (task == Task.INIT) & (t - self.last_change >= p.T_ini) & lead_any
        self.leader_of[init] = lead_here[init].argmax(axis=1)
        task[init] = Task.FORM

        form = np.flatnonzero(f & (task == Task.FORM))
        if form.size:
            self._assign(form, present)
        rows = np.arange(n)
        lid = np.where(self.leader_of >= 0, self.leader_of, self.L)
        lead_kin = m.kin(rows, lid)
        lead_pos, lead_vel, lead_u = lead_kin[:, 0:3], lead_kin[:, 3:6], lead_kin[:, 6:9]
        targets = self.home.copy()
        placed = f & ((task == Task.FORM) | (task == Task.FLOW)) & (self.slot >= 0)
        targets[placed, :2] = lead_pos[placed, :2] + self.pattern.offsets_xy[self.slot[placed]]
        targets[placed, 2] = lead_pos[placed, 2]

        # APF navigation (eq. 4.21-4.28) for FORM agents and STOP agents on their way home.
        navigating = f & (placed & (task == Task.FORM) | (task == Task.STOP) & ~self.home_done)
        arrived = arrived_on_target(world.pos, targets, p.eps_r)
        to_flow = navigating & (task == Task.FORM) & arrived
        task[to_flow] = Task.FLOW
        self.stats["flow_at"][to_flow & np.isnan(self.stats["flow_at"])] = t
        home_now = navigating & (task == Task.STOP) & arrived
        self.home_done |= home_now
        self.stats["home_at"][home_now] = t
        navigating &= ~arrived

        sp = Setpoints.hold(world.pos)
        # Tracker on the slot (FLOW, and FORM near it) with the leader's mapped state as feed-forward.
        fed = f & placed
        sp.mode[f] = Mode.TRACK
        sp.pos[f] = targets[f]
        sp.vel[fed], sp.acc[fed] = lead_vel[fed], lead_u[fed]
        self._navigate(world, sensing, present, targets, navigating, sp)
        self.leader.update(world, present, m, self.task, sp)
        self._measure(world)
        return sp

    def _navigate(self, world: WorldState, sensing: Sensing | None, present: np.ndarray,
                  targets: np.ndarray, navigating: np.ndarray, sp: Setpoints) -> None:
        """APF navigation (eq. 4.21-4.27) of the agents still farther than d_c from their target."""
        p = self.p
        far = navigating & ~close_to_target(world.pos, targets, p.d_c)
        if not far.any():
            return
        radius = p.d_c * np.hypot(2.0, LEVEL_BAND) + 1.0  # + staleness of mapped positions
        pairs = (sensing.pairs(radius) if sensing is not None
                 else np.array([(a, b) for a in range(self.n) for b in range(a + 1, self.n)]))
        v = map_repulsion(world.pos, self.map, present, pairs, far, p.d_c, p.v_sat)
        v = saturate(v + attraction_velocity(world.pos, targets, p.d_c, p.v_sat), p.v_sat)
        z_ref = flight_level_altitude(targets[:, 2], p.d_c, p.level_offset)
        vz = np.clip(p.altitude_gain * (z_ref - world.pos[:, 2]), -p.v_sat, p.v_sat)
        sp.mode[far] = Mode.VELOCITY
        sp.vel[far, :2], sp.vel[far, 2] = v[far], vz[far]
        sp.acc[far] = 0.0
        sp.pos[far] = world.pos[far]

    # -- measurements (section 4.5.3, Fig. 4.21-4.24) -------------------------------------------

    def _measure(self, world: WorldState) -> None:
        """Neighbour distances over formation-graph edges and tracking error while following."""
        if not self.leader.following:
            return
        flow = np.flatnonzero(self.is_follower & world.healthy & (self.task == Task.FLOW)
                              & (self.slot >= 0))
        if flow.size == 0:
            return
        holder = np.full(self.pattern.m + 1, -1)
        holder[0] = self.L
        holder[self.slot[flow] + 1] = flow
        a, b = holder[self.edges[:, 0]], holder[self.edges[:, 1]]
        ok = (a >= 0) & (b >= 0)
        if ok.any():
            d = np.linalg.norm(world.pos[a[ok]] - world.pos[b[ok]], axis=1)
            self.stats["neighbour_mean"].append(d.mean())
            self.stats["neighbour_min"] = min(self.stats["neighbour_min"], d.min())
            self.stats["neighbour_max"] = max(self.stats["neighbour_max"], d.max())
        slot_pos = world.pos[self.L] + np.c_[self.pattern.offsets_xy[self.slot[flow]], np.zeros(flow.size)]
        self.stats["tracking"].append(np.linalg.norm(world.pos[flow] - slot_pos, axis=1).mean())

    def followers_home(self, world: WorldState) -> bool:
        """Every healthy follower has run its stop sequence and is home."""
        f = self.is_follower & world.healthy
        return bool(np.all(self.home_done[f]))

    def complete(self, world: WorldState) -> bool:
        """Formation reached, every waypoint visited, leader done and every healthy follower home."""
        lead = self.leader
        return bool(lead.formed_at is not None and lead.done_at is not None and not lead.aborted
                    and self.followers_home(world))
