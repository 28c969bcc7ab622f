"""``quadrotor`` dynamics: 6-DOF rigid bodies (thesis eq. 3.4-3.16) under an SE(3) controller.

Per guidance tick, :meth:`Quadrotor.control` turns the setpoints into references for the geometric
tracking controller of Lee, Leok and McClamroch (2010) with differential-flatness feed-forward
(Mellinger and Kumar 2011); per physics step, :meth:`Quadrotor.step` runs that controller (thrust and
torque), the inverse mixer with rotor-speed limits (eq. 3.16) and one RK4 step of the rigid body.
Everything is vectorised over agents; see quadrotor_model.py for frames (world z up, body
front-left-up; the thesis' NED/FRD equations are converted there).

Setpoint modes:
    TRACK     p, v, a, jerk, snap, yaw: the reference moves along its Taylor polynomial between
              ticks (so the inner loop sees a smooth trajectory, not a staircase); flatness gives
              the body-rate and angular-acceleration feed-forward.
    POSITION  go to p (v, a, jerk, snap are feed-forward at the tick's values, not propagated, since
              the target itself is meant to stay put).
    VELOCITY  fly at v (position error ignored), a as feed-forward.
    HOLD      hold p with no feed-forward; failed agents are put in HOLD where they are.
The yaw rate and acceleration are taken as zero (the setpoint record carries yaw only).

Added to the world: ``quat`` (N, 4) (w, x, y, z) body to world, ``omega`` (N, 3) body rates rad/s,
``rotor_speed`` (N, 4) rad/s.

Motor failure (a ``motor_failure`` event, through the ``swarmscene_event`` hook): rotor r of the
hit vehicles keeps ``fraction`` of its thrust and drag torque from then on (an effective speed
sqrt(fraction) ϖ_r). The controller does not know: it keeps holding where the vehicle failed
(a failed agent is put in HOLD) with four rotors in its allocation, so the vehicle falls, tilts and
spins as the remaining wrench makes it (a dead rotor leaves the yaw drag torques unbalanced).

Wind (``disturbances``): the model integrates it (``wind_coupling = "integrated"``): at each
internal step the force per mass R diag(D) R^T w (the airframe's rotor-drag coefficients D, see
quadrotor_model.py) joins the RK4 right-hand side, and with ``moment_arm`` h the moment
(0, 0, h) x F_body joins the rotors' torque.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import BuildContext, Dynamics, PluginParams
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState

from swarmscene.methods.quadrotor.flatness import flat_state, heading_vector
from swarmscene.methods.quadrotor.model import AIRFRAMES, allocate, pack, quat_to_rotmat, rk4, wrench, yaw_to_quat
from swarmscene.methods.quadrotor.se3_controller import se3_control, se3_gains


class Quadrotor(Dynamics):
    """Rigid-body quadrotors with rotor-level inputs and an SE(3) tracking controller."""

    name = "quadrotor"
    has_attitude = True
    wind_coupling = "integrated"
    rotors = 4

    class Params(PluginParams):
        airframe: Literal["crazyflie", "m330"] = Field(
            "crazyflie",
            description="crazyflie: 27 g nano quad (Foerster 2015 identification); m330: ~1 kg, "
            "330 mm quad of the CEM paper's class (assumed parameters, see quadrotor_model.py)",
        )
        position_omega: float = Field(
            4.0, gt=0, description="natural frequency of the position loop, rad/s")
        position_xi: float = Field(0.9, gt=0, description="damping ratio of the position loop")
        attitude_omega: float = Field(
            25.0, gt=0, description="natural frequency of the roll/pitch loop, rad/s")
        attitude_xi: float = Field(0.8, gt=0, description="damping ratio of the attitude loop")
        yaw_omega: float = Field(8.0, gt=0, description="natural frequency of the yaw loop, rad/s")
        max_tilt: float = Field(
            45.0, gt=0, lt=90, description="cap on the commanded tilt from vertical, degrees")
        max_step: float = Field(
            1.0 / 240.0, ge=1e-5,
            description="longest internal integration step, s (at least 10 us): a longer "
            "clock.physics_step is split into equal sub-steps, so the inner loop stays stable at "
            "any physics rate",
        )
        propagate_reference: bool = Field(
            True, description="in TRACK mode, move the reference along its Taylor polynomial "
            "(p, v, a, jerk, snap) between guidance ticks")

        @model_validator(mode="after")
        def _inner_loop_resolved(self) -> "Quadrotor.Params":
            # the attitude loop is discrete at max_step: keep omega dt well below its stability edge
            if self.attitude_omega * self.max_step > 0.5:
                raise ValueError(
                    f"attitude_omega * max_step must be <= 0.5 for a stable discrete attitude loop "
                    f"(got {self.attitude_omega} * {self.max_step})")
            return self

    def __init__(self, params: "Quadrotor.Params", ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        self.airframe = AIRFRAMES[params.airframe]
        self.gains = se3_gains(self.airframe, params.position_omega, params.position_xi,
                               params.attitude_omega, params.attitude_xi, params.yaw_omega)
        self.max_tilt = math.radians(params.max_tilt)

    # -- lifecycle ---------------------------------------------------------------------------
    def initialize(self, world: WorldState) -> None:
        n = world.n
        world.quat = yaw_to_quat(np.zeros(n))
        world.omega = np.zeros((n, 3))
        world.rotor_speed = np.full((n, 4), self.airframe.hover_rotor_speed)
        self.rotor_health: np.ndarray | None = None  # (N, 4) thrust kept, allocated at a failure
        self.control(world, Setpoints.hold(world.pos))

    def control(self, world: WorldState, sp: Setpoints) -> None:
        """Latch this tick's references (zero-order hold, or Taylor propagation in TRACK mode)."""
        n = world.n
        mode = np.where(world.healthy, sp.mode, Mode.HOLD)
        hold = (mode == Mode.HOLD)[:, None]
        zeros = np.zeros((n, 3))
        jerk = zeros if sp.jerk is None else sp.jerk
        snap = zeros if sp.snap is None else sp.snap
        self._p = np.where(world.healthy[:, None], sp.pos, world.pos)
        self._v = np.where(hold, 0.0, sp.vel)
        self._a = np.where(hold, 0.0, sp.acc)
        self._yaw = np.asarray(sp.yaw, dtype=float).copy()
        self._heading = heading_vector(self._yaw)
        self._position_mask = mode != Mode.VELOCITY
        track = (mode == Mode.TRACK)[:, None] & self.params.propagate_reference
        # derivatives used to move the reference during the tick (zero rows: not propagated)
        self._dv = np.where(track, self._v, 0.0)
        self._da = np.where(track, self._a, 0.0)
        self._dj = np.where(track, jerk, 0.0)
        self._ds = np.where(track, snap, 0.0)
        self._tau = 0.0
        if sp.jerk is None and sp.snap is None:
            # constant acceleration and heading: the flat body rates are zero
            self._omega_d = self._alpha_d = None
        else:
            ff = flat_state(self._a, np.where(hold, 0.0, jerk), np.where(hold, 0.0, snap), self._yaw)
            self._omega_d, self._alpha_d = ff.omega, ff.alpha

    def step(self, world: WorldState, dt: float) -> None:
        """Advance the rigid bodies by ``dt`` (in sub-steps of at most ``max_step``)."""
        substeps = max(1, math.ceil(dt / self.params.max_step - 1e-9))
        h = dt / substeps
        af = self.airframe
        x = pack(world.pos, world.vel, world.quat, world.omega)
        for _ in range(substeps):
            p_d, v_d, a_d = self._reference(self._tau)
            thrust, torque, _ = se3_control(
                x[:, 0:3], x[:, 3:6], quat_to_rotmat(x[:, 6:10]), x[:, 10:13], p_d, v_d, a_d,
                self._yaw, self._omega_d, self._alpha_d, self.gains, af, self._position_mask,
                self.max_tilt, self._heading)
            rotor_speed = allocate(thrust, torque, af)
            thrust, torque = wrench(self._effective(rotor_speed), af)   # what the rotors really give
            ext_acc = None
            if world.wind is not None:
                ext_acc, moment = self._wind(x, world.wind, world.wind_moment_arm)
                torque = torque + moment
            x = rk4(x, thrust, torque, af, h, ext_acc)
            self._tau += h
        world.pos[...] = x[:, 0:3]
        world.vel[...] = x[:, 3:6]
        world.quat[...] = x[:, 6:10]
        world.omega[...] = x[:, 10:13]
        world.rotor_speed[...] = rotor_speed

    @hookimpl
    def swarmscene_event(self, sim, event) -> None:
        """A ``motor_failure``: rotor ``event.rotor`` of the event's agents keeps ``event.fraction``."""
        if getattr(event.kind, "value", event.kind) != "motor_failure":
            return
        if self.rotor_health is None:
            self.rotor_health = np.ones((sim.world.n, 4))
        self.rotor_health[list(event.agents), event.rotor] = event.fraction

    def _effective(self, rotor_speed: np.ndarray) -> np.ndarray:
        """Rotor speeds giving the thrust the rotors really make: sqrt(kept fraction) ϖ."""
        if self.rotor_health is None:
            return rotor_speed
        return rotor_speed * np.sqrt(self.rotor_health)

    def _wind(self, x: np.ndarray, wind: np.ndarray, arm: float) -> tuple[np.ndarray, np.ndarray]:
        """The wind's acceleration (N, 3) world and moment (N, 3) N m body: a = R D R^T w and
        M = (0, 0, h) x m D R^T w (the drag force acting at the centre of pressure)."""
        R = quat_to_rotmat(x[:, 6:10])
        f_body = np.einsum("nji,nj->ni", R, wind) * np.asarray(self.airframe.drag)  # per mass
        acc = np.einsum("nij,nj->ni", R, f_body)
        m = self.airframe.mass
        moment = np.column_stack([-arm * m * f_body[:, 1], arm * m * f_body[:, 0], np.zeros(len(x))])
        return acc, moment

    def wind_acceleration(self, world: WorldState) -> np.ndarray:
        return self._wind(pack(world.pos, world.vel, world.quat, world.omega), world.wind, 0.0)[0]

    def _reference(self, tau: float):
        """(p_d, v_d, a_d) at ``tau`` s after the tick (Taylor polynomial on TRACK rows)."""
        if tau == 0.0:
            return self._p, self._v, self._a
        t2, t3, t4 = tau * tau / 2.0, tau**3 / 6.0, tau**4 / 24.0
        p = self._p + tau * self._dv + t2 * self._da + t3 * self._dj + t4 * self._ds
        v = self._v + tau * self._da + t2 * self._dj + t3 * self._ds
        a = self._a + tau * self._dj + t2 * self._ds
        return p, v, a


@hookimpl
def swarmscene_register_dynamics(register) -> None:
    register(Quadrotor)
