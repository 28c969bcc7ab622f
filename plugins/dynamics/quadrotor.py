"""``quadrotor`` dynamics: 6-DOF rigid bodies (thesis eq. 3.4-3.16) under an SE(3) controller.

Per guidance tick, :meth:`Quadrotor.control` turns the setpoints into references for the geometric
tracking controller of Lee, Leok and McClamroch (2010) with differential-flatness feed-forward
(Mellinger and Kumar 2011); per physics step, :meth:`Quadrotor.step` runs that controller (thrust and
torque), the inverse mixer with rotor-speed limits (eq. 3.16) and one RK4 step of the rigid body.
Each is one compiled call over all agents (methods/quadrotor/kernels.py; numba, cached beside the
module, imported when the plugin is built; the physics step runs the agents as SIMD lanes); see
methods/quadrotor/model.py for frames (world z up, body front-left-up; the thesis' NED/FRD
equations are converted there).

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
methods/quadrotor/model.py) joins the RK4 right-hand side, and with ``moment_arm`` h the moment
(0, 0, h) x F_body joins the rotors' torque. The force phase's ``world.force`` (downwash, ground
effect, drag, a battery's limit) joins the RK4 right-hand side the same way
(``force_coupling = "integrated"``), held over the physics step.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from itertools import repeat
from typing import Literal, Self

import numpy as np
from pydantic import Field, model_validator

from swarmscene.methods.quadrotor.flatness import heading_vector
from swarmscene.methods.quadrotor.model import AIRFRAMES, quat_to_rotmat, yaw_to_quat
from swarmscene.methods.quadrotor.se3_controller import se3_gains
from swarmscene.plugin import (
    BuildContext,
    Dynamics,
    PluginParams,
    SetpointBatch,
    Setpoints,
    WorldBatch,
    WorldState,
    hookimpl,
)


class Quadrotor(Dynamics):
    """Rigid-body quadrotors with rotor-level inputs and an SE(3) tracking controller."""

    name = "quadrotor"
    has_attitude = True
    wind_coupling = "integrated"
    force_coupling = "integrated"
    rotors = 4

    class Params(PluginParams):
        airframe: Literal["crazyflie", "m330"] = Field(
            "crazyflie",
            description="crazyflie: 27 g nano quad (Foerster 2015 identification); m330: ~1 kg, "
            "330 mm quad of the CEM paper's class (assumed parameters, see methods/quadrotor/model.py)",
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
        dtype: Literal["float64", "float32"] = Field(
            "float64",
            description="precision of the physics step's arithmetic (the SE(3) law, the mixer and "
            "RK4). float32: the state is rounded to float32 on its way into each physics step and "
            "the step computes in float32 (the engine's arrays, the reference latch and the metrics "
            "stay float64); 1.2-2.6x as fast (8 agents per SIMD instruction instead of 4); "
            "positions off float64's by 0.4 um to 30 um over 6-71 s "
            "of the presets near the origin, ~0.5 mm in a flock 100 m out, where float32 resolves "
            "7.6 um (docs/batched.md)")
        threads: int | None = Field(
            1, ge=1, description="threads of the physics step when it steps at least 1,024 agents "
            "(one large swarm, or the worlds of a batch together): each thread steps a share of "
            "the agents, and every agent gets the bits it gets with one thread; null: every thread "
            "numba may start (NUMBA_NUM_THREADS, by default the cores). 1 (the default) leaves the "
            "other cores to a sweep's workers")

        @model_validator(mode="after")
        def _inner_loop_resolved(self) -> Quadrotor.Params:
            # the attitude loop is discrete at max_step: keep omega dt well below its stability edge
            if self.attitude_omega * self.max_step > 0.5:
                raise ValueError(
                    f"attitude_omega * max_step must be <= 0.5 for a stable discrete attitude loop "
                    f"(got {self.attitude_omega} * {self.max_step})")
            return self

    params: Params

    def __init__(self, params: Quadrotor.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        # numba is imported here, not at module level: listing plugins must not pay for it
        from swarmscene.methods.quadrotor import kernels

        self._kernels = kernels
        af = self.airframe = AIRFRAMES[params.airframe]
        self.gains = se3_gains(af, params.position_omega, params.position_xi,
                               params.attitude_omega, params.attitude_xi, params.yaw_omega)
        self.max_tilt = math.radians(params.max_tilt)
        lo, hi = af.rotor_speed_min**2, af.rotor_speed_max**2
        # the physics step's constants, in its precision (their type chooses the compiled step)
        precision = self._precision = np.dtype(params.dtype).type
        self._constants = {
            name: np.ascontiguousarray(value, dtype=precision) if np.ndim(value) else precision(value)
            for name, value in dict(
                mass=af.mass, J=af.J, gyro=af.gyro, k_x=self.gains.k_x, k_v=self.gains.k_v, k_R=self.gains.k_R,
                k_Omega=self.gains.k_Omega, tan_max_tilt=np.tan(self.max_tilt), min_lift=MIN_LIFT,
                mixer=af.mixer, mixer_inverse=af.mixer_inverse, thrust_min=4.0 * af.k_T * lo,
                thrust_max=4.0 * af.k_T * hi, w2_min=lo, w2_max=hi, drag=af.drag).items()}
        self._drag = _floats(af.drag)

    # -- lifecycle ---------------------------------------------------------------------------
    def initialize(self, world: WorldState) -> None:
        """Attitude level and yawed to 0, at rest, every rotor at hover speed; all rotors healthy."""
        n = world.n
        world.quat = yaw_to_quat(np.zeros(n))
        world.omega = np.zeros((n, 3))
        world.rotor_speed = np.full((n, 4), self.airframe.hover_rotor_speed)
        self.rotor_health: np.ndarray | None = None  # (N, 4) thrust kept, allocated at a failure
        self._allocate(n)
        self.control(world, Setpoints.hold(world.pos))

    def _allocate(self, n: int) -> None:
        """The kernels' per-agent arrays (they write in place and do not check sizes)."""
        self._rotor_gain = np.ones((n, 4)) if self.rotor_health is None else np.sqrt(self.rotor_health)
        self._zeros = np.zeros((n, 3))
        # this tick's references (p_d, v_d, a_d), Taylor coefficients and flatness feed-forward
        self._p, self._v, self._a, self._dv, self._da, self._dj, self._ds, self._omega_d, self._alpha_d = (
            np.zeros((n, 3)) for _ in range(9))
        self._heading = np.zeros((n, 3))  # (cos psi, sin psi, 0), written by control
        self._position_mask = np.ones(n, dtype=bool)

    def control(self, world: WorldState, sp: Setpoints) -> None:
        """Latch this tick's references (zero-order hold, or Taylor propagation in TRACK mode) and
        their flatness feed-forward, in one compiled call (:func:`kernels.latch_references`)."""
        if self._p.shape[0] != world.n or sp.pos.shape[0] != world.n:
            if sp.pos.shape[0] != world.n:
                raise ValueError(f"quadrotor: {sp.pos.shape[0]} setpoints for {world.n} agents")
            self._allocate(world.n)
        self._heading[:] = heading_vector(np.asarray(sp.yaw, dtype=float))  # in place: see _REFERENCES
        # constant acceleration and heading (no jerk, no snap): the flat body rates are zero
        self._feedforward = sp.jerk is not None or sp.snap is not None
        self._kernels.latch_references(
            world.healthy, np.asarray(sp.mode, dtype=np.int8), _floats(sp.pos), _floats(sp.vel),
            _floats(sp.acc), self._zeros if sp.jerk is None else _floats(sp.jerk),
            self._zeros if sp.snap is None else _floats(sp.snap), _floats(world.pos), self._heading,
            self.params.propagate_reference, self._feedforward,
            self._p, self._v, self._a, self._dv, self._da, self._dj, self._ds, self._position_mask,
            self._omega_d, self._alpha_d)
        self._clock = _Clock()

    def step(self, world: WorldState, dt: float) -> None:
        """Advance the rigid bodies by ``dt`` (in sub-steps of at most ``max_step``), all agents in
        one compiled call (:func:`kernels.step_swarm`)."""
        substeps = max(1, math.ceil(dt / self.params.max_step - 1e-9))
        wind, force = world.wind, world.force
        kernel, split = _stepper(self._kernels, self.params.threads, world.n)
        # a new clock, not this one advanced: it may be the batch's this world was controlled in
        self._clock = _Clock(kernel(
            world.pos, world.vel, world.quat, world.omega, world.rotor_speed,
            self._p, self._v, self._a, self._dv, self._da, self._dj, self._ds, self._heading,
            self._position_mask, self._omega_d, self._alpha_d, self._feedforward,
            self._clock.tau, dt / substeps, substeps, rotor_gain=self._rotor_gain,
            wind=self._zeros if wind is None else _floats(wind), has_wind=wind is not None,
            arm=self._precision(world.wind_moment_arm),
            force=self._zeros if force is None else _floats(force), has_force=force is not None,
            **self._constants, **split))

    _REFERENCES = ("_p", "_v", "_a", "_dv", "_da", "_dj", "_ds", "_heading", "_position_mask",
                   "_omega_d", "_alpha_d", "_rotor_gain")
    """The per-agent arrays ``step`` hands the kernel besides the state (latched by ``control``).
    Only ``_allocate`` rebinds them, all at once (``control`` and the rotor-fault event write in
    place), so a batch checks one of them to know the instances still hold their slices
    (``WorldBatch.pack(..., together=True)``); a subclass that overrides one of these three is
    checked name by name (:func:`_packed_references`)."""

    @classmethod
    def control_batch(cls, models: Sequence[Self], batch: WorldBatch, worlds: Sequence[WorldState],
                      setpoints: Sequence[Setpoints]) -> object:
        """``control`` of B worlds in one compiled call over their B x N agents (docs/batched.md).

        :func:`kernels.latch_references` latches agents independently, so the worlds' setpoints,
        stacked along the world axis, are one swarm's; the references are written into the arrays
        :meth:`WorldBatch.pack` holds for :meth:`step_batch` (each instance holds its slice, as if
        its own ``control`` had written it). The heading vectors are computed over the stacked
        yaws by the same elementwise numpy code as ``control`` (tests/test_batch.py holds its bits
        to the per-world ones at every length). The instances share one :class:`_Clock`, and the
        packed references are latched for the tick's :meth:`step_batch` (:meth:`WorldBatch.latch`),
        so that its sub-steps touch no instance. Setpoints given as a
        :class:`~swarmscene.core.setpoint.SetpointBatch` are read whole, not stacked again (the
        same bits). Worlds whose instances differ in options, or whose setpoints differ in
        carrying feed-forward (jerk or snap), are left to the per-world ``control``; so is a
        setpoint record of the wrong size (the world's ``control`` raises)."""
        first = models[0]
        b, n = batch.pos.shape[:2]
        whole = _whole(setpoints, b * n)
        head = setpoints[0] if whole is None else whole
        feedforward = head.jerk is not None or head.snap is not None
        if (whole is None and not _setpoints_agree(setpoints, n, feedforward)) or not cls._same_options(models, batch):
            return NotImplemented
        clock = _Clock()
        ref = _packed_references(cls, models, batch, clock)
        zeros = ref["zeros"]
        sp = _stacked_record(setpoints, zeros, feedforward) if whole is None else whole
        ref["_heading"][:] = heading_vector(sp.yaw)
        own = len(worlds) == len(batch.worlds) and all(map(operator.is_, worlds, batch.worlds))
        pos = batch.pos.reshape(b * n, 3) if own else _stacked([w.pos for w in worlds])
        first._kernels.latch_references(
            np.concatenate([w.healthy for w in worlds]), sp.mode, sp.pos, sp.vel, sp.acc,
            zeros if sp.jerk is None else sp.jerk, zeros if sp.snap is None else sp.snap,
            pos, ref["_heading"], first.params.propagate_reference, feedforward,
            ref["_p"], ref["_v"], ref["_a"], ref["_dv"], ref["_da"], ref["_dj"], ref["_ds"], ref["_position_mask"],
            ref["_omega_d"], ref["_alpha_d"])
        for model in models:
            model._feedforward = feedforward
            model._clock = clock
        batch.latch("quadrotor.references", ref)
        return None

    @classmethod
    def _same_options(cls, models: Sequence[Self], batch: WorldBatch) -> bool:
        """Whether the worlds' instances were built with the same options (their kernels then take
        one set of gains); asked once per batch, the options being frozen."""
        return bool(batch.per_batch("quadrotor.same_options",
                                    lambda: all(m.params == models[0].params for m in models)))

    @classmethod
    def step_batch(cls, models: Sequence[Self], batch: WorldBatch, dt: float) -> object:
        """``step`` of B worlds in one compiled call over their B x N agents (docs/batched.md).

        The kernel steps agents independently, so B worlds of N agents are one swarm of B N
        agents: the state is the batch's, the references each instance latched are packed along
        the world axis (:meth:`WorldBatch.pack`), and each agent's arithmetic is its single
        run's; the instances' shared :class:`_Clock` advances once for all. Worlds whose instances
        differ in options, or whose ticks are not in step (their time since the tick, or
        feed-forward, differs), or whose wind and force models differ, are left to the per-world
        steps."""
        first = models[0]
        b, n = batch.pos.shape[:2]
        ref = batch.per_tick("quadrotor.references", lambda: cls._references(models, batch))
        if ref is not None and ref["clock"] is not first._clock:
            # not this tick's: a driver that skipped controlled(), or called it before the controllers
            ref = cls._references(models, batch)
        if ref is None or not batch.per_tick("quadrotor.forces_agree", lambda: _forces_agree(batch.worlds)):
            return NotImplemented
        assert batch.quat is not None and batch.omega is not None and batch.rotor_speed is not None
        zeros = ref["zeros"]
        worlds = batch.worlds
        has_wind, has_force = worlds[0].wind is not None, worlds[0].force is not None
        substeps = max(1, math.ceil(dt / first.params.max_step - 1e-9))
        kernel, split = _stepper(first._kernels, first.params.threads, b * n)
        ref["clock"].tau = kernel(
            batch.pos.reshape(b * n, 3), batch.vel.reshape(b * n, 3), batch.quat.reshape(b * n, 4),
            batch.omega.reshape(b * n, 3), batch.rotor_speed.reshape(b * n, 4),
            ref["_p"], ref["_v"], ref["_a"], ref["_dv"], ref["_da"], ref["_dj"], ref["_ds"], ref["_heading"],
            ref["_position_mask"], ref["_omega_d"], ref["_alpha_d"], first._feedforward,
            ref["clock"].tau, dt / substeps, substeps, rotor_gain=ref["_rotor_gain"],
            wind=_floats(batch.stack("wind")).reshape(b * n, 3) if has_wind else zeros, has_wind=has_wind,
            arm=first._precision(worlds[0].wind_moment_arm),
            force=_floats(batch.stack("force")).reshape(b * n, 3) if has_force else zeros, has_force=has_force,
            **first._constants, **split)
        return None

    @classmethod
    def _references(cls, models: Sequence[Self], batch: WorldBatch) -> dict | None:
        """The tick's latched references of every world as (B N, k) arrays and the instances'
        shared clock, when ``control_batch`` did not latch them (the worlds ran their own
        ``control``); None when the worlds cannot be one swarm (their options, time since the
        tick or feed-forward differ)."""
        first = models[0]
        if not cls._same_options(models, batch) or any(m._feedforward != first._feedforward for m in models):
            return None
        clock = first._clock
        if not all(m._clock is clock for m in models):
            if any(m._clock.tau != clock.tau for m in models):
                return None
            clock = _Clock(clock.tau)
            for model in models:
                model._clock = clock
        return _packed_references(cls, models, batch, clock)

    @hookimpl
    def swarmscene_event(self, sim, event) -> None:
        """A rotor fault (a kind declaring ``rotor_fault``: ``motor_failure``): rotor ``event.rotor``
        of the event's agents keeps ``event.fraction`` of its thrust."""
        if not event.behaviour.rotor_fault:
            return
        if self.rotor_health is None:
            self.rotor_health = np.ones((sim.world.n, 4))
        self.rotor_health[list(event.agents), event.rotor] = event.fraction
        self._rotor_gain[:] = np.sqrt(self.rotor_health)  # in place: see _REFERENCES

    def wind_acceleration(self, world: WorldState) -> np.ndarray:
        """The wind's force per mass a = R D R^T w (N, 3) world (``step`` integrates it itself)."""
        # initialize() set the attitude; the kernel asks for this only when a wind model is declared
        assert world.quat is not None and world.wind is not None
        R = quat_to_rotmat(world.quat)
        f_body = np.einsum("nji,nj->ni", R, world.wind) * self._drag
        return np.einsum("nij,nj->ni", R, f_body)


MIN_LIFT = 0.2
"""The desired force keeps at least this fraction of m g upwards (se3_controller.py)."""

PARALLEL_MIN_AGENTS = 1024
"""Agents (of one world, or of a batch's worlds together) from which ``threads`` > 1 steps them in
parallel: a physics step costs ~0.08 us an agent (SIMD lanes), starting the threads some tens of us
(2 threads: 1.4x at 1,024 agents, 1.8x at 10,000; docs/batched.md)."""


class _Clock:
    """tau, the time since the references were latched, s (the kernel propagates TRACK references
    by it). Each instance holds one; ``control_batch`` gives a batch's instances one, which
    ``step_batch`` advances once a physics step for all (a float per instance would be B writes a
    step). ``step`` gives its instance a new one rather than advance it, so that a world stepped on
    its own after a batched ``control`` leaves the others' clock alone."""

    __slots__ = ("tau",)

    def __init__(self, tau: float = 0.0) -> None:
        self.tau = tau


def _packed_references(cls: type[Quadrotor], models: Sequence[Quadrotor], batch: WorldBatch,
                       clock: _Clock) -> dict:
    """The instances' ``_REFERENCES`` packed along the world axis as (B N, k) arrays, with zeros
    (B N, 3) for the kernel's absent inputs and the instances' shared clock: what the tick's
    steps read. Checked by one name where the class keeps the references' in-place rule."""
    in_place = all(getattr(cls, method) is getattr(Quadrotor, method)
                   for method in ("_allocate", "control", "swarmscene_event"))
    packed = batch.pack(list(models), cls._REFERENCES, together=in_place)
    b, n = batch.pos.shape[:2]
    return {"zeros": np.zeros((b * n, 3)), "clock": clock,
            **{name: a.reshape(b * n, *a.shape[2:]) for name, a in packed.items()}}


def _setpoints_agree(setpoints: Sequence[Setpoints], n: int, feedforward: bool) -> bool:
    """Whether every setpoint record is for ``n`` agents and carries feed-forward (jerk or snap)
    if and only if ``feedforward`` (C loops in the common case, none carrying it: a batch of
    4,096 one-agent worlds asks this every tick)."""
    if set(map(len, map(operator.attrgetter("pos"), setpoints))) != {n}:
        return False
    if feedforward:
        return all(sp.jerk is not None or sp.snap is not None for sp in setpoints)
    return _nones(setpoints, "jerk") == _nones(setpoints, "snap") == len(setpoints)


def _nones(items: Sequence[object], name: str) -> int:
    """How many of ``items`` have ``None`` as ``name``."""
    return sum(map(operator.is_, map(operator.attrgetter(name), items), repeat(None)))


def _forces_agree(worlds: Sequence[WorldState]) -> bool:
    """Whether the worlds can be stepped in one kernel call, which takes one wind moment arm and
    one say on whether there is wind and force for all."""
    count = len(worlds)
    return (len(set(map(operator.attrgetter("wind_moment_arm"), worlds))) == 1
            and _nones(worlds, "wind") in (0, count) and _nones(worlds, "force") in (0, count))


def _stepper(kernels, threads: int | None, agents: int) -> tuple:
    """The kernel that steps ``agents`` agents with ``threads`` threads (``Quadrotor.Params``), and
    its extra argument: :func:`kernels.step_swarm` on one thread, or
    :func:`kernels.step_swarm_parallel` with one share of the agents per thread (the threads set
    for the call; at most numba's own count, ``NUMBA_NUM_THREADS``)."""
    if threads == 1 or agents < PARALLEL_MIN_AGENTS:
        return kernels.step_swarm, {}
    import numba  # already loaded by the kernels

    most = int(numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]  # set when numba loads
    count = min(threads or most, most)
    if count <= 1:
        return kernels.step_swarm, {}
    numba.set_num_threads(count)
    return kernels.step_swarm_parallel, {"chunks": count}


def _stacked(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """The worlds' (N, k) arrays stacked (B N, k) in float64, each converted as ``_floats`` does."""
    return np.concatenate(arrays, dtype=np.float64, casting="unsafe")


def _stacked_or_zeros(arrays: Sequence[np.ndarray | None], zeros: np.ndarray) -> np.ndarray:
    """:func:`_stacked` where a world's ``None`` (no jerk, no snap) reads as zeros, as in
    ``control``; ``zeros`` (B N, 3) itself when every world's is ``None``."""
    if all(a is None for a in arrays):
        return zeros
    n = zeros.shape[0] // len(arrays)
    return _stacked([zeros[:n] if a is None else a for a in arrays])


def _whole(setpoints: Sequence[Setpoints], rows: int) -> Setpoints | None:
    """A :class:`SetpointBatch`'s stacked record of ``rows`` agents in the dtypes and layout the
    kernels take (what :func:`_stacked_record` makes of B records; no copy where they already
    are), or ``None``: not a batch, a world's record replaced, or the wrong size (the per-world
    path then checks and raises)."""
    whole = setpoints.whole() if isinstance(setpoints, SetpointBatch) else None
    if whole is None:
        return None
    if (any(np.shape(a) != (rows,) for a in (whole.mode, whole.yaw))
            or any(np.shape(a) != (rows, 3) for a in (whole.pos, whole.vel, whole.acc))
            or any(a is not None and np.shape(a) != (rows, 3) for a in (whole.jerk, whole.snap))):
        return None
    return Setpoints(np.ascontiguousarray(whole.mode, dtype=np.int8), _floats(whole.pos), _floats(whole.vel),
                     _floats(whole.acc), _floats(whole.yaw), None if whole.jerk is None else _floats(whole.jerk),
                     None if whole.snap is None else _floats(whole.snap))


def _stacked_record(setpoints: Sequence[Setpoints], zeros: np.ndarray, feedforward: bool) -> Setpoints:
    """B worlds' records stacked into one of B N agents (float64, int8 modes, each converted as
    ``_floats`` does); a world's missing jerk or snap reads as zeros, as in ``control``."""
    return Setpoints(
        np.concatenate([sp.mode for sp in setpoints], dtype=np.int8, casting="unsafe"),
        _stacked([sp.pos for sp in setpoints]), _stacked([sp.vel for sp in setpoints]),
        _stacked([sp.acc for sp in setpoints]),
        np.concatenate([sp.yaw for sp in setpoints], dtype=np.float64, casting="unsafe"),
        _stacked_or_zeros([sp.jerk for sp in setpoints], zeros) if feedforward else None,
        _stacked_or_zeros([sp.snap for sp in setpoints], zeros) if feedforward else None)


def _floats(a) -> np.ndarray:
    """A C-contiguous float64 array (a no-op for the engine's arrays), so the kernels compile once."""
    return np.ascontiguousarray(a, dtype=np.float64)


@hookimpl
def swarmscene_register_dynamics(register) -> None:
    """Add :class:`Quadrotor` to the registry, so that ``dynamics=quadrotor`` chooses it."""
    register(Quadrotor)
