"""Double integrator: the thesis' translational model (eq. 3.21-3.22) under a PD tracker.

    r(k+1) = r(k) + T v(k) + T^2/2 u(k),   v(k+1) = v(k) + T u(k),   |u| <= u_sat

The acceleration u is computed once per guidance tick and held (zero-order hold) over the physics
sub-steps, which integrate it exactly. Setpoint modes:
    POSITION, TRACK, HOLD: u = acc_ff + k_p (pos_ref - r) + k_d (vel_ref - v)
    VELOCITY:              u = acc_ff + k_v (vel_ref - v)
The gains default to a critically damped response with natural frequency ``omega`` (k_p = omega^2,
k_d = 2 omega). The thesis' discrete PID/PI/tracker controllers replace this in the dynamics issue.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import Dynamics, PluginParams
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState

from .single_integrator import clip_norm


class DoubleIntegrator(Dynamics):
    """Point mass with saturated acceleration (thesis eq. 3.21-3.22) and a PD tracker."""

    name = "double_integrator"

    class Params(PluginParams):
        omega: float = Field(1.0, gt=0, description="natural frequency of the PD tracker, rad/s")
        k_v: float = Field(2.0, gt=0, description="velocity-error gain in VELOCITY mode, 1/s")
        u_sat: float = Field(3.0, gt=0, description="acceleration limit |u| <= u_sat, m/s^2")
        v_max: float = Field(5.0, gt=0, description="speed limit, m/s")

    def initialize(self, world: WorldState) -> None:
        self.u = np.zeros_like(world.pos)

    def control(self, world: WorldState, sp: Setpoints) -> None:
        p = self.params
        k_p, k_d = p.omega**2, 2.0 * p.omega
        u_pos = k_p * (sp.pos - world.pos) + k_d * (sp.vel - world.vel)
        u_vel = p.k_v * (sp.vel - world.vel)
        u = sp.acc + np.where((sp.mode == Mode.VELOCITY)[:, None], u_vel, u_pos)
        self.u = clip_norm(u, p.u_sat)

    def step(self, world: WorldState, dt: float) -> None:
        world.pos += world.vel * dt + 0.5 * self.u * dt * dt
        world.vel += self.u * dt
        speed = np.linalg.norm(world.vel, axis=1, keepdims=True)
        world.vel *= np.minimum(1.0, self.params.v_max / np.maximum(speed, 1e-12))


@hookimpl
def swarmscene_register_dynamics(register) -> None:
    register(DoubleIntegrator)
