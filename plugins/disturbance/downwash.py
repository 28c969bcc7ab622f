"""The ``downwash`` disturbance model: the push of the rotors above on every vehicle below.

Numerics and sources: :mod:`swarmscene.methods.physics.downwash` (the gym-pybullet-drones fit,
regularised; the Crazyswarm keep-out ellipsoid). A force phase model: each physics step it finds
the vehicles above each one (compiled cell search) and returns -F / m e_3 per vehicle.

Metrics (``disturbances.<key>.``): ``peak_acceleration`` (m/s^2, the largest push on a vehicle),
``min_keep_out`` (the smallest ||E^-1 (p_i - p_j)|| over the pairs within reach, null: none came
within reach), ``keep_out_conflicts`` (distinct pairs inside the ellipsoid),
``keep_out_first_time`` and ``keep_out_agents`` (the first conflict; only after one). These are
measured on the physics steps, as the model's own view, and judge nothing: the run's safety
condition is the monitor's ``safety.keep_out`` (:class:`swarmscene.core.monitors.SafetyMonitor`:
``min_keep_out``, ``keep_out_conflicts``, ``violations.keep_out.*``, counted by ``success``).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.methods.physics import crazyflie as cf
from swarmscene.plugin import Disturbance, DisturbanceParams, hookimpl


class Downwash(Disturbance):
    """F_z = -α exp(-½ (r / β)²) from every vehicle above (gym-pybullet-drones' fit, regularised)."""

    name = "downwash"
    phase = "force"

    class Params(DisturbanceParams):
        scale: float = Field(1.0, ge=0, le=100, description="multiplies the fitted force (1: the fit)")
        c1: float = Field(cf.DOWNWASH_COEFFICIENTS[0], gt=0, description="C_1, N (gym-pybullet-drones 2267.18)")
        c2: float = Field(cf.DOWNWASH_COEFFICIENTS[1], description="C_2 (0.16)")
        c3: float = Field(cf.DOWNWASH_COEFFICIENTS[2], description="C_3, m (-0.11)")
        rotor_radius: float = Field(cf.ROTOR_RADIUS, gt=0, le=10, description="R_p, m (Crazyflie 0.0231)")
        mass: float = Field(cf.MASS, gt=0, le=1e4, description="the vehicles' mass m, kg (Crazyflie 0.027)")
        min_width: float = Field(
            2 * cf.ROTOR_RADIUS, ge=0, le=10,
            description="β_min, m: the plume width is sqrt(β² + β_min²) (0: the published fit, singular "
            "at Δz = -C_3 / C_2 = 0.69 m)")
        min_height: float = Field(
            0.1, gt=0, le=10, description="Δz is taken as at least this, m (α grows as 1 / Δz²)")
        reach_r: float = Field(1.0, gt=0, le=100, description="horizontal reach of a plume, m")
        reach_z: float = Field(3.0, gt=0, le=1000, description="vertical reach of a plume, m")
        keep_out: tuple[float, float, float] = Field(
            cf.KEEP_OUT_RADII, description="radii of the keep-out ellipsoid [x, y, z], m (Crazyswarm "
            "0.12, 0.12, 0.3); conflicts are reported, not enforced")

    params: Params

    def __init__(self, params: Downwash.Params, ctx) -> None:
        super().__init__(params, ctx)
        # numba is imported here, not at module level: listing plugins must not pay for it
        from swarmscene.methods.physics.downwash import downwash_field

        self._field = downwash_field
        self._radii = np.asarray(params.keep_out, dtype=float)
        if np.any(self._radii <= 0):
            raise ValueError("keep_out: the ellipsoid's radii must be > 0")
        self.peak = 0.0
        self.min_keep_out = np.inf
        self.conflicts: set[tuple[int, int]] = set()
        self.first: tuple[float, list[int]] | None = None

    def force(self, world, t):
        """-scale F / m e_3 per vehicle (N, 3), m/s^2."""
        p = self.params
        push, strongest, best, conflicts = self._field(
            np.ascontiguousarray(world.pos, dtype=np.float64), p.c1, p.c2, p.c3, p.rotor_radius, p.min_width,
            p.min_height, p.reach_r, p.reach_z, self._radii)
        acc = np.zeros((world.n, 3))
        acc[:, 2] = -p.scale / p.mass * push
        self.peak = max(self.peak, p.scale / p.mass * strongest)
        self.min_keep_out = min(self.min_keep_out, best)
        if conflicts.shape[0]:
            self.conflicts.update(map(tuple, conflicts.tolist()))
            if self.first is None:
                self.first = (float(t), sorted(set(conflicts.ravel().tolist())))
        return acc

    def metrics(self):
        """``peak_acceleration`` (m/s^2) and the keep-out ellipsoid's (module docstring)."""
        out = {"peak_acceleration": self.peak,
               "min_keep_out": self.min_keep_out if np.isfinite(self.min_keep_out) else None,
               "keep_out_conflicts": len(self.conflicts)}
        if self.first is not None:
            out["keep_out_first_time"], out["keep_out_agents"] = self.first
        return out


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Downwash` to the registry, so that ``disturbances=[downwash]`` chooses it."""
    register(Downwash)
