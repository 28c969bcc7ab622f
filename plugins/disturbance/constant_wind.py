"""The ``constant_wind`` disturbance model: steady, uniform wind, the same air velocity everywhere.

A wind phase model (what the wind models share: :mod:`swarmscene.methods.disturbances.wind`); the
kernel applies the air's velocity as a force on the dynamics.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances.wind import MAX_WIND, WindParams, direction
from swarmscene.plugin import Disturbance, DisturbanceContext, WorldState, hookimpl


class ConstantWindParams(WindParams):
    """``name: constant_wind``: its speed toward ``heading`` and its vertical component."""

    speed: float = Field(5.0, ge=0.0, le=MAX_WIND, description="wind speed, m/s")
    vertical: float = Field(0.0, ge=-MAX_WIND, le=MAX_WIND, description="vertical component, m/s (up +)")


class ConstantWind(Disturbance):
    """Steady, uniform wind: the same air velocity at every agent for the whole run."""

    name = "constant_wind"
    phase = "wind"
    Params = ConstantWindParams

    params: ConstantWindParams

    def __init__(self, params: ConstantWindParams, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.velocity = params.speed * direction(params.heading)
        self.velocity[2] = params.vertical

    def air(self, world: WorldState, t: float) -> np.ndarray:
        """The same constant wind at every agent, (N, 3) m/s (a read-only broadcast: no copy per step)."""
        return np.broadcast_to(self.velocity, world.pos.shape)


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`ConstantWind` to the registry, so that ``disturbances.<key>.name: constant_wind`` chooses it."""
    register(ConstantWind)
