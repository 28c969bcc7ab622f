"""ORCA: Optimal Reciprocal Collision Avoidance (van den Berg, Guy, Lin, Manocha 2011), planar.

Every guidance tick each healthy agent A replaces its setpoint by a velocity command:

1. v_A^pref from the formation's setpoint (``methods.baselines.common.preferred_velocity``):
   VELOCITY: ``sp.vel``; POSITION/TRACK: ``sp.vel + gain (sp.pos - p)``; HOLD: ``gain (sp.pos - p)``;
   clipped to ``v_max``.
2. One half-plane ORCA^tau_{A|B} = {v : (v - (v_A + u/2)) . n >= 0} (eq. 4) per neighbour B among
   the ``max_neighbours`` nearest within ``neighbour_dist`` (the tick's shared k-d tree pairs), from
   the truncated velocity obstacle VO^tau_{A|B} with combined radius r_A + r_B =
   ``safety.separation_limit + margin`` (eq. 2-3). A failed vehicle does not avoid: it is a static
   neighbour (velocity 0) and A takes all of u (responsibility 1).
3. The environment's nearest obstacle point within reach gives one hard half-plane,
   {v : v . n >= -(c - c_s)/tau_obst} (c its clearance, c_s = ``safety.clearance_limit + margin``).
4. v_A^new = the velocity of the disc |v| <= ``v_max`` closest to v_A^pref within every half-plane
   (eq. 5), by RVO2's linear programs for all agents in lock-step; if none exists, the velocity of
   least penetration with the obstacle half-plane kept hard (section 5.3).

Output: healthy agents get ``Mode.VELOCITY`` with ``vel = (v_new_x, v_new_y, v_pref_z)`` and zero
acceleration feed-forward; failed agents' setpoints are passed through untouched; the input
setpoints are never modified (a copy is returned). ``pos`` keeps the formation's reference (unused
in VELOCITY mode, useful for plots).

Dynamics: single_integrator flies the command exactly (ORCA's own model). double_integrator and
quadrotor track it through their velocity loops with a lag; ``margin`` absorbs it and v_A is the
measured velocity, so the next tick corrects. Keep ``v_max`` at or below the dynamics' own speed
limit (single_integrator.u_max), else the plant clips commands the LP chose inside the disc.

Choices where the paper leaves room:
- planar: velocity obstacles, the disc and the LP are in x-y (the swarm flies at one altitude in
  the scenarios that use it); the z command is v_pref_z. Distances in x-y ignore altitude
  differences, which is conservative (agents are treated as infinite vertical cylinders).
- neighbours: RVO2's rule (the nearest ``max_neighbours`` within ``neighbour_dist``, nearest first);
  ``neighbour_dist`` null means 2 v_max tau + r_A + r_B, beyond which no relative velocity in reach
  can enter VO^tau.
- agents already closer than r_A + r_B use the cut-off disc of one guidance period (RVO2).
- obstacles: the nearest point's tangent half-plane instead of RVO2's polygon-edge obstacles.
- deadlocks (a deliberate deviation, measured in docs/benchmarks.md): in a perfectly symmetric
  swap ORCA settles into a ring of agents pressed together round the centre, and a random
  perturbation of v_pref (RVO2's examples; ``perturbation``, from the run's seeded generator) does
  not break it from N = 16 on. An agent whose v_pref lies outside one of its half-planes therefore
  has it turned ``detour`` degrees clockwise (the right-hand rule): the crowd circulates round the
  centre like a roundabout and leaves it. Only the objective of eq. 5 changes, not the half-planes.
  The default ``detour=0`` is the paper's ORCA; the ``swap`` preset's tuning
  (scenarios/tuning/avoidance/swap/orca.yaml) sets 30 degrees.

Metrics: ``orca.fallback_ticks`` (agent-ticks where the half-planes were infeasible and the
section 5.3 fallback ran), ``orca.max_neighbours_used``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.methods.baselines.common import (
    VelocityFilterParams,
    filtered_setpoints,
    filtered_world,
    nearest_obstacles,
    perturb,
    perturb_rows,
    preferred_velocity,
    stacked_setpoints,
)
from swarmscene.methods.baselines.neighbours import neighbour_table
from swarmscene.methods.baselines.orca import new_velocities, obstacle_lines
from swarmscene.plugin import Avoidance, BuildContext, Setpoints, hookimpl

_Rows = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""The per-agent rows of :func:`new_velocities`: positions, velocities, v_pref, neighbours, valid, static."""


class Orca(Avoidance):
    """Optimal Reciprocal Collision Avoidance (planar), all agents' linear programs in lock-step."""

    name = "orca"

    class Params(VelocityFilterParams):
        time_horizon: float = Field(
            3.0, gt=0, le=1000.0, description="tau, s: velocity obstacles are truncated at this horizon "
            "(eq. 2); at most 1000 s")
        time_horizon_obstacle: float = Field(
            1.0, gt=0, le=1000.0, description="tau_obst, s: horizon of the obstacle half-plane; at most 1000 s")
        max_neighbours: int = Field(
            10, ge=1, le=1_000_000, description="neighbours considered per agent, nearest first (RVO2 "
            "maxNeighbors); at most 10^6")
        neighbour_dist: float | None = Field(
            None, gt=0, le=1e6, description="neighbour range, m; null: 2 v_max tau + r_A + r_B")

    params: Params

    def __init__(self, params: Orca.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        self.combined_radius = ctx.separation_limit + params.margin
        self.range = (params.neighbour_dist if params.neighbour_dist is not None
                      else 2.0 * params.v_max * params.time_horizon + self.combined_radius)
        self.obstacle_limit = ctx.clearance_limit + params.margin
        # an obstacle plane cannot cut the speed disc from farther than this
        self.obstacle_reach = self.obstacle_limit + params.v_max * params.time_horizon_obstacle
        self.fallback_ticks = 0
        self.max_used = 0

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        """Each agent's velocity nearest its preferred one inside the ORCA half-planes of its
        neighbours (reciprocal: each takes half of the avoidance); failed agents count as static."""
        v_pref, rows, hard = self._rows(world, sensing, sp)
        v_new, feasible = new_velocities(*rows, *self._constants(), hard, np.radians(self.params.detour))
        return filtered_world(self, world, sp, np.column_stack([v_new, v_pref[:, 2]]), rows[4], feasible)

    @classmethod
    def adjust_batch(cls, avoidances, worlds, sensings, setpoints):
        """``adjust`` of B worlds with one pass of ORCA's numerics. The worlds' agents are stacked
        as rows: the preferred velocities and the neighbour tables are made for all of them at
        once (each world's pairs shifted to its rows, so an agent's partners stay in its world),
        the perturbation with each world's own stream and the obstacle half-planes from each
        world's sensing, then every row goes through :func:`new_velocities`. All of it is row by
        row (masked lock-step loops, elementwise operations and square roots; the neighbour order
        a sort within each agent), so every world gets its own ``adjust``'s bits (the contract
        check ``avoidance.adjust_batch_equals_worlds``). The answer (:func:`filtered_setpoints`) is
        one :class:`SetpointBatch` where it was handed one, else a record per world. Declined
        (``NotImplemented``, before any world is touched) for instances whose options differ, or
        worlds with and without obstacles."""
        first = avoidances[0]
        if any(a.params != first.params or a._constants() != first._constants() for a in avoidances[1:]) or len(
                {s.environment.empty for s in sensings}) != 1:
            return NotImplemented
        p, sizes = first.params, [len(w.pos) for w in worlds]
        offsets = np.cumsum([0, *sizes[:-1]])
        pos = np.concatenate([w.pos for w in worlds])
        stacked = stacked_setpoints(setpoints, len(pos))
        v_pref = preferred_velocity(stacked, pos, p.gain, p.v_max)  # row by row
        pairs = np.concatenate([s.pairs(first.range) + o for s, o in zip(sensings, offsets, strict=True)])
        index, valid = neighbour_table(pairs, pos[:, :2], p.max_neighbours)  # each agent's partners in its world
        static = ~np.concatenate([w.healthy for w in worlds])
        vel = np.where(static[:, None], 0.0, np.concatenate([w.vel[:, :2] for w in worlds]))
        preferred = perturb_rows(v_pref[:, :2], p.perturbation, [a.ctx.rng for a in avoidances], sizes)
        planes = [a._obstacle_halfplanes(s) for a, s in zip(avoidances, sensings, strict=True)]
        hard = None if planes[0] is None else tuple(np.concatenate([h[k] for h in planes]) for k in range(3))
        v_new, feasible = new_velocities(pos[:, :2], vel, preferred, index, valid, static, *first._constants(), hard,
                                         np.radians(p.detour))
        return filtered_setpoints(avoidances, worlds, setpoints, np.column_stack([v_new, v_pref[:, 2]]), valid,
                                  feasible)

    def _rows(self, world, sensing, sp: Setpoints) -> tuple[np.ndarray, _Rows, Any]:
        """What eq. 5 needs of one world: v_pref (N, 3), the rows of :func:`new_velocities` (x-y
        positions, velocities with the failed ones static, the perturbed v_pref, the neighbour
        table and its mask, the static agents) and the obstacle half-planes (None without)."""
        p = self.params
        v_pref = preferred_velocity(sp, world.pos, p.gain, p.v_max)
        index, valid = neighbour_table(sensing.pairs(self.range), world.pos[:, :2], p.max_neighbours)
        static = ~world.healthy
        vel = np.where(static[:, None], 0.0, world.vel[:, :2])
        preferred = perturb(v_pref[:, :2], p.perturbation, self.ctx.rng)
        return v_pref, (world.pos[:, :2], vel, preferred, index, valid, static), self._obstacle_halfplanes(sensing)

    def _constants(self) -> tuple[float, float, float, float]:
        """r_A + r_B, tau, the time step and v_max of :func:`new_velocities`."""
        return self.combined_radius, self.params.time_horizon, self.ctx.guidance_period, self.params.v_max

    def _obstacle_halfplanes(self, sensing):
        if sensing.environment.empty:
            return None
        normal, clearance, near = nearest_obstacles(sensing, self.obstacle_reach)
        clearance = np.where(near, clearance, 0.0)
        point, direction = obstacle_lines(normal, clearance, self.obstacle_limit,
                                          self.params.time_horizon_obstacle)
        return point[:, None], direction[:, None], near[:, None]

    @hookimpl
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """Add ``orca.fallback_ticks`` and ``orca.max_neighbours_used``."""
        metrics["orca.fallback_ticks"] = self.fallback_ticks
        metrics["orca.max_neighbours_used"] = self.max_used


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`Orca` to the registry, so that ``avoidance=orca`` chooses it."""
    register(Orca)
