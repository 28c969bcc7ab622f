"""Double integrator: the thesis' translational model (eq. 3.17-3.22) under its digital controllers.

    r(k+1) = r(k) + T_s v(k) + T_s^2/2 u(k),   v(k+1) = v(k) + T_s u(k),   u = sat(u_lim)

The attitude loop is taken as perfect (thesis 3.2.2), so ``u`` is the net acceleration. It is
computed once per guidance tick by the controllers of thesis section 3.2 (thesis_controllers.py)
and held over the physics sub-steps, which integrate it exactly (so any physics step gives eq.
3.21-3.22 at the tick). The law is chosen per agent from the setpoint mode:

    POSITION, HOLD  position PID with feed-forward and anti-windup (eq. 3.29-3.30) on ``sp.pos``
    VELOCITY        velocity PI with feed-forward and anti-windup (eq. 3.23-3.25) on ``sp.vel``,
                    the reference clipped to ±v_max per axis
    TRACK           tracker control (eq. 3.41-3.42) on the target ``sp.pos``, ``sp.vel``, ``sp.acc``

The velocity limiter (eq. 3.45) with limit ``v_max`` acts on the position and tracker laws.
Gains are synthesised at T_s = ``ctx.guidance_period`` from continuous-time tuning values, so the
behaviour does not change with the guidance period: (omega, xi) pairs as in eq. 3.40, and for the
velocity loop the rates of its two real poles, p_v = exp(-k T_s) (eq. 3.28). The defaults are the
thesis' tuning at T_s = 0.1 s (K_Pv = 9.0, K_Iv = 1.4, K_Fv = 7.0; K_Pr = 0.10, K_Ir = 0.00084,
K_Dr = 0.48, K_Fr = 0.052; K_Pt = 4.1, K_It = 0.20, K_Dt = 2.9). Axes are independent and
identical as in the thesis (eq. 3.20 decoupling), so u_sat and v_max bound each world axis.

Frames: the laws commute with the thesis' NED -> world change of axes (see thesis_controllers.py),
so they run on world arrays directly. Failed agents are switched to HOLD where they are.
Fills ``world.acc`` (N, 3) m/s^2, the input applied this tick (the ū another
agent's tracker can use as feed-forward).

Wind (``disturbances``): a force per mass D w on the point mass (``wind_coupling = "force"``,
the kernel adds it after each step, exactly), D = ``drag_coefficient`` = 0.21 1/s, the Dynamics
default (the thesis gives no drag identification; the Crazyflie's rotor drag per kg is taken).
The position and velocity laws' integral states cancel a steady wind: u -> -D w.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Self

import numpy as np
from pydantic import Field

from swarmscene.methods.quadrotor.thesis_controllers import (
    ThesisController,
    position_gains,
    tracker_gains,
    velocity_gains,
)
from swarmscene.plugin import (
    BuildContext,
    Dynamics,
    Mode,
    PluginParams,
    SetpointBatch,
    Setpoints,
    WorldBatch,
    WorldState,
    every,
    hookimpl,
)


class DoubleIntegrator(Dynamics):
    """Point mass with saturated acceleration (thesis eq. 3.17-3.22) under the thesis controllers."""

    name = "double_integrator"

    class Params(PluginParams):
        omega: float = Field(
            1.5, gt=0, description="tracker natural frequency ω_t, rad/s (eq. 3.40; thesis 1.5)")
        xi: float = Field(0.71, gt=0, lt=1, description="tracker damping ξ_t (thesis 0.71)")
        position_omega: float = Field(
            0.23, gt=0, description="position PID natural frequency ω_r, rad/s (thesis 0.23)")
        position_xi: float = Field(
            0.71, gt=0, lt=1, description="position PID damping ξ_r (thesis 0.71)")
        k_v: float = Field(
            12.04, gt=0, description="velocity loop rate, 1/s: its fast pole is p_v1 = "
            "exp(-k_v T_s), which sets the first-order velocity response (thesis p_v1 = 0.30 at "
            "T_s = 0.1 s, k_v = 12.04)")
        k_v_slow: float = Field(
            2.231, gt=0, description="rate of the velocity loop's slow pole p_v2 = exp(-k_v_slow "
            "T_s), cancelled by the feed-forward zero; it moderates the gains (thesis p_v2 = 0.80)")
        K_Wv: float = Field(0.5, ge=0, description="velocity anti-windup gain K_Wv, s (thesis 0.5)")
        K_Wr: float = Field(50.0, ge=0, description="position anti-windup gain K_Wr, s^2 (thesis 50)")
        K_Wt: float = Field(5.0, ge=0, description="tracker anti-windup gain K_Wt, s^2 (thesis 5)")
        u_sat: float = Field(
            3.4, gt=0, description="acceleration saturation u_sat per axis, m/s^2 (eq. 3.26; "
            "thesis 3.4 for velocity and tracker, 2.6 for position)")
        v_max: float | None = Field(
            5.0, gt=0, description="velocity limit v̄_lim per axis, m/s (eq. 3.45), on the "
            "position and tracker laws; VELOCITY references are clipped to it; null: no limit")
        K_lim: float = Field(
            2.5, gt=0, description="velocity limiter gain K_lim, 1/s (thesis 2.5); capped at 1/T_s "
            "so the limiter stays stable (thesis: K_lim < 2/T_s) at long guidance periods")
        eps_lim: float = Field(
            0.0, ge=0, description="anti-chattering threshold ε_lim, m/s (thesis: 3 σ of the "
            "velocity noise): a limit at or below it brakes with -K_lim v")

    params: Params

    def __init__(self, params: DoubleIntegrator.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        T_s = ctx.guidance_period
        # the slower real pole is the one cancelled by the zero (eq. 3.28)
        # (kept inside (0, 1): a very long T_s would round a pole to 0, a very short one to 1)
        p_1, p_2 = sorted(min(max(math.exp(-k * T_s), 1e-12), 1.0 - 1e-12)
                          for k in (params.k_v, params.k_v_slow))
        self.T_s = T_s
        self.velocity = velocity_gains(p_1, p_2, T_s, params.K_Wv)
        self.position = position_gains(params.position_omega, params.position_xi, T_s, params.K_Wr)
        self.tracker = tracker_gains(params.omega, params.xi, T_s, params.K_Wt)
        self.K_lim = min(params.K_lim, 1.0 / T_s)

    def initialize(self, world: WorldState) -> None:
        """Build the thesis controller for N agents and expose its input u as ``world.acc``."""
        p = self.params
        self.controller = ThesisController(world.n, self.velocity, self.position, self.tracker,
                                           p.u_sat, self.K_lim, p.eps_lim)
        self.u = np.zeros_like(world.pos)
        world.acc = self.u
        self._held_dt: float | None = None  # the dt of _du_pos = T^2/2 u and _du_vel = T u
        self._move = np.empty_like(self.u)  # step()'s work array

    def control(self, world: WorldState, sp: Setpoints) -> None:
        """u from the thesis' three laws (velocity PI, position PID, tracker), by setpoint mode;
        failed agents are switched to HOLD."""
        healthy = world.healthy
        if every(healthy):  # nobody to switch to HOLD (the selections below would copy sp as is)
            mode, r_ref = sp.mode, sp.pos
        else:
            mode = np.where(healthy, sp.mode, Mode.HOLD)
            r_ref = np.where(healthy[:, None], sp.pos, world.pos)
        v_max = self.params.v_max
        if v_max is None:
            v_ref = sp.vel
        else:  # np.clip's values
            v_ref = np.maximum(sp.vel, -v_max)
            np.minimum(v_ref, v_max, out=v_ref)
        self.u[...] = self.controller.step(mode, world.pos, world.vel, r_ref, v_ref, sp.acc, v_max)
        self._held_dt = None

    _LAWS = ("velocity", "position", "tracker")
    """The controller's law objects, in the order of its law numbers (its ``steady_law``)."""

    @classmethod
    def control_batch(cls, models: Sequence[Self], batch: WorldBatch, worlds: Sequence[WorldState],
                      setpoints: Sequence[Setpoints]) -> object:
        """``control`` of B worlds at once over their stacked B x N agents (docs/batched.md).

        The worlds whose agents are all healthy and all keep the law they ran at the previous tick
        (:meth:`ThesisController.steady_law`, every tick but a world's first and its mode
        changes) are grouped by that law, and each group of two or more is one swarm of stacked
        agents: their integral states are packed along the world axis (:meth:`WorldBatch.pack`,
        each controller integrates its slice), and one :meth:`ThesisController.step_steady` runs
        the law's elementwise operations, which give each agent its single run's bits. The other
        worlds are left to the engine (their places returned), which runs their own ``control``
        (a world whose ``control`` raises stops alone). Setpoints given as a
        :class:`~swarmscene.core.setpoint.SetpointBatch` are read whole (each world's modes a row
        of its stacked modes, a group's references its rows), not world by world. Worlds whose
        instances differ in options, and setpoints that are not (N, 3) float64 records, are all
        left to the per-world ``control`` (which raises for a wrong size)."""
        n = batch.pos.shape[1]
        whole = _whole(setpoints, len(models), n)
        if not cls._same_options(models, batch) or (
                whole is None and not all(map(_plain_record, setpoints, [n] * len(setpoints)))):
            return NotImplemented
        modes = [sp.mode for sp in setpoints] if whole is None else whole.mode.reshape(len(models), n)
        laws = [model.controller.steady_law(mode) if every(world.healthy) else None
                for model, world, mode in zip(models, worlds, modes, strict=True)]
        groups = {law: [b for b, own in enumerate(laws) if own == law]
                  for law in sorted({law for law in laws if law is not None})}
        groups = {law: group for law, group in groups.items() if len(group) > 1}
        if not groups:
            return NotImplemented
        for law, group in groups.items():
            cls._control_steady([models[b] for b in group], batch, [worlds[b] for b in group],
                                _references(setpoints, whole, group, n), law)
        return sorted(set(range(len(models))) - {b for group in groups.values() for b in group})

    @classmethod
    def _control_steady(cls, flock: list[Self], batch: WorldBatch, worlds: list[WorldState],
                        references: tuple[np.ndarray, np.ndarray, np.ndarray], law: int) -> None:
        """``control`` of worlds whose agents all keep law ``law``: one stacked step of the law,
        ``references`` their setpoints' stacked positions, velocities and accelerations."""
        n = batch.pos.shape[1]
        sp_pos, sp_vel, sp_acc = references
        x_I = batch.pack([getattr(model.controller, cls._LAWS[law]) for model in flock], ("x_I",),
                         key=f"double_integrator.{cls._LAWS[law]}")["x_I"]
        twin = batch.per_batch(f"double_integrator.twin.{law}", lambda: flock[0].controller.stacked(law, x_I))
        getattr(twin, cls._LAWS[law]).x_I = x_I.reshape(-1, 3)  # the slices pack() handed out this tick
        v_max = flock[0].params.v_max
        if v_max is None:
            v_ref = sp_vel
        else:  # np.clip's values, as control's
            v_ref = np.maximum(sp_vel, -v_max)
            np.minimum(v_ref, v_max, out=v_ref)
        u = twin.step_steady(
            law, np.concatenate([world.pos for world in worlds]), np.concatenate([world.vel for world in worlds]),
            sp_pos, v_ref, sp_acc, v_max)
        for model, own_u in zip(flock, u.reshape(len(flock), n, 3), strict=True):
            model.u[...] = own_u
            model._held_dt = None

    @classmethod
    def _same_options(cls, models: Sequence[Self], batch: WorldBatch) -> bool:
        """Whether the worlds' instances were built with the same options (one set of gains);
        asked once per batch, the options being frozen."""
        return bool(batch.per_batch("double_integrator.same_options",
                                    lambda: all(m.params == models[0].params for m in models)))

    def step(self, world: WorldState, dt: float) -> None:
        """r += T v + T^2/2 u, v += T u (exact for u held over the step)."""
        # r += T v + T^2/2 u, v += T u. u is held over the tick's sub-steps, so its two terms are
        # computed once per tick and dt (the same products, in the same order: the same bits).
        if self._held_dt != dt:
            self._held_dt, self._du_pos, self._du_vel = dt, 0.5 * self.u * dt * dt, self.u * dt
        move = np.multiply(world.vel, dt, out=self._move)
        move += self._du_pos
        world.pos += move
        world.vel += self._du_vel

    @classmethod
    def step_batch(cls, models: Sequence[Self], batch: WorldBatch, dt: float) -> None:
        """``step`` of B worlds at once over (B, N, 3) arrays (docs/batched.md): the same products
        in the same order as one world's, so each world gets the bits its single run gets."""
        def held() -> tuple[np.ndarray, np.ndarray]:  # T^2/2 u and T u of each world's input, stacked
            u = np.stack([model.u for model in models])
            return 0.5 * u * dt * dt, u * dt

        du_pos, du_vel = batch.per_tick(f"double_integrator.held.{dt!r}", held)
        move = batch.vel * dt
        move += du_pos
        batch.pos += move
        batch.vel += du_vel


def _whole(setpoints: Sequence[Setpoints], b: int, n: int) -> Setpoints | None:
    """A :class:`SetpointBatch`'s stacked record of B worlds of N agents where it is plain
    (:func:`_plain_record`), else ``None`` (the records are then checked one by one)."""
    whole = setpoints.whole() if isinstance(setpoints, SetpointBatch) else None
    return whole if whole is not None and _plain_record(whole, b * n) else None


def _references(setpoints: Sequence[Setpoints], whole: Setpoints | None, group: list[int],
                n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The positions, velocities and accelerations of the worlds ``group``'s setpoints, stacked
    (B' N, 3): the batch's own arrays where the group is every world, its rows where it is not,
    the records concatenated where there is no batch (the same values every way)."""
    if whole is None:
        pos, vel, acc = (np.concatenate([getattr(setpoints[b], field) for b in group])
                         for field in ("pos", "vel", "acc"))
        return pos, vel, acc
    if group == list(range(len(setpoints))):
        return whole.pos, whole.vel, whole.acc
    rows = np.concatenate([np.arange(b * n, (b + 1) * n) for b in group])
    return whole.pos[rows], whole.vel[rows], whole.acc[rows]


def _plain_record(sp: Setpoints, n: int) -> bool:
    """Whether ``sp`` commands ``n`` agents with (N,) modes and (N, 3) float64 references: what the
    stacked law reads (another dtype would be promoted differently once stacked)."""
    return sp.mode.shape == (n,) and all(a.shape == (n, 3) and a.dtype == np.float64
                                         for a in (sp.pos, sp.vel, sp.acc))


@hookimpl
def swarmscene_register_dynamics(register) -> None:
    """Add :class:`DoubleIntegrator` to the registry, so that ``dynamics=double_integrator`` chooses it."""
    register(DoubleIntegrator)
