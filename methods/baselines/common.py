"""What both baselines need from a tick: preferred velocities from setpoints, nearest obstacles."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.core.plugin import PluginParams
from swarmscene.core.setpoint import Mode, SetpointBatch, Setpoints, is_mode
from swarmscene.core.state import WorldState
from swarmscene.core.vectors import clip_norm


class VelocityFilterParams(PluginParams):
    """The options both baselines share: how the preferred velocity v_pref (ORCA's v_A^pref, the
    certificates' u^nom) is made from a setpoint, how fast it may be, and how symmetric deadlocks
    are broken. Each method's Params adds its own."""

    v_max: float = Field(
        1.0, gt=0, le=1000.0, description="speed limit |v| <= v_max, m/s (ORCA's disc D(0, v_max) of "
        "eq. 5); keep it at or below the dynamics' speed limit; at most 1000 m/s")
    margin: float = Field(
        0.05, ge=0, le=1000.0, description="added to safety.separation_limit (ORCA: the combined radius "
        "r_A + r_B; cbf: D_s) and to safety.clearance_limit (obstacles), m; absorbs tracking lag")
    perturbation: float = Field(
        0.01, ge=0, description="random perturbation of the preferred velocity, m/s: breaks the "
        "deadlocks of perfectly symmetric encounters (RVO2 examples); from the run's seeded generator")
    detour: float = Field(
        0.0, ge=0, lt=90, description="right-hand rule: the preferred velocity of an agent outside one "
        "of its constraints is turned this many degrees clockwise (about +z), so symmetric encounters "
        "circulate instead of deadlocking; 0 (default): the published method (the swap preset's "
        "tuning sets 30)")
    gain: float = Field(
        1.0, gt=0, description="pull onto POSITION/TRACK/HOLD references in the preferred velocity, 1/s")


def preferred_velocity(sp: Setpoints, pos: np.ndarray, gain: float, v_max: float) -> np.ndarray:
    """v_pref (N, 3) m/s of every setpoint, at most ``v_max`` long.

    VELOCITY: ``sp.vel``. POSITION, TRACK: ``sp.vel + gain (sp.pos - p)`` (feed-forward plus a
    proportional pull onto the reference, the single integrator's own law). HOLD: ``gain (sp.pos -
    p)`` (HOLD carries no feed-forward).
    """
    pull = gain * (sp.pos - pos)
    v = np.where(is_mode(sp.mode, Mode.VELOCITY)[:, None], sp.vel, sp.vel + pull)
    v = np.where(is_mode(sp.mode, Mode.HOLD)[:, None], pull, v)
    return clip_norm(v, v_max)


def perturb(v: np.ndarray, magnitude: float, rng: np.random.Generator) -> np.ndarray:
    """``v`` (N, 2) plus a random vector of uniform direction and uniform length in [0, magnitude]
    per row (RVO2's examples: "perturb a little to avoid deadlocks due to perfect symmetry")."""
    if magnitude == 0.0:
        return v
    angle = rng.uniform(0.0, 2.0 * np.pi, len(v))
    length = rng.uniform(0.0, magnitude, len(v))
    return v + length[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])


def perturb_rows(v: np.ndarray, magnitude: float, rngs: Sequence[np.random.Generator],
                 sizes: Sequence[int]) -> np.ndarray:
    """:func:`perturb` of several swarms' stacked rows ``v``, swarm k's ``sizes[k]`` rows drawn
    from its own ``rngs[k]`` (its angles, then its lengths, as :func:`perturb` draws them): each
    row gets the bits :func:`perturb` gives it (the same elementwise operations; numpy's ``cos``
    and ``sin`` give every element the same bits at any length, tests/test_batch.py)."""
    if magnitude == 0.0:
        return v
    draws = [(rng.uniform(0.0, 2.0 * np.pi, size), rng.uniform(0.0, magnitude, size))
             for rng, size in zip(rngs, sizes, strict=True)]
    angle = np.concatenate([a for a, _ in draws])
    length = np.concatenate([b for _, b in draws])
    return v + length[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])


def velocity_setpoints(sp: Setpoints, active: np.ndarray, vel: np.ndarray) -> Setpoints:
    """A copy of ``sp`` with the ``active`` agents switched to VELOCITY at ``vel`` (N, 3) m/s and
    zero acceleration (and jerk, snap) feed-forward; the other agents' rows are left as they were."""
    out = sp.copy()
    out.mode[active] = Mode.VELOCITY
    out.vel[active] = vel[active]
    out.acc[active] = 0.0
    for extra in (out.jerk, out.snap):
        if extra is not None:
            extra[active] = 0.0
    return out


def stacked_setpoints(setpoints: Sequence[Setpoints], rows: int) -> Setpoints:
    """B worlds' setpoints as one record of their stacked agents (mode, pos, vel, acc, yaw): a
    :class:`SetpointBatch`'s own arrays (its records are views of them), else the records
    concatenated."""
    whole = setpoints.whole() if isinstance(setpoints, SetpointBatch) else None
    if whole is not None and whole.n == rows:
        return Setpoints(whole.mode, whole.pos, whole.vel, whole.acc, whole.yaw)
    return Setpoints(*(np.concatenate([getattr(sp, key) for sp in setpoints])
                       for key in ("mode", "pos", "vel", "acc", "yaw")))


def filtered_setpoints(filters: Sequence[Any], worlds: Sequence[WorldState], setpoints: Sequence[Setpoints],
                       commands: np.ndarray, valid: np.ndarray, feasible: np.ndarray) -> Sequence[Setpoints]:
    """A velocity filter's batched answer (ORCA's, the certificates'): each world's healthy agents
    switched to VELOCITY at its rows of ``commands`` (B N, 3) (:func:`velocity_setpoints`), and
    each instance's ``fallback_ticks`` and ``max_used`` counted from its rows of ``feasible`` and
    ``valid`` (the neighbour table's mask) as its own ``adjust`` counts them. Handed one
    :class:`SetpointBatch`, it answers with one (the commands of all rows at once, the counts by
    ``reduceat`` over the worlds' offsets); else with one record per world."""
    sizes = [len(world.pos) for world in worlds]
    offsets = np.cumsum([0, *sizes[:-1]])
    healthy = np.concatenate([world.healthy for world in worlds])
    whole = setpoints.whole() if isinstance(setpoints, SetpointBatch) else None
    if whole is not None and whole.n == len(healthy) and min(sizes) > 0:
        fallback = np.add.reduceat((~feasible & healthy).astype(np.int64), offsets)
        used = np.maximum.reduceat(valid.sum(axis=1), offsets)
        for f, count, most in zip(filters, fallback.tolist(), used.tolist(), strict=True):
            f.fallback_ticks += count
            f.max_used = max(f.max_used, most)
        return SetpointBatch(velocity_setpoints(whole, healthy, commands), len(worlds))
    return [filtered_world(f, world, sp, commands[start:start + size], valid[start:start + size],
                           feasible[start:start + size])
            for f, world, sp, start, size in zip(filters, worlds, setpoints, offsets.tolist(), sizes, strict=True)]


def filtered_world(f: Any, world: WorldState, sp: Setpoints, commands: np.ndarray, valid: np.ndarray,
                   feasible: np.ndarray) -> Setpoints:
    """One world's answer of a velocity filter (ORCA's, the certificates' ``adjust``): its healthy
    agents switched to VELOCITY at ``commands`` (N, 3) (:func:`velocity_setpoints`), and the
    instance's ``fallback_ticks`` (healthy agents whose program was infeasible) and ``max_used``
    (the most neighbours an agent's table held, ``valid`` its mask) counted."""
    f.fallback_ticks += int(np.count_nonzero(~feasible & world.healthy))
    f.max_used = max(f.max_used, int(valid.sum(axis=1).max(initial=0)))
    return velocity_setpoints(sp, world.healthy, commands)


def nearest_obstacles(sensing, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each agent's nearest obstacle point within ``reach`` m, from the tick's shared queries.

    Returns (normal (N, 2) unit, from the obstacle point towards the agent; clearance (N,) m,
    signed, ``inf`` beyond reach; near (N,) bool). Inside an obstacle the normal still points out.
    """
    n = sensing.world.n
    normal = np.zeros((n, 2))
    if sensing.environment.empty:
        return normal, np.full(n, np.inf), np.zeros(n, dtype=bool)
    _, clearance = sensing.obstacle_nearest(reach)
    near = np.isfinite(clearance)
    rows = np.flatnonzero(near)
    if rows.size:
        pos = sensing.world.pos[rows, :2]
        away = pos - sensing.environment.nearest_point(pos)
        away[clearance[rows] < 0] *= -1.0  # inside: the nearest boundary point lies outwards
        normal[rows] = away / np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-12)
    return normal, clearance, near
