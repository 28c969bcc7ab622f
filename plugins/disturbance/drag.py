"""The ``drag`` disturbance model: rotor drag (Foerster 2015) and body drag in still air.

Numerics and sources: :mod:`swarmscene.methods.physics.drag`. A force phase model:
a = -(θ̇_Σ / m) R K_aero R^T v - (c_b / m) |v| v per vehicle, with the rotor speeds and attitude
where the dynamics has them (hover speeds and level otherwise). The wind models add the moving
air's part themselves.

Metrics: ``peak_acceleration`` (m/s^2).
"""

from __future__ import annotations

from pydantic import Field

from swarmscene.methods.physics import crazyflie as cf
from swarmscene.plugin import Disturbance, DisturbanceParams, hookimpl


class Drag(Disturbance):
    """Rotor drag linear in airspeed and parasitic body drag quadratic in it."""

    name = "drag"
    phase = "force"

    class Params(DisturbanceParams):
        k_aero: tuple[float, float, float] = Field(
            cf.K_AERO, description="K_aero along body x, y, z, kg/rad (Foerster 2015: 9.1785e-7, "
            "9.1785e-7, 10.311e-7)")
        body: float = Field(1.08e-3, ge=0, le=1e3, description="c_b = ½ ρ C_D A, kg/m (estimate: "
                            "C_D 1.18, A 15 cm^2)")
        mass: float = Field(cf.MASS, gt=0, le=1e4, description="m, kg (Crazyflie 0.027)")
        hover_speed: float = Field(cf.HOVER_ROTOR_SPEED, gt=0, description="rotor speed at hover, rad/s, "
                                   "for models without rotors (1516)")

    params: Params

    def __init__(self, params: Drag.Params, ctx) -> None:
        super().__init__(params, ctx)
        from swarmscene.methods.physics import drag, thrust  # numba: imported when built

        self._drag, self._thrust = drag, thrust
        if any(k < 0 for k in params.k_aero):
            raise ValueError("k_aero: must be >= 0")
        self.peak = 0.0

    def force(self, world, t):
        """The drag's acceleration (N, 3), m/s^2."""
        p = self.params
        rotors = self._thrust.rotor_speed_sum(world, p.hover_speed)
        acc, peak = self._drag.drag_acceleration(world.vel, world.quat, rotors, p.k_aero, p.mass, p.body)
        self.peak = max(self.peak, peak)
        return acc

    def metrics(self):
        """``peak_acceleration``, m/s^2."""
        return {"peak_acceleration": self.peak}


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Drag` to the registry, so that ``disturbances=[drag]`` chooses it."""
    register(Drag)
