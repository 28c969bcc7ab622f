"""The ``gust`` disturbance model: the discrete 1-cosine gust of MIL-F-8785C 3.7.5, hitting every agent.

v(t) = V_m s(t) along a direction, s = (1 - cos(pi (t - start) / rise)) / 2 while rising; ``hold``
null keeps the peak (the standard's form), ``hold`` 0 is the airworthiness codes' 1-cosine pulse.
Numerics: :func:`swarmscene.methods.disturbances.atmosphere.one_minus_cosine`.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances import atmosphere
from swarmscene.methods.disturbances.wind import MAX_WIND, WindParams, direction
from swarmscene.plugin import MAX_DURATION, Disturbance, DisturbanceContext, WorldState, hookimpl


class GustParams(WindParams):
    """``name: gust``: its peak, direction and timing."""

    amplitude: float = Field(5.0, ge=0.0, le=MAX_WIND, description="gust peak V_m, m/s")
    elevation: float = Field(
        0.0, ge=-90.0, le=90.0, description="gust direction above the horizontal, degrees")
    start: float = Field(5.0, ge=0.0, le=MAX_DURATION, description="time the gust begins, s")
    rise: float = Field(
        1.0, gt=0.0, le=MAX_DURATION,
        description="time to the peak, s (gust length d_m over the speed it is crossed at)")
    hold: float | None = Field(
        None, ge=0.0, le=MAX_DURATION,
        description="time at the peak before the mirror-image decay, s (null: stays, the "
        "MIL-F-8785C form; 0: the 1-cosine pulse)")


class Gust(Disturbance):
    """The discrete 1-cosine gust of MIL-F-8785C 3.7.5 (``hold`` null) or the airworthiness codes'
    1-cosine pulse (``hold`` 0), hitting every agent at once: v(t) = V_m s(t) along a direction."""

    name = "gust"
    phase = "wind"
    Params = GustParams

    params: GustParams

    def __init__(self, params: GustParams, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.peak = params.amplitude * direction(params.heading, params.elevation)

    def air(self, world: WorldState, t: float) -> np.ndarray:
        """v(t) = V_m s(t) along the gust's direction at every agent, (N, 3) m/s."""
        p = self.params
        shape = float(atmosphere.one_minus_cosine(t, p.start, p.rise, p.hold))
        return np.broadcast_to(shape * self.peak, world.pos.shape)


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Gust` to the registry, so that ``disturbances.<key>.name: gust`` chooses it."""
    register(Gust)
