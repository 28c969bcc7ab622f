"""The ``dryden`` disturbance model: continuous turbulence, Dryden form of MIL-F-8785C / MIL-HDBK-1797.

At low altitude, with altitude-dependent scales and intensities, plus (``mean``) the standard's
log-profile mean wind; the turbulence components are in wind axes (u along the mean wind, v across,
w up). Numerics and sources: :mod:`swarmscene.methods.disturbances.atmosphere` (the shaping filters
discretised exactly).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances import atmosphere
from swarmscene.methods.disturbances.wind import MAX_WIND, WindParams
from swarmscene.plugin import Disturbance, DisturbanceContext, WorldState, hookimpl


class DrydenParams(WindParams):
    """``name: dryden``: W_20, the mean wind, the intensities' factor and the field's extent."""

    speed: float = Field(
        5.0, ge=0.0, le=MAX_WIND,
        description="W_20, the mean wind speed at 20 ft (6.1 m), m/s; sets sigma_w = 0.1 W_20 "
        "(MIL-F-8785C: 7.7 light, 15.4 moderate, 23.2 severe)")
    mean: bool = Field(
        True, description="add the mean wind W_20 ln(h / z0) / ln(20 ft / z0) (MIL-F-8785C "
        "log profile, z0 = 0.15 ft) to the turbulence")
    intensity: float = Field(
        1.0, ge=0.0, le=10.0, description="factor on the standard's intensities sigma_u, sigma_v, "
        "sigma_w (1: the standard)")
    field: Literal["shared", "independent"] = Field(
        "shared",
        description="shared: one realisation at the swarm's mean altitude for every agent (the "
        "field is correlated over tens of metres); independent: one per agent")


class Dryden(Disturbance):
    """Continuous turbulence, Dryden form of MIL-F-8785C / MIL-HDBK-1797 at low altitude, with
    altitude-dependent scales and intensities, plus (``mean``) the standard's log-profile mean
    wind; the turbulence components are in wind axes (u along the mean wind, v across, w up)."""

    name = "dryden"
    phase = "wind"
    Params = DrydenParams

    params: DrydenParams

    def __init__(self, params: DrydenParams, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.axes = atmosphere.wind_axes(math.radians(params.heading))
        self.filters: atmosphere.DrydenFilters | None = None
        self.dt = ctx.physics_step
        self.per_tick = max(1, round(ctx.guidance_period / ctx.physics_step))
        self.steps = 0
        self.conditions: tuple[Any, ...] = ()  # (L, sigma, V, mean): set at the first physics step

    def _conditions(self, world: WorldState) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(L, sigma, V) per realisation at its altitude h; the mean wind (M, 3) there."""
        p = self.params
        h = world.pos[:, 2]
        vel = world.vel
        if p.field == "shared":
            h, vel = h.mean(keepdims=True), vel.mean(axis=0, keepdims=True)
        L, sigma = atmosphere.dryden_scales(h, p.speed)
        sigma = sigma * p.intensity
        mean = atmosphere.log_profile(h, p.speed)[:, None] * self.axes[0]
        # the frozen field passes at the speed through the air mass (Taylor's hypothesis)
        V = np.maximum(np.linalg.norm(vel - mean, axis=1), atmosphere.MIN_AIRSPEED)
        return L, sigma, V, (mean if p.mean else 0.0 * mean)

    def air(self, world: WorldState, t: float) -> np.ndarray:
        """Called once per physics step: the first call starts the filters in their stationary
        state, each later one advances them by the physics step. The scales, intensities, airspeed
        and mean wind (which change with altitude and speed over seconds) are evaluated at the
        first physics step of each guidance tick and held over its others."""
        if self.steps % self.per_tick == 0:
            self.conditions = self._conditions(world)
        self.steps += 1
        L, sigma, V, mean = self.conditions
        if self.filters is None:
            self.filters = atmosphere.DrydenFilters(V.size, self.rng, L, sigma, V)
            gust = self.filters.output
        else:
            gust = self.filters.step(self.dt, L, sigma, V)
        air = np.empty(world.pos.shape)  # every agent's row (np.broadcast_to's Python costs more)
        air[:] = mean + gust @ self.axes
        return air


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Dryden` to the registry, so that ``disturbances.<key>.name: dryden`` chooses it."""
    register(Dryden)
