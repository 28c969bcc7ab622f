"""Indoor swarm formation: a leader drags the swarm along a path through corridors (thesis ch. 5).

Karydes (2020), sections 5.2-5.4. Every tick the swarm senses its neighbours with range and line of
sight (G_n), drops edges by the two deactivation rules (G_sigma), each follower moves by the
connectivity, compactness and leader-traction terms

    w_i = w_con + w_com + w_led          (eq. 5.37-5.42; rank estimate eq. 5.26, virtual leader 5.24)

and the leader (``swarm.leader``) follows the way-points by Algorithm 1 with the bounds u_lsat,
u_lcon (eq. 5.43-5.44). The obstacle and collision terms w_obs + w_col and the saturation at u_sat
(eq. 5.30) belong to the avoidance plugin ``potential_barrier``: the kernel composes the two, so
either can be swapped. With another avoidance method set ``saturate: true`` here.

Units: the thesis' inputs are displacements per sampling period T_s (Table 5.1 gains in m per step);
a setpoint velocity is w / T_s with T_s = ``clock.guidance_period``. The swarm is planar (world x-y);
altitudes are held. Failed agents hold still and stay in the graphs.

Checked against sections 5.2-5.4 (the Fig. 5.13 gap of issue 6): every term of eq. 5.30-5.44 has
the thesis' sign, range and Table 5.1 value (psi_con attracts, see the notes with the source text);
no term is missing (w = w_obs + w_col + w_con + w_com + w_led over G_sigma); Algorithm 1 runs on
the corridor's centreline resampled every 0.25 m, so the leader cuts the L's corner by 0.03 m (it
passes 0.32 m from the inner corner of the 0.7 m corridor, 0.35 m on the centreline); u_lcon
(eq. 5.43) bounds the leader by its *nearest* G_sigma neighbour only, as written, so the leader
does not wait for a swarm stretched behind that neighbour. Collision avoidance between agents
needs line of sight, as in the thesis: w_col sums over N_i(G_sigma) (eq. 5.35), and G_sigma is in
G_s, whose edges need the joining segment d_l clear of walls (eq. 5.8).
Edge deactivation (eq. 5.15-5.16) takes the candidates m in N_i(G_n) as printed, the edge off
when either end's rule fires (``deactivation_candidates: neighbours``, the default); ``common``
(N_i ∩ N_j, the reading shipped before issue 17, which keeps G_n's components) and ``directed``
are the alternatives, with their reasons in methods/indoor/graphs.py.
What remains is the limitation the thesis states (no LOS maintenance, section 5.3.3); the
``indoor.disconnect.*`` metrics classify each split (benchmarks/reproduction/sweep_indoor.py). Measured with
30 seeds per width, literal reading (docs/indoor_fidelity.md, every reading): straight
0 / 0 / 93.3 / 100 / 100 % and L 0 / 0 / 90.0 / 83.3 / 100 % for w = 0.5 ... 0.9 m (``common``:
0.7-0.8 m 90 / 96.7 % and 86.7 / 73.3 %).
In the L the failures at 0.7 m are a link stretched past d_n at the corridor mouth while the
entrance jam holds the tail (a tug of war: with all inputs saturated at u_sat both ends of a link
can move apart by 2 u_sat = 0.04 m in one step, more than the width of the barrier of eq. 5.38);
at 0.8 m, the width that lets the file run two abreast, they are one configuration: the
compactness and collision repulsion of an abreast neighbour holds the second-last agent 0.2 m
from the north leg's inner wall and the tail's single link to it passes the inner corner under
d_l, after which the tail, without neighbours, stops (docs/indoor_fidelity.md, section 3). Safety
(eq. 5.2-5.3) breaks only in failed runs at 0.5-0.6 m: the leader, which has no avoidance term
(eq. 5.44), drives a follower into the pocket beyond the L's turn, too small below w = 0.624 m to
keep both d_c from the leader's corner way-point and d_o from the walls (section 4 there).
Giving the leader the avoidance terms (``avoidance.exempt_leader=false``, not in eq. 5.44) made
the L worse (63 / 50 % at 0.7 / 0.8 m with the ``common`` reading, docs/benchmarks.md).
The straight corridor's failures at 0.7 m are splits at the entrance and, in the ``common``
reading, deadlocks (G_n connected, a few agents pinned in the corners beside the corridor mouth
by the compactness repulsion, K_com = 0.1 m per step being 5 u_sat).

Metrics (``metrics.json``, keys ``indoor.*``):
    indoor.arrived: every agent in the end region at the end of the run.
    indoor.connected: G_n connected at every tick (max rank < N, the thesis' criterion).
    indoor.initial_connected: G_n connected at t = 0 (a "random eligible" initial state).
    indoor.max_rank: largest rank rho_i (eq. 5.23) over the run (N means an agent was cut off).
    indoor.mean_neighbours: mean |N_i(G_n)| over agents and ticks; ``indoor.mean_neighbours_sigma``
        the same on G_sigma (Fig. 5.17).
    indoor.disconnect.*: where G_n first split (diagnostics, absent when it never did): ``t`` (s),
        ``lost_agents`` (cut off from the leader), ``links`` (edges of the last tick across the
        cut), ``link_length`` and ``link_clearance`` (m, of the cut edge nearest an obstacle: a
        clearance below d_l is a wall breaking line of sight, a length above d_n a link stretched
        out of range), ``link_mid_x``, ``link_mid_y`` (its midpoint, m) and ``leader_done`` (the leader had
        reached its last way-point).
    indoor.success: arrived and connected throughout, no collision (eq. 5.2 with
        ``safety.separation_limit`` = d_c) and no clearance violation (eq. 5.3 with
        ``safety.clearance_limit`` = d_o); also written as ``success``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import shapely
from pydantic import Field
from shapely.geometry import Polygon

from swarmscene.methods.indoor.control import TABLE_5_1, IndoorGains, IndoorSnapshot, formation_step
from swarmscene.methods.indoor.graphs import initial_rank_estimate, mean_degree
from swarmscene.methods.indoor.graphs import max_rank as max_rank_of
from swarmscene.methods.indoor.maps import resample_path
from swarmscene.methods.indoor.sensing import saturate
from swarmscene.methods.indoor.shared import GraphParams, shared_snapshot
from swarmscene.plugin import BuildContext, Formation, Mode, Setpoints, WorldState, hookimpl

Point2 = tuple[float, float]
_VELOCITY = int(Mode.VELOCITY)

class IndoorSwarm(Formation):
    """Leader-follower swarm with LOS sensing, edge deactivation and ranks (thesis ch. 5)."""

    name = "indoor_swarm"
    metric_prefix = "indoor"
    requires_leader = True

    class Params(GraphParams):
        waypoints: list[Point2] = Field(min_length=2, description="leader path vertices [x, y], m")
        waypoint_spacing: float = Field(
            0.25, ge=1e-3, description="the path is resampled every this many m (Algorithm 1 cuts "
            "corners); at least 1 mm"
        )
        end_region: list[Point2] = Field(min_length=3, description="polygon every agent must reach")
        d_c: float = Field(TABLE_5_1.d_c, gt=0, description="collision-free distance d_c, m")
        l_n: float = Field(TABLE_5_1.l_n, gt=0, description="connectivity range l_n, m")
        K_con: float = Field(TABLE_5_1.K_con, gt=0, description="connectivity gain, m per step")
        eps_con: float = Field(TABLE_5_1.eps_con, gt=0, description="connectivity slope")
        K_com: float = Field(TABLE_5_1.K_com, gt=0, description="compactness gain, m per step")
        alpha_com: float = Field(TABLE_5_1.alpha_com, gt=0, lt=1, description="compactness level")
        K_led: float = Field(TABLE_5_1.K_led, gt=0, description="leader traction gain, per step")
        u_sat: float = Field(TABLE_5_1.u_sat, gt=0, description="input saturation, m per step")
        alpha_lsat: float = Field(TABLE_5_1.alpha_lsat, gt=0, lt=1, description="leader saturation level")
        alpha_lcon: float = Field(TABLE_5_1.alpha_lcon, gt=0, lt=1, description="leader connectivity level")
        saturate: bool = Field(
            False, description="saturate followers at u_sat here (when the avoidance does not)"
        )

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        leader = ctx.initial.leader
        assert leader is not None  # requires_leader: validation checked it
        self.leader = leader
        fields = IndoorGains.__dataclass_fields__
        self.gains = replace(
            TABLE_5_1, T_s=ctx.guidance_period, **{k: v for k, v in params if k in fields}
        )
        self.waypoints = resample_path(np.asarray(params.waypoints, dtype=float), params.waypoint_spacing)
        self.end_region = Polygon(params.end_region)
        shapely.prepare(self.end_region)
        self.rho_bar = initial_rank_estimate(ctx.n, leader)
        self.m = 0
        self.snapshot: IndoorSnapshot | None = None
        self._max_rank = 0
        self._connected = True
        self._initial_connected: bool | None = None
        self._degree_sum = [0.0, 0.0]  # sums of mean |N_i(G_n)| and |N_i(G_sigma)| over ticks
        self._ticks = 0
        self._prev: IndoorSnapshot | None = None
        self._cut: dict[str, Any] = {}
        # The compiled kernels (numba) load here, not when the plugin registers (start-up).
        from swarmscene.methods.indoor import kernels  # noqa: F401

    def setpoints(self, world: WorldState, sensing: Any) -> Setpoints:
        """The followers' input w_i (eq. 5.24-5.26, 5.37-5.42) and the leader's (Algorithm 1), as velocities."""
        g, T = self.gains, self.gains.T_s
        snap = self.snapshot = shared_snapshot(sensing, g)
        # w_con + w_com + w_led, the leader's input in its row, and the rank step: one kernel call.
        w, self.m, self.rho_bar = formation_step(snap, self.rho_bar, self.leader, self.waypoints, self.m, g)
        if self.params.saturate:  # the leader's row is below u_lsat < u_sat: left unchanged
            w = saturate(w, g.u_sat)
        self._observe(snap, world.t, sensing.environment.tree)
        sp = Setpoints.hold(world.pos)
        moving = world.healthy
        if moving.all():  # the usual case: whole slices (masks and enum casts cost more than the step)
            sp.mode[:] = _VELOCITY
            sp.vel[:, :2] = w / T
        else:
            sp.mode[moving] = _VELOCITY
            sp.vel[moving, :2] = w[moving] / T
        return sp

    def _observe(self, snap: IndoorSnapshot, t: float, obstacles: Any) -> None:
        """Ranks and neighbour counts of this tick's graphs (measured, for the metrics)."""
        max_rank, reached = max_rank_of(snap.g_n, self.leader)
        if self._initial_connected is None:
            self._initial_connected = max_rank < self.ctx.n
        elif max_rank >= self.ctx.n and self._connected and self._prev is not None:
            self._cut = _cut_links(self._prev, snap, ~reached, obstacles, t)
            self._cut["leader_done"] = self.m == len(self.waypoints) - 1
        self._max_rank = max(self._max_rank, max_rank)
        self._connected &= max_rank < self.ctx.n
        self._degree_sum[0] += mean_degree(snap.g_n)
        self._degree_sum[1] += mean_degree(snap.g_sigma)
        self._ticks += 1
        self._prev = snap

    def arrived(self, world: WorldState) -> np.ndarray:
        """(N,) bool: agents inside the end region."""
        return shapely.contains_xy(self.end_region, world.pos[:, 0], world.pos[:, 1])

    def complete(self, world: WorldState) -> bool:
        """Every healthy agent is inside the end region."""
        return bool(self.arrived(world)[world.healthy].all())

    @hookimpl(trylast=True)
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """``indoor.*`` metrics: arrival, connectivity, max rank, mean |N_i|, the first split, success."""
        arrived = bool(self.arrived(sim.world).all())
        ticks = max(self._ticks, 1)
        metrics["indoor.arrived"] = arrived
        metrics["indoor.connected"] = self._connected
        metrics["indoor.initial_connected"] = bool(self._initial_connected)
        metrics["indoor.max_rank"] = self._max_rank
        metrics["indoor.mean_neighbours"] = float(self._degree_sum[0] / ticks)
        metrics["indoor.mean_neighbours_sigma"] = float(self._degree_sum[1] / ticks)
        for key, value in self._cut.items():
            metrics[f"indoor.disconnect.{key}"] = value
        safe = metrics.get("collisions", 0) == 0 and metrics.get("clearance_violations", 0) == 0
        metrics["indoor.success"] = bool(arrived and self._connected and safe)
        metrics["success"] = metrics["indoor.success"]


def _cut_links(
    prev: IndoorSnapshot, now: IndoorSnapshot, lost: np.ndarray, obstacles: Any, t: float
) -> dict[str, Any]:
    """How G_n split at time ``t``: the last tick's edges between the cut-off agents and the rest.

    For each such edge, its length now and the clearance of its segment from the obstacles now:
    a clearance below d_l is a line of sight broken by a wall (eq. 5.8), a length above d_n a link
    stretched out of range (eq. 5.12). Reported for the first split only (diagnostics).
    """
    cross = lost[prev.g_n.i] != lost[prev.g_n.j]
    i, j = prev.g_n.i[cross], prev.g_n.j[cross]
    length = np.linalg.norm(now.r[j] - now.r[i], axis=1)
    clearance = np.full(len(i), np.inf)
    if obstacles is not None and len(i):
        seg = shapely.linestrings(np.stack([now.r[i], now.r[j]], axis=1))
        (which, _), dist = obstacles.query_nearest(seg, return_distance=True, all_matches=False)
        clearance[which] = dist
    k = int(np.argmin(clearance)) if len(i) else 0
    mid = (now.r[i[k]] + now.r[j[k]]) / 2 if len(i) else np.full(2, np.nan)
    return {
        "t": float(t),
        "lost_agents": int(lost.sum()),
        "links": len(i),
        "link_length": float(length[k]) if len(i) else float("nan"),
        "link_clearance": float(clearance[k]) if len(i) else float("nan"),
        "link_mid_x": float(mid[0]),
        "link_mid_y": float(mid[1]),
    }


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Register ``indoor_swarm``."""
    register(IndoorSwarm)
