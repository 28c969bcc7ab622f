"""The ``ground_effect`` disturbance model: more thrust near the floor (Cheeseman and Bennett 1955).

Numerics and sources: :mod:`swarmscene.methods.physics.ground_effect`. A force phase model: the
extra thrust per mass (T_IGE / T_OGE - 1) τ along each vehicle's thrust τ
(:mod:`swarmscene.methods.physics.thrust`), at its height above ``environment.floor`` (which it
needs: a scenario without a floor is refused); compiled,
:func:`swarmscene.methods.physics.kernels.ground_lift`.

Metrics: ``peak_ratio`` (the largest T_IGE / T_OGE applied).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.methods.physics import crazyflie as cf
from swarmscene.plugin import Disturbance, DisturbanceParams, hookimpl


class GroundEffect(Disturbance):
    """T_IGE / T_OGE = 1 / (1 - (R / 4z)²) at each vehicle's height above the floor."""

    name = "ground_effect"
    phase = "force"

    class Params(DisturbanceParams):
        rotor_radius: float = Field(cf.ROTOR_RADIUS, gt=0, le=10, description="R, m (Crazyflie 0.0231)")
        min_height: float = Field(
            cf.ROTOR_RADIUS / 2, gt=0, le=10,
            description="z is taken as at least this, m (default R / 2: ratio <= 4/3; singular at R / 4)")
        mass: float = Field(cf.MASS, gt=0, le=1e4, description="m, kg, to read the rotors' thrust (0.027)")
        k_T: float = Field(cf.K_T, gt=0, description="k_T, N/(rad/s)^2, to read the rotors' thrust (2.88e-8)")

    params: Params

    def __init__(self, params: GroundEffect.Params, ctx) -> None:
        super().__init__(params, ctx)
        if ctx.floor is None:
            raise ValueError("needs a ground: set environment.floor (e.g. environment.floor=0)")
        if params.min_height <= params.rotor_radius / 4:
            raise ValueError(f"min_height: must be above rotor_radius / 4 = {params.rotor_radius / 4:g} m, "
                             f"where the ratio is singular (got {params.min_height})")
        # numba: imported when built
        from swarmscene.methods.physics.kernels import ground_lift
        from swarmscene.methods.physics.thrust import thrust_per_mass

        self._thrust, self._lift = thrust_per_mass, ground_lift
        self.floor = float(ctx.floor)
        self.peak = 1.0

    def force(self, world, t):
        """(ratio - 1) τ per vehicle (N, 3), m/s^2."""
        p = self.params
        tau = np.ascontiguousarray(self._thrust(world, p.k_T, p.mass), dtype=np.float64)
        lift, peak = self._lift(np.ascontiguousarray(world.pos[:, 2]), tau, self.floor, p.rotor_radius, p.min_height)
        self.peak = max(self.peak, peak)
        return lift

    def metrics(self):
        """``peak_ratio``: the largest T_IGE / T_OGE applied."""
        return {"peak_ratio": self.peak}


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`GroundEffect` to the registry, so that ``disturbances=[ground_effect]`` chooses it."""
    register(GroundEffect)
