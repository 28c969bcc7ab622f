"""Single integrator: the kinematic point of the thesis' indoor swarm (eq. 5.1).

    r(k+1) = r(k) + T u(k),   |u(k)| <= u_max

The control u is a velocity, held for the guidance period (zero-order hold). Setpoint modes:
VELOCITY flies ``sp.vel``; POSITION and TRACK fly ``sp.vel + gain * (sp.pos - r)`` (feed-forward
plus proportional correction); HOLD flies ``gain * (sp.pos - r)``. Every command is clipped to
``u_max`` in magnitude.

Wind (``disturbances``): the point flies relative to the air (``wind_coupling = "carried"``): its
ground velocity is u + w (the kinematic model of a vehicle in wind, e.g. Beard and McLain,
Small Unmanned Aircraft, 2012, eq. 2.9), so holding a position at gain k it settles at
p + w / k.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Self

import numpy as np
from pydantic import Field

from swarmscene.plugin import (
    Dynamics,
    Mode,
    PluginParams,
    Setpoints,
    WorldBatch,
    WorldState,
    clip_norm,
    hookimpl,
)

_VELOCITY, _HOLD = int(Mode.VELOCITY), int(Mode.HOLD)
"""As ints: numpy compares an array with an enum member several times slower."""
assert _VELOCITY & 1 and _HOLD & 1 and not int(Mode.POSITION) & 1 and not int(Mode.TRACK) & 1


class SingleIntegrator(Dynamics):
    """Kinematic point: the velocity command is the velocity (thesis eq. 5.1)."""

    name = "single_integrator"
    wind_coupling = "carried"

    class Params(PluginParams):
        u_max: float = Field(1.0, gt=0, description="speed limit |u| <= u_max, m/s")
        gain: float = Field(
            1.0, gt=0, description="proportional gain on position error in POSITION/TRACK/HOLD, 1/s"
        )

    params: Params

    def initialize(self, world: WorldState) -> None:
        """The velocity command u, zero until the first guidance tick."""
        self.u = np.zeros_like(world.pos)

    def control(self, world: WorldState, sp: Setpoints) -> None:
        """u = v̄ + k (r̄ - r); VELOCITY setpoints take v̄ alone, HOLD ones k (r̄ - r) alone."""
        p = self.params
        correction = p.gain * (sp.pos - world.pos)
        u = sp.vel + correction
        if np.count_nonzero(sp.mode & 1):  # VELOCITY (1) or HOLD (3) somewhere: else u as it is
            velocity = sp.mode == _VELOCITY
            if np.count_nonzero(velocity):
                u = np.where(velocity[:, None], sp.vel, u)
            u = np.where((sp.mode == _HOLD)[:, None], correction, u)
        self.u = clip_norm(u, p.u_max)

    @classmethod
    def control_batch(cls, models: Sequence[Self], batch: WorldBatch, worlds: Sequence[WorldState],
                      setpoints: Sequence[Setpoints]) -> object:
        """``control`` of B worlds at once over their stacked B x N agents (docs/batched.md): the
        correction, the mode selection and the saturation are elementwise or row by row, so each
        agent gets its own ``control``'s bits. Worlds whose options differ, and setpoints that are
        not (N, 3) float64 records with (N,) integer modes, are left to the per-world ``control``
        (where a wrong record raises for its own world)."""
        first = models[0]
        n = batch.pos.shape[1]
        same = batch.per_batch("single_integrator.same_options", lambda: all(m.params == first.params for m in models))
        if not same or not all(
                sp.mode.shape == (n,) and sp.mode.dtype.kind in "iu" and sp.pos.shape == sp.vel.shape == (n, 3)
                and sp.pos.dtype == sp.vel.dtype == np.float64 for sp in setpoints):
            return NotImplemented
        p = first.params
        mode = np.concatenate([sp.mode for sp in setpoints])
        vel = np.concatenate([sp.vel for sp in setpoints])
        own = all(w is t for w, t in zip(worlds, batch.worlds, strict=True))
        correction = p.gain * (np.concatenate([sp.pos for sp in setpoints])
                               - (batch.pos.reshape(-1, 3) if own else np.concatenate([w.pos for w in worlds])))
        u = vel + correction
        if np.count_nonzero(mode & 1):  # as control's selection, over every world's agents
            velocity = mode == _VELOCITY
            if np.count_nonzero(velocity):
                u = np.where(velocity[:, None], vel, u)
            u = np.where((mode == _HOLD)[:, None], correction, u)
        for model, own_u in zip(models, clip_norm(u, p.u_max).reshape(len(models), n, 3), strict=True):
            model.u = own_u
        return None

    def step(self, world: WorldState, dt: float) -> None:
        """r += u T, v = u: the velocity command is flown exactly."""
        world.pos += self.u * dt
        world.vel[:] = self.u

    @classmethod
    def step_batch(cls, models: Sequence[Self], batch: WorldBatch, dt: float) -> None:
        """``step`` of B worlds in three array operations over (B, N, 3) (docs/batched.md)."""
        u = batch.per_tick("single_integrator.u", lambda: np.stack([model.u for model in models]))
        batch.pos += u * dt
        batch.vel[:] = u


@hookimpl
def swarmscene_register_dynamics(register) -> None:
    """Add :class:`SingleIntegrator` to the registry, so that ``dynamics=single_integrator`` chooses it."""
    register(SingleIntegrator)
