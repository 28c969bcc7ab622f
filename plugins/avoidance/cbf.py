"""CBF: safety barrier certificates (Wang, Ames, Egerstedt 2017; Borrmann et al. 2015), decentralised.

Every guidance tick each healthy agent i replaces its setpoint by a velocity command u_i*:

1. The nominal input u_i^nom is the preferred velocity of its setpoint
   (``methods.baselines.common.preferred_velocity``): VELOCITY: ``sp.vel``; POSITION/TRACK:
   ``sp.vel + gain (sp.pos - p)``; HOLD: ``gain (sp.pos - p)``; clipped to ``v_max`` (the Robotarium
   also thresholds the nominal input before its QP).
2. Barrier h_ij = |p_i - p_j|^2 - D_s^2 with D_s = ``safety.separation_limit + margin``; certificate
   dh_ij/dt >= -gamma h_ij^p, i.e. -2 (p_i - p_j)^T (u_i - u_j) <= gamma h_ij^p, split half and half
   between the two agents (each keeps -2 (p_i - p_j)^T u_i <= gamma h_ij^p / 2), all of it against
   a failed vehicle (it hovers: u_j = 0). Obstacles: the nearest obstacle point o_i within reach,
   h_io = |p_i - o_i|^2 - D_o^2, D_o = ``safety.clearance_limit + margin``, responsibility 1.
3. u_i* = argmin |u_i - u_i^nom|^2 subject to those constraints and |u_i| <= ``v_max``: the
   decentralised QP of each agent is a projection onto half-planes in a disc, solved exactly and
   for all agents at once (``methods.baselines.cbf``; no iterative solver). Where it is infeasible
   (agents already inside D_s and squeezed), the input minimising the largest violation is used,
   the obstacle constraint kept hard.

Output: healthy agents get ``Mode.VELOCITY`` with ``vel = (u*_x, u*_y, u^nom_z)`` and zero
acceleration feed-forward; failed agents' setpoints pass through untouched; the input setpoints
are never modified (a copy is returned).

Dynamics: the certificate is the single-integrator one (section III of the paper): with
single_integrator the filtered velocity is the velocity, and gamma T_s <= 1 keeps h >= 0 between
ticks exactly (see ``methods.baselines.cbf``). double_integrator and quadrotor receive the same
filtered velocity as a VELOCITY setpoint and track it with their velocity loops (a velocity-level
filter, not the paper's acceleration-level certificate for double integrators); ``margin`` and a
moderate ``gamma`` absorb their lag.

Choices where the papers leave room:
- planar: constraints and the QP in x-y, distances in x-y (conservative: altitude differences are
  ignored), z command = u^nom_z;
- neighbours: every agent within the range where a half-constraint can be active inside the speed
  disc (``influence_range``), or the nearest ``max_neighbours`` of them when set;
- kappa(h) = h^p with p = ``power`` (1: the linear certificate of the issue; 3: the Robotarium's).
- deadlocks (a deliberate deviation, measured in docs/benchmarks.md): minimally invasive filters
  stop agents whose nominal input points into their neighbours' constraints, and the symmetric swap
  deadlocks already at N = 8, random perturbations (``perturbation``) notwithstanding. Two changes
  of the nominal input, never of the constraints: an agent whose u^nom violates one of its
  constraints has it turned ``detour`` degrees clockwise (the right-hand rule: the crowd
  circulates); an agent the filter still stops (|u*| < ``deadlock_ratio`` |u^nom|, e.g. pressed
  into the gap between two neighbours resting on their goals, which never yield) is filtered again
  with u^nom turned ``deadlock_turn`` degrees to either side and keeps the faster result (it
  slides along the obstruction; Grover et al. 2021 resolve CBF deadlocks in the same spirit).
  ``detour=0 deadlock_turn=0``, the defaults, is the plain certificate; the ``swap`` preset's
  tuning (scenarios/tuning/avoidance/swap/cbf.yaml) sets 30 and 90 degrees.

Metrics: ``cbf.fallback_ticks`` (agent-ticks where the QP was infeasible),
``cbf.max_neighbours_used``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.methods.baselines.cbf import influence_range, safe_velocities
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
from swarmscene.plugin import Avoidance, BuildContext, Setpoints, hookimpl


class BarrierCertificates(Avoidance):
    """Decentralised single-integrator safety barrier certificates, one exact QP per agent."""

    name = "cbf"

    class Params(VelocityFilterParams):
        gamma: float = Field(
            1.0, gt=0, description="barrier gain gamma of dh/dt >= -gamma h^p, 1/s (for p = 1); "
            "gamma * clock.guidance_period <= 1 keeps a single integrator safe between ticks")
        power: int = Field(
            1, ge=1, description="p of the class-K function h^p (1: linear; 3: the Robotarium's)")
        max_neighbours: int | None = Field(
            None, ge=1, le=1_000_000, description="constraints per agent, nearest first; null: every neighbour "
            "whose constraint can be active")
        deadlock_turn: float = Field(
            0.0, ge=0, lt=180, description="an agent the filter stops (|u*| < deadlock_ratio "
            "|u^nom|) is filtered again with u^nom turned this many degrees to either side and keeps "
            "the faster result: it slides along the obstruction instead of waiting; 0 (default): "
            "never (the swap preset's tuning sets 90)")
        deadlock_ratio: float = Field(
            0.1, gt=0, lt=1, description="|u*| / |u^nom| under which an agent counts as stopped")

    params: Params

    def __init__(self, params: BarrierCertificates.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        self.safe_distance = ctx.separation_limit + params.margin
        self.range = influence_range(self.safe_distance, params.gamma, params.power, params.v_max)
        self.obstacle_distance = ctx.clearance_limit + params.margin
        # a static constraint (responsibility 1) is inactive in the disc beyond this
        self.obstacle_reach = influence_range(self.obstacle_distance, 2.0 * params.gamma, params.power,
                                              params.v_max)
        self.fallback_ticks = 0
        self.max_used = 0

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        """The planar velocity nearest the (perturbed) nominal one that keeps every certificate
        h >= 0, against neighbours and the nearest obstacle, as VELOCITY setpoints for the healthy
        agents; counts the ticks an agent had to fall back to the least violation."""
        p = self.params
        u_nom = preferred_velocity(sp, world.pos, p.gain, p.v_max)
        index, valid = neighbour_table(sensing.pairs(self.range), world.pos[:, :2], p.max_neighbours)
        u, feasible = safe_velocities(
            world.pos[:, :2], perturb(u_nom[:, :2], p.perturbation, self.ctx.rng), index, valid,
            ~world.healthy, self.safe_distance, p.gamma, p.power, p.v_max, self._obstacles(sensing),
            np.radians(p.detour), np.radians(p.deadlock_turn), p.deadlock_ratio,
        )
        return filtered_world(self, world, sp, np.column_stack([u, u_nom[:, 2]]), valid, feasible)

    @classmethod
    def adjust_batch(cls, avoidances, worlds, sensings, setpoints):
        """``adjust`` of B worlds with one pass of the certificates' numerics, as ORCA's batched
        form: the worlds' agents stacked as rows (each world's pairs shifted to its rows), the
        perturbation from each world's own stream, each world's nearest obstacles from its
        sensing, then every row through :func:`safe_velocities`, which is row by row (each agent's
        half-planes, its closest velocity and its deadlock escape), so every world gets its own
        ``adjust``'s bits (the contract check ``avoidance.adjust_batch_equals_worlds``). The
        answer (:func:`filtered_setpoints`) is one :class:`SetpointBatch` where it was handed one.
        Declined (``NotImplemented``, before any world is touched) for instances whose options or
        limits differ, worlds with and without obstacles, and ``power`` other than 1: kappa's
        ``|h| ** p`` is numpy's ``power``, whose SIMD path may give an element other bits at
        another array length."""
        first = avoidances[0]
        p = first.params
        if (p.power != 1 or any(a.params != p or a._limits() != first._limits() for a in avoidances[1:])
                or len({s.environment.empty for s in sensings}) != 1):
            return NotImplemented
        sizes = [len(w.pos) for w in worlds]
        offsets = np.cumsum([0, *sizes[:-1]])
        pos = np.concatenate([w.pos for w in worlds])
        u_nom = preferred_velocity(stacked_setpoints(setpoints, len(pos)), pos, p.gain, p.v_max)  # row by row
        pairs = np.concatenate([s.pairs(first.range) + o for s, o in zip(sensings, offsets, strict=True)])
        index, valid = neighbour_table(pairs, pos[:, :2], p.max_neighbours)  # each agent's partners in its world
        nominal = perturb_rows(u_nom[:, :2], p.perturbation, [a.ctx.rng for a in avoidances], sizes)
        near = [a._obstacles(s) for a, s in zip(avoidances, sensings, strict=True)]
        obstacle = None if near[0] is None else (
            *(np.concatenate([o[k] for o in near]) for k in range(3)), first.obstacle_distance)
        u, feasible = safe_velocities(
            pos[:, :2], nominal, index, valid, ~np.concatenate([w.healthy for w in worlds]), first.safe_distance,
            p.gamma, p.power, p.v_max, obstacle, np.radians(p.detour), np.radians(p.deadlock_turn), p.deadlock_ratio,
        )
        return filtered_setpoints(avoidances, worlds, setpoints, np.column_stack([u, u_nom[:, 2]]), valid, feasible)

    def _limits(self) -> tuple[float, float, float, float]:
        """The distances the instance derived from its run's limits: D_s, the neighbour range, D_o
        and the obstacles' reach, m."""
        return self.safe_distance, self.range, self.obstacle_distance, self.obstacle_reach

    def _obstacles(self, sensing):
        if sensing.environment.empty:
            return None
        normal, clearance, near = nearest_obstacles(sensing, self.obstacle_reach)
        return normal, np.where(near, clearance, 1.0), near, self.obstacle_distance

    @hookimpl
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """Add ``cbf.fallback_ticks`` and ``cbf.max_neighbours_used``."""
        metrics["cbf.fallback_ticks"] = self.fallback_ticks
        metrics["cbf.max_neighbours_used"] = self.max_used


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`BarrierCertificates` to the registry, so that ``avoidance=cbf`` chooses it."""
    register(BarrierCertificates)
