"""``virtual_rigid_body`` formation: Zhou and Schwager's Virtual Rigid Body (VRB).

The team holds formations Pi_m (constant local positions in a body frame F_v) while F_v flies a C^4
trajectory in SE(3) through keyframes, and transforms between consecutive formations with the
Hungarian assignment plus the sine-profile transformation field and the repelling field (eq. 7-9).
Every agent gets a TRACK setpoint carrying its flat outputs from Theorems 1-2 (eq. 1-3): position,
velocity, acceleration, jerk and snap, and the body's yaw. With ``dynamics=quadrotor`` the SE(3)
controller uses them as differential-flatness feed-forward; simpler dynamics use p and v.

The algorithm lives in three modules this plugin wraps:
    vrb_trajectory.py  minimum-snap keyframe trajectory p_v(t), R_v(t) (Euler Z-Y-X) and derivatives
    vrb_transform.py   formations, assignment, the transformation law (design and proof of eq. 4-6
                       in its docstring), flat outputs of every robot
    vrb_airshow.py     the section IV air show (``preset: airshow``)

Agents are matched to the slots of Pi_1 (placed by the body pose at the start) by minimum total
squared distance, so any agent order in the swarm config works. Failed agents HOLD where they are;
the others keep flying the plan (a VRB is an open-loop plan; it does not re-plan around failures).

Metrics (``metrics.json``):
    vrb.min_transformation_distance: smallest distance between two agents, measured on the flown
        states, during transformations (m); the paper's Problem 4 bound is s_i + s_j.
    vrb.safety_distance: s_i + s_j (m). vrb.safety_holds: the measured distance never went below it.
    vrb.planned_min_transformation_distance: the same on the plan (m).
    vrb.max_switch_discontinuity: largest jump of p, v, a, jerk or snap of any agent at any of the
        2(M-1) switches, relative to max(1, |value|) (eq. 5; ~1e-15 by construction).
    vrb.tracking_rms / vrb.tracking_max: position error |p - p_ref(t)| of healthy agents at every
        guidance tick, m.
    vrb.planning_ms: mean time to plan one transformation segment (assignment + law), ms.
"""

from __future__ import annotations

import time
from typing import Any, Literal

import numpy as np
import scipy  # its submodules load on first use: registering this plugin must not import them
from pydantic import BaseModel, ConfigDict, Field, model_validator

from swarmscene.methods.shapes import shape_offsets
from swarmscene.methods.vrb.airshow import airshow_keyframes, airshow_sequence
from swarmscene.methods.vrb.trajectory import ORDER, Keyframes, VRBTrajectory
from swarmscene.methods.vrb.transform import (
    FormationSequence,
    TransformationLaw,
    plan_flight,
    robot_flat_outputs,
    switch_jumps,
)
from swarmscene.plugin import BuildContext, Formation, Mode, PluginParams, Setpoints, WorldState, hookimpl

Point3 = tuple[float, float, float]
_PLANE_AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class KeyframeSpec(_Spec):
    """One keyframe K_k of the VRB trajectory (paper Fig. 3-4); unset derivatives are free."""

    t: float = Field(ge=0, description="time, s")
    pos: Point3 = Field(description="position of the origin of F_v in the world, [x, y, z] m")
    euler_deg: Point3 = Field((0.0, 0.0, 0.0), description="[roll, pitch, yaw] of F_v, degrees, "
                              "Z-Y-X convention, unwrapped (720 = two turns)")
    vel: Point3 | None = Field(None, description="fixed velocity, m/s")
    acc: Point3 | None = Field(None, description="fixed acceleration, m/s^2")
    euler_rate_deg: Point3 | None = Field(None, description="fixed Euler-angle rates, deg/s")


class FormationSpec(_Spec):
    """One formation Pi_m: constant local positions in F_v (x forward, y left, z up)."""

    shape: Literal["start", "explicit", "line", "grid", "circle", "v", "triangle"] = Field(
        "explicit", description="start (first formation only): where the agents are at t_1, in "
        "F_v; explicit: ``positions``; else static_shape's shapes, centred")
    positions: list[Point3] = Field(default_factory=list, description="explicit slots, m")
    spacing: float = Field(0.7, gt=0, description="neighbour distance of a named shape, m")
    plane: Literal["xy", "xz", "yz"] = Field(
        "xy", description="plane of F_v holding a named shape (its forward, left axes)")
    duration: float = Field(gt=0, description="T_m, s")

    def slots(self, n: int) -> np.ndarray:
        """(n, 3) local positions (NaN for ``start``: filled in from the agents' positions)."""
        if self.shape == "start":
            return np.full((n, 3), np.nan)
        if self.shape == "explicit":
            if len(self.positions) != n:
                raise ValueError(f"formation has {len(self.positions)} positions for {n} agents")
            return np.asarray(self.positions, float)
        flat = shape_offsets(self.shape, n, self.spacing)
        out = np.zeros((n, 3))
        a, b = _PLANE_AXES[self.plane]
        out[:, a], out[:, b] = flat[:, 0], flat[:, 1]
        return out


class VirtualRigidBody(Formation):
    """Formations and transformations in a body frame flying a C^4 trajectory in SE(3)."""

    name = "virtual_rigid_body"
    metric_prefix = "vrb"

    class Params(PluginParams):
        preset: Literal["airshow", "custom"] = Field(
            "airshow", description="airshow: the paper's section IV show (3 agents, 71 s); "
            "custom: ``keyframes`` and ``formations`` below")
        keyframes: list[KeyframeSpec] = Field(default_factory=list, description="custom only")
        formations: list[FormationSpec] = Field(default_factory=list, description="custom only")
        transformation_duration: float = Field(
            3.0, gt=0, description="T^m_{m+1} of every transformation (custom), s")
        clearance: float = Field(0.3, gt=0, description="s_i, m; pair safety distance s_i + s_j")
        threshold: float = Field(0.7, gt=0, description="D, m: repelling neighbourhood (eq. 8)")
        repel_gain: float = Field(0.8, ge=0, description="B_j, m/s (eq. 8); 0 = field off")
        return_gain: float = Field(1.5, ge=0, description="k_r, 1/s: pull back to the straight path")
        max_step: float = Field(0.06, ge=1e-4, description="integration step of the law, s (at least 0.1 ms)")
        knot_spacing: float = Field(
            0.3, ge=1e-3, description="deviation spline knot spacing, s (at least 1 ms)")

        @model_validator(mode="after")
        def _preset_or_custom(self) -> VirtualRigidBody.Params:
            if self.preset == "airshow" and (self.keyframes or self.formations):
                raise ValueError("keyframes/formations are only read with preset: custom")
            if self.preset == "custom" and (len(self.keyframes) < 2 or not self.formations):
                raise ValueError("preset: custom needs >= 2 keyframes and >= 1 formation")
            if any(f.shape == "start" for f in self.formations[1:]):
                raise ValueError("formations: shape 'start' is only valid for the first formation")
            if self.threshold <= 2 * self.clearance:
                raise ValueError("threshold D must exceed s_i + s_j = 2 clearance (eq. 8)")
            return self

    params: Params

    def __init__(self, params: VirtualRigidBody.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        keyframes, sequence = self._task(params, ctx.n)
        self.trajectory = VRBTrajectory(keyframes)
        self.law = TransformationLaw(
            clearance=params.clearance, threshold=params.threshold, gain=params.repel_gain,
            k_return=params.return_gain, max_step=params.max_step, knot_spacing=params.knot_spacing)
        sequence = self._match_agents(sequence, ctx.initial.pos)
        t0 = time.perf_counter()
        self.flight = plan_flight(sequence, self.law)
        self.planning_ms = (time.perf_counter() - t0) * 1e3 / max(len(self.flight.transformations), 1)
        self.end_time = max(self.trajectory.t_end, float(self.flight.bounds[-1]))
        self._windows = np.array([(tf.t_start, tf.t_end) for tf in self.flight.transformations])
        self._err_sq_sum, self._err_count, self._err_max = 0.0, 0, 0.0
        self._min_transform_distance = np.inf

    @staticmethod
    def _task(params: VirtualRigidBody.Params, n: int) -> tuple[Keyframes, FormationSequence]:
        if params.preset == "airshow":
            seq = airshow_sequence()
            if seq.slots.shape[1] != n:
                raise ValueError(f"virtual_rigid_body preset airshow flies 3 agents (swarm.n = {n})")
            return airshow_keyframes(), seq
        kfs = sorted(params.keyframes, key=lambda k: k.t)
        derivs = np.full((len(kfs), ORDER, 6), np.nan)
        for i, k in enumerate(kfs):
            for order, value, cols in ((1, k.vel, slice(0, 3)), (2, k.acc, slice(0, 3)),
                                       (1, k.euler_rate_deg, slice(3, 6))):
                if value is not None:
                    scale = np.pi / 180.0 if cols.start == 3 else 1.0
                    derivs[i, order - 1, cols] = np.asarray(value) * scale
        keyframes = Keyframes(
            t=np.array([k.t for k in kfs]), pos=np.array([k.pos for k in kfs], float),
            euler=np.radians([k.euler_deg for k in kfs]), derivs=derivs)
        m = len(params.formations)
        seq = FormationSequence(
            slots=np.stack([f.slots(n) for f in params.formations]),
            durations=np.array([f.duration for f in params.formations]),
            transitions=np.full(m - 1, params.transformation_duration), t1=float(keyframes.t[0]))
        return keyframes, seq

    def _match_agents(self, seq: FormationSequence, start: np.ndarray) -> FormationSequence:
        """Reorder Pi_1's slots so that agent i takes the slot nearest its start (Hungarian);
        a ``start`` formation is the agents' own positions expressed in F_v at t_1."""
        body = self.trajectory.evaluate(seq.t1)
        if np.isnan(seq.slots[0]).any():
            slots = np.array(seq.slots, copy=True)
            slots[0] = (start - body.p[0, 0]) @ body.R[0, 0]  # R_v^T (p_i - p_v), eq. 1 inverted
            return FormationSequence(slots, seq.durations, seq.transitions, seq.t1)
        world_slots = body.p[0, 0] + seq.slots[0] @ body.R[0, 0].T
        cost = np.sum((start[:, None, :] - world_slots[None, :, :]) ** 2, axis=-1)
        _, cols = scipy.optimize.linear_sum_assignment(cost)
        slots = np.array(seq.slots, copy=True)
        slots[0] = seq.slots[0][cols]
        return FormationSequence(slots, seq.durations, seq.transitions, seq.t1)

    def setpoints(self, world: WorldState, sensing) -> Setpoints:
        """Each robot's flat outputs (position and derivatives up to snap) at time t, as TRACK
        setpoints; records the tracking error for the run's metrics."""
        fo = robot_flat_outputs(self.trajectory, self.flight, world.t)
        p = fo.p[:, 0]  # (5, N, 3) at this tick
        err = np.linalg.norm(world.pos - p[0], axis=1)[world.healthy]
        if err.size:
            self._err_sq_sum += float(np.sum(err * err))
            self._err_count += err.size
            self._err_max = max(self._err_max, float(err.max()))
        live = world.healthy
        track = live[:, None]
        return Setpoints(  # failed agents HOLD where they are, with no feed-forward
            mode=np.where(live, Mode.TRACK, Mode.HOLD).astype(np.int8),
            pos=np.where(track, p[0], world.pos),
            vel=np.where(track, p[1], 0.0),
            acc=np.where(track, p[2], 0.0),
            yaw=fo.yaw[0, 0].copy(),
            jerk=np.where(track, p[3], 0.0),
            snap=np.where(track, p[4], 0.0),
        )

    def complete(self, world: WorldState) -> bool:
        """True once the last transformation has ended."""
        return world.t >= self.end_time

    @hookimpl
    def swarmscene_step_end(self, sim: Any) -> None:
        """During a transformation: the smallest inter-agent distance seen (what s_ij must bound)."""
        t = sim.world.t
        if self._windows.size and np.any((self._windows[:, 0] <= t) & (t <= self._windows[:, 1])):
            nearest, _ = sim.sensing.nearest
            if nearest.size:
                self._min_transform_distance = min(self._min_transform_distance, float(nearest.min()))

    @staticmethod
    def describe_verdict(key: str, m: dict[str, Any]) -> str | None:
        """The limit and scope of ``vrb.safety_holds`` for the run summary (swarmscene/views/summary.py)."""
        if key != "vrb.safety_holds":
            return None
        measured = m.get("vrb.min_transformation_distance")
        if measured is None:
            return "n/a: no transformation flown, Problem 4's bound has nothing to check"
        return (f"min {measured:.3g} m vs s_i + s_j = 2 formation.clearance = "
                f"{m['vrb.safety_distance']:.3g} m (Problem 4), "
                "nearest pairs in 3-D, every guidance tick during transformations only (formations held "
                "between them: the separation line)")

    @hookimpl
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """The ``vrb.`` metrics: the transformations' smallest distance against s_ij = 2 clearance
        (Problem 4), the largest jump of the flat outputs at a switch, the tracking error, the
        planning time."""
        jumps = switch_jumps(self.trajectory, self.flight)  # (switches, 5)
        ts = self.flight.switch_times
        scale = np.abs(robot_flat_outputs(self.trajectory, self.flight, ts).p).max(axis=(2, 3)).T
        s_ij = 2.0 * self.params.clearance
        measured = self._min_transform_distance
        metrics["vrb.min_transformation_distance"] = float(measured) if np.isfinite(measured) else None
        metrics["vrb.safety_distance"] = s_ij
        metrics["vrb.safety_holds"] = bool(not np.isfinite(measured) or measured >= s_ij)
        metrics["vrb.planned_min_transformation_distance"] = (
            self.flight.min_transformation_distance() if self.flight.transformations else None)
        metrics["vrb.max_switch_discontinuity"] = (
            float(np.max(jumps / np.maximum(scale, 1.0))) if jumps.size else 0.0)
        metrics["vrb.tracking_rms"] = (
            float(np.sqrt(self._err_sq_sum / self._err_count)) if self._err_count else None)
        metrics["vrb.tracking_max"] = self._err_max if self._err_count else None
        metrics["vrb.planning_ms"] = self.planning_ms


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Add :class:`VirtualRigidBody` to the registry, so that ``formation=virtual_rigid_body`` chooses it."""
    register(VirtualRigidBody)
