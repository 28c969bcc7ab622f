"""Antipodal swap: every agent flies to the point opposite its start through the ring's centre.

The standard stress test of multi-robot collision avoidance (the circle scenario of the RVO2
examples; the swap of the barrier-certificate papers): N agents start on a ring of radius R
(``swarm.start.layout: circle``) and each one's goal is its antipode,

    g_i = 2 c - p_i(0),   c = the centroid of the start positions (the ring's centre),

so all straight paths cross at c at the same time and avoidance has to do all the work.

Setpoints: ``Mode.VELOCITY`` with the RVO2 examples' preferred velocity, towards the goal at
``speed`` and slowing down within ``speed / gain`` of it,

    v_i = clip(gain (g_i - p_i), speed),

and ``pos = g_i`` for reference. Velocity commands are what velocity-level avoidance (ORCA, barrier
certificates) filters; they also keep the mission the same for every dynamics model (each one's
velocity loop tracks them), where a POSITION goal would hand each model's position controller its
own approach profile. Failed agents hold where they are.

The mission is complete when every healthy agent is within ``arrival_tolerance`` of its goal.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydantic import Field

from swarmscene.plugin import (
    BuildContext,
    Formation,
    Mode,
    PluginParams,
    SetpointBatch,
    Setpoints,
    WorldState,
    clip_norm,
    hookimpl,
)


class AntipodalSwap(Formation):
    """Each agent flies to the antipode of its start through the ring centre."""

    name = "antipodal_swap"

    class Params(PluginParams):
        speed: float = Field(1.0, gt=0, description="preferred speed towards the goal, m/s")
        gain: float = Field(
            1.0, gt=0, description="slow-down gain near the goal, 1/s (v = clip(gain (g - p), speed))")
        arrival_tolerance: float = Field(
            0.1, gt=0, description="distance to its goal at which an agent has arrived, m")

    params: Params

    def __init__(self, params: AntipodalSwap.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        start = ctx.initial.pos
        self.center = start.mean(axis=0)
        self.goal = 2.0 * self.center - start

    def setpoints(self, world: WorldState, sensing) -> Setpoints:
        """Healthy agents fly at their goal (the antipode of their start) at the capped speed;
        failed ones hold."""
        p = self.params
        sp = Setpoints.hold(world.pos)
        healthy = world.healthy
        sp.mode[healthy] = Mode.VELOCITY
        sp.pos[healthy] = self.goal[healthy]
        sp.vel[healthy] = clip_norm(p.gain * (self.goal[healthy] - world.pos[healthy]), p.speed)
        return sp

    @classmethod
    def setpoints_batch(cls, formations: Sequence[AntipodalSwap], worlds: Sequence[WorldState],
                        sensings: Sequence[object]) -> SetpointBatch | object:
        """``setpoints`` of B worlds of N agents as one :class:`SetpointBatch`: the same
        elementwise steps over the stacked agents (the speed cap row by row), which give every
        agent its single run's bits. Declined where the instances' options or the worlds' sizes
        differ."""
        first, n = formations[0], len(worlds[0].pos)
        if any(f.params.speed != first.params.speed or f.params.gain != first.params.gain for f in formations) or any(
                len(world.pos) != n for world in worlds):
            return NotImplemented
        here = np.concatenate([world.pos for world in worlds])
        healthy = np.concatenate([world.healthy for world in worlds])
        goal = np.concatenate([f.goal for f in formations])
        sp = Setpoints.hold(here)
        sp.mode[healthy] = Mode.VELOCITY
        sp.pos[healthy] = goal[healthy]
        sp.vel[healthy] = clip_norm(first.params.gain * (goal[healthy] - here[healthy]), first.params.speed)
        return SetpointBatch(sp, len(worlds))

    def complete(self, world: WorldState) -> bool:
        """True when every healthy agent is within ``arrival_tolerance`` of its goal."""
        error = np.linalg.norm(world.pos - self.goal, axis=1)
        return bool(np.all(error[world.healthy] <= self.params.arrival_tolerance))


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Add :class:`AntipodalSwap` to the registry, so that ``formation=antipodal_swap`` chooses it."""
    register(AntipodalSwap)
