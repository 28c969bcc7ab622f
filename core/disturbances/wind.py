"""Wind models of the ``disturbances`` group: constant wind, 1-cosine gust, Dryden turbulence.

Each returns the air's velocity at every agent for the physics step; the kernel sums them and
applies the result as a force on the dynamics model (:mod:`swarmscene.core.disturbances`, "wind
phase"). Numerics and sources: :mod:`swarmscene.core.disturbances.atmosphere`.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field

from ..fields import MAX_DURATION
from ..state import WorldState
from . import atmosphere as numerics
from .base import Disturbance, DisturbanceContext, DisturbanceParams

MAX_WIND = 100.0
"""m/s: the largest wind speed a model accepts (a category-5 hurricane is ~70 m/s)."""


class WindParams(DisturbanceParams):
    """Options shared by the wind models."""

    heading: float = Field(
        0.0, ge=-360.0, le=360.0,
        description="direction the wind blows toward, degrees counter-clockwise from +x (east)")
    moment_arm: float = Field(
        0.0, ge=-1.0, le=1.0,
        description="height of the centre of pressure above the centre of gravity, m: models with "
        "attitude (quadrotor) take the moment r x F of the wind's force there (0: force only)")


def _direction(heading_deg: float, elevation_deg: float = 0.0) -> np.ndarray:
    h, e = math.radians(heading_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(h), math.cos(e) * math.sin(h), math.sin(e)])


class ConstantWind(Disturbance):
    """Steady, uniform wind: the same air velocity at every agent for the whole run."""

    kind = "constant_wind"
    phase = "wind"

    class Params(WindParams):
        speed: float = Field(5.0, ge=0.0, le=MAX_WIND, description="wind speed, m/s")
        vertical: float = Field(0.0, ge=-MAX_WIND, le=MAX_WIND, description="vertical component, m/s (up +)")

    params: Params

    def __init__(self, params: ConstantWind.Params, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.velocity = params.speed * _direction(params.heading)
        self.velocity[2] = params.vertical

    def air(self, world: WorldState, t: float) -> np.ndarray:
        """The same constant wind at every agent, (N, 3) m/s (a read-only broadcast: no copy per step)."""
        return np.broadcast_to(self.velocity, world.pos.shape)


class Gust(Disturbance):
    """The discrete 1-cosine gust of MIL-F-8785C 3.7.5 (``hold`` null) or the airworthiness codes'
    1-cosine pulse (``hold`` 0), hitting every agent at once: v(t) = V_m s(t) along a direction,
    s = (1 - cos(pi (t - start) / rise)) / 2 while rising (see
    :func:`~swarmscene.core.disturbances.atmosphere.one_minus_cosine`)."""

    kind = "gust"
    phase = "wind"

    class Params(WindParams):
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

    params: Params

    def __init__(self, params: Gust.Params, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.peak = params.amplitude * _direction(params.heading, params.elevation)

    def air(self, world: WorldState, t: float) -> np.ndarray:
        """v(t) = V_m s(t) along the gust's direction at every agent, (N, 3) m/s."""
        p = self.params
        shape = float(numerics.one_minus_cosine(t, p.start, p.rise, p.hold))
        return np.broadcast_to(shape * self.peak, world.pos.shape)


class Dryden(Disturbance):
    """Continuous turbulence, Dryden form of MIL-F-8785C / MIL-HDBK-1797 at low altitude, with
    altitude-dependent scales and intensities, plus (``mean``) the standard's log-profile mean
    wind; the turbulence components are in wind axes (u along the mean wind, v across, w up)."""

    kind = "dryden"
    phase = "wind"

    class Params(WindParams):
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

    params: Params

    def __init__(self, params: Dryden.Params, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.axes = numerics.wind_axes(math.radians(params.heading))
        self.filters: numerics.DrydenFilters | None = None
        self.dt = ctx.physics_step
        self.per_tick = max(1, round(ctx.guidance_period / ctx.physics_step))
        self.steps = 0
        self.conditions: tuple[Any, ...] = ()  # (L, sigma, V, mean): set at the first physics step

    def _conditions(self, world: WorldState) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(h, L, sigma, V) per realisation; the mean wind (M, 3) at those altitudes."""
        p = self.params
        h = world.pos[:, 2]
        vel = world.vel
        if p.field == "shared":
            h, vel = h.mean(keepdims=True), vel.mean(axis=0, keepdims=True)
        L, sigma = numerics.dryden_scales(h, p.speed)
        sigma = sigma * p.intensity
        mean = numerics.log_profile(h, p.speed)[:, None] * self.axes[0]
        # the frozen field passes at the speed through the air mass (Taylor's hypothesis)
        V = np.maximum(np.linalg.norm(vel - mean, axis=1), numerics.MIN_AIRSPEED)
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
            self.filters = numerics.DrydenFilters(V.size, self.rng, L, sigma, V)
            gust = self.filters.output
        else:
            gust = self.filters.step(self.dt, L, sigma, V)
        return np.broadcast_to(mean + gust @ self.axes, world.pos.shape)


MODELS = (ConstantWind, Gust, Dryden)
