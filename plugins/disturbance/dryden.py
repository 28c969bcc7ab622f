"""The ``dryden`` disturbance model: continuous turbulence, Dryden form of MIL-F-8785C / MIL-HDBK-1797.

At low altitude, with altitude-dependent scales and intensities, plus (``mean``) the standard's
log-profile mean wind; the turbulence components are in wind axes (u along the mean wind, v across,
w up). Numerics and sources: :mod:`swarmscene.methods.disturbances.atmosphere` (the shaping filters
discretised exactly).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal, cast

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
        L, sigma, V, mean = self._held_conditions(world)
        if self.filters is None:
            self.filters = atmosphere.DrydenFilters(V.size, self.rng, L, sigma, V)
            gust = self.filters.output
        else:
            gust = self.filters.step(self.dt, L, sigma, V)
        return self._blown(world, mean, gust)

    @classmethod
    def air_batch(cls, models: Sequence[Dryden], worlds: Sequence[WorldState], t: float) -> list[np.ndarray] | Any:
        """``air`` of B worlds at once: each world's conditions as its own ``air`` holds them, then
        the filters of every world stepped in one pass (``DrydenFilters.step_together``: each
        world's own draws, the same bits). Declined at the first physics step (each world starts
        its filters alone) and where the instances' options or sizes differ."""
        first = models[0]
        if any(m.filters is None for m in models):
            return NotImplemented
        filters = [cast(atmosphere.DrydenFilters, m.filters) for m in models]
        if any(m.params != first.params or m.dt != first.dt for m in models) or len({f.u.size for f in filters}) > 1:
            return NotImplemented
        held = [m._held_conditions(world) for m, world in zip(models, worlds, strict=True)]
        gusts = atmosphere.DrydenFilters.step_together(filters, first.dt, [conditions[:3] for conditions in held])
        return [m._blown(world, conditions[3], gust)
                for m, world, conditions, gust in zip(models, worlds, held, gusts, strict=True)]

    def _held_conditions(self, world: WorldState) -> tuple[Any, ...]:
        """(L, sigma, V, mean) for this physics step: evaluated at a tick's first, held over its others."""
        if self.steps % self.per_tick == 0:
            self.conditions = self._conditions(world)
        self.steps += 1
        return self.conditions

    def _blown(self, world: WorldState, mean: np.ndarray, gust: np.ndarray) -> np.ndarray:
        """The air at every agent (N, 3): the mean wind plus the gusts turned from wind axes."""
        air = np.empty(world.pos.shape)  # every agent's row (np.broadcast_to's Python costs more)
        air[:] = mean + gust @ self.axes
        return air


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Dryden` to the registry, so that ``disturbances.<key>.name: dryden`` chooses it."""
    register(Dryden)
