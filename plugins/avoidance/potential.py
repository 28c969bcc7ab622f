"""Potential-field avoidance: pairwise and obstacle repulsion that keeps the safety distances.

Each agent i gets a repulsive velocity from every agent j closer than the influence range
``d_0 = influence * d_s`` (d_s = ``safety.separation_limit``) and from the nearest obstacle point
closer than ``d_0^obs = obstacle_influence + c_s`` (c_s = ``safety.clearance_limit``):

    v_rep = v_max * ((d_0 - d) / (d_0 - d_s))^2 * (r_i - r_j) / d,   clipped to 1 at d <= d_s

a bounded, smooth barrier: zero at the edge of the range, ``v_max`` at the safety distance. The sum
is clipped to ``v_max``. The setpoint is reshaped, not overridden: ``vel += v_rep`` and
``pos += lookahead * v_rep`` so both position- and velocity-mode controllers turn away.
Neighbours come from the tick's shared k-d tree; obstacles from the environment's vectorised
nearest-point query, so a step costs O(N log N).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.plugin import Avoidance, Mode, PluginParams, SetpointBatch, Setpoints, clip_norm, every, hookimpl


def barrier(d: np.ndarray, d_safe: float, d_range: float) -> np.ndarray:
    """Magnitude profile in [0, 1]: 0 at ``d >= d_range``, 1 at ``d <= d_safe``, quadratic between."""
    x = np.clip((d_range - d) / max(d_range - d_safe, 1e-9), 0.0, 1.0)
    return x * x


def _sum_at(rows: np.ndarray, values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Zeros of ``shape`` with ``values[k]`` added to row ``rows[k]``, k in order: ``np.add.at``'s
    sums to the bit (one bincount over the flat index, a few times cheaper for a few agents)."""
    n, width = shape
    flat = (rows[:, None] * width + np.arange(width)).ravel()
    summed = np.bincount(flat, weights=values.ravel(), minlength=n * width)
    return summed.astype(float, copy=False).reshape(shape)  # (no rows: bincount's zeros are ints)


_VELOCITY = int(Mode.VELOCITY)
"""As an int: numpy compares an array with an enum member several times slower."""


class Potential(Avoidance):
    """Pairwise and obstacle repulsion added to the formation's setpoints."""

    name = "potential"

    class Params(PluginParams):
        v_max: float = Field(1.5, gt=0, description="largest repulsive speed, m/s")
        influence: float = Field(
            2.5, gt=1, le=1000.0, description="agent range as a multiple of safety.separation_limit (at most "
            "1000: the pair query lists every neighbour within it)"
        )
        obstacle_influence: float = Field(
            1.5, gt=0, le=1000.0, description="obstacle range beyond safety.clearance_limit, m (at most 1 km: "
            "the obstacle query lists every footprint within it)"
        )
        lookahead: float = Field(
            1.0, ge=0, description="shift of the position reference along v_rep, s"
        )

    params: Params

    def repulsion(self, world, sensing) -> np.ndarray:
        """Repulsive velocity (N, 3) from neighbours and obstacles (failed agents included)."""
        v = self._repulsion(world, sensing)
        return np.zeros_like(world.pos) if v is None else v

    def _repulsion(self, world, sensing) -> np.ndarray | None:
        """:meth:`repulsion`, or ``None`` when no agent and no obstacle is in range (zero)."""
        pairs = sensing.pairs(self._range())
        v = self._pair_repulsion(world.pos, pairs) if len(pairs) else None
        if not sensing.environment.empty:
            obstacle = self._obstacle_repulsion(world, sensing)
            if obstacle is not None:
                v = np.zeros_like(world.pos) if v is None else v
                v += obstacle
        return None if v is None else clip_norm(v, self.params.v_max)

    def _range(self) -> float:
        """d_0 = ``influence`` d_s, the agents' range, m."""
        return self.params.influence * max(self.ctx.separation_limit, 1e-3)

    def _pair_repulsion(self, pos: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """The agents' repulsion (N, 3) from the ``pairs`` (P, 2) within d_0, each pair's push summed
        onto its agents in the pairs' order (zero rows for agents in no pair)."""
        p, d_s = self.params, self.ctx.separation_limit
        i, j = pairs[:, 0], pairs[:, 1]
        delta = pos[i] - pos[j]
        d = np.sqrt(np.add.reduce(delta * delta, axis=1))  # np.linalg.norm(axis=1), its own ops
        push = (p.v_max * barrier(d, d_s, self._range()) / np.maximum(d, 1e-9))[:, None] * delta
        return _sum_at(np.concatenate([i, j]), np.concatenate([push, -push]), pos.shape)

    def _obstacle_repulsion(self, world, sensing) -> np.ndarray | None:
        """Repulsive velocity (N, 3) from the nearest obstacles; ``None`` when none is in range."""
        p, c_s = self.params, self.ctx.clearance_limit
        d_range = c_s + p.obstacle_influence
        if sensing.nothing_within(d_range):  # shown already this tick (a batch's prefetch): no query
            return None
        clearance = sensing.clearance_within(d_range)
        below = clearance < d_range
        if not np.count_nonzero(below):
            return None
        near = np.flatnonzero(below)
        v = np.zeros_like(world.pos)
        point = sensing.environment.nearest_point(world.pos[near])
        away = world.pos[near, :2] - point
        d = np.maximum(clearance[near], 1e-9)
        direction = away / np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-9)
        # Inside an obstacle the nearest point lies behind: push outwards all the same.
        direction[clearance[near] < 0] *= -1
        v[near, :2] = (p.v_max * barrier(d, c_s, d_range))[:, None] * direction
        return v

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        """Add the repulsive velocity v_rep to the setpoints' velocity, and shift their positions by
        ``lookahead`` v_rep, so that position-mode controllers turn away too (failed agents get none)."""
        repulsion = self._repulsion(world, sensing)
        if repulsion is not None and not every(world.healthy):
            repulsion[~world.healthy] = 0.0
        # None is added as a scalar 0.0: the same sums as with an array of zeros
        v_rep = 0.0 if repulsion is None else repulsion
        shift = self.params.lookahead * v_rep
        moving = sp.mode != _VELOCITY
        if every(moving):  # pos + shift, without two gathers and a scatter
            pos = sp.pos + shift
        else:
            pos = sp.pos.copy()
            pos[moving] += shift[moving] if isinstance(shift, np.ndarray) else shift
        # New pos and vel; the fields it does not change are handed on, not copied (nothing
        # after avoidance writes to setpoints: the dynamics' contract forbids it).
        return Setpoints(sp.mode, pos, sp.vel + v_rep, sp.acc, sp.yaw, sp.jerk, sp.snap)

    @classmethod
    def adjust_batch(cls, avoidances, worlds, sensings, setpoints):
        """``adjust`` of B worlds of N agents with one pass of the pairs' numerics: the worlds'
        agents stacked as rows, each world's pairs shifted to its rows (the pushes summed onto each
        agent in its own world's pair order, zero rows where :meth:`adjust` adds a scalar 0), each
        world's obstacles its own, then the clip, the failed agents' zeros and the reshaped
        setpoints row by row: every world gets its own ``adjust``'s bits (the contract check
        ``avoidance.adjust_batch_equals_worlds``). Answers with one :class:`SetpointBatch` (the
        setpoints read whole where they came as one). Declined (``NotImplemented``) for instances
        whose options or safety limits differ, or worlds of different sizes."""
        first = avoidances[0]
        limits = (first.ctx.separation_limit, first.ctx.clearance_limit)
        if any(a.params != first.params or (a.ctx.separation_limit, a.ctx.clearance_limit) != limits
               for a in avoidances[1:]) or len({len(w.pos) for w in worlds}) != 1:
            return NotImplemented
        batch = _whole_batch(setpoints)
        if batch is None:
            return NotImplemented
        sp = batch.whole()
        n = len(worlds[0].pos)
        pos = np.concatenate([w.pos for w in worlds])
        pairs = np.concatenate([s.pairs(first._range()) + b * n for b, s in enumerate(sensings)])
        v = first._pair_repulsion(pos, pairs)
        for b, (a, world, sensing) in enumerate(zip(avoidances, worlds, sensings, strict=True)):
            if not sensing.environment.empty:
                obstacle = a._obstacle_repulsion(world, sensing)
                if obstacle is not None:
                    v[b * n:(b + 1) * n] += obstacle
        v_rep = clip_norm(v, first.params.v_max)
        v_rep[~np.concatenate([w.healthy for w in worlds])] = 0.0
        shift = first.params.lookahead * v_rep
        moving = (sp.mode != _VELOCITY)[:, None]
        return SetpointBatch(Setpoints(sp.mode, np.where(moving, sp.pos + shift, sp.pos), sp.vel + v_rep, sp.acc,
                                       sp.yaw, sp.jerk, sp.snap), len(worlds))


def _whole_batch(setpoints) -> SetpointBatch | None:
    """The worlds' setpoints as a batch that can be read whole: the one handed, else the records
    stacked; None for records that cannot be stacked (some carrying jerk or snap and others not)."""
    if isinstance(setpoints, SetpointBatch) and setpoints.whole() is not None:
        return setpoints
    try:
        return SetpointBatch.stack(list(setpoints))
    except ValueError:
        return None


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`Potential` to the registry, so that ``avoidance=potential`` chooses it."""
    register(Potential)
