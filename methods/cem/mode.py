"""Containment Exclusion Mode over a run: which vehicles failed, each activation (Algorithm 1 lines
5-10), the guidance tick (lines 12-22), the hand-back, the theorems' preconditions and the ``cem.*``
metrics (Romano, Uppaluru, Rastgoftar, Atkins, papers/cem-fluid-flow-navigation.md).

The ``cem`` avoidance plugin (``swarmscene.plugins.avoidance.cem``) adapts this class to the
engine: its options become :class:`Settings`, a ``hover`` or ``motor_failure`` event calls
:meth:`ContainmentExclusionMode.fail`, the avoidance step :meth:`~ContainmentExclusionMode.command`,
the step-end hook :meth:`~ContainmentExclusionMode.measure` and the run-end hook
:meth:`~ContainmentExclusionMode.metrics`. The plugin's docstring gives the choices made where the
paper is silent (flight direction, failures at different times, several failures, hand-back) with
their measured effects, and the metrics.

Symbols: a_f the failed vehicle's no-fly radius, a_p = a_f + delta + eps the planned exclusion radius
(eq. 4), delta the tracking-error bound, eps the vehicle's enclosing radius, z_f a failed vehicle's
x-y centre, theta the flight direction (rad, counter-clockwise from world +x), mu_f the doublet
strengths of eq. 1, N_f the number of failed vehicles.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState

from .flow import CEMNavigator, Theorem1Check, Theorem2Check, planned_exclusion_radius
from .handback import HandBack, SafetyRecord

MULTI_FAILURE_FLOWS = ("ring_streamlines", "unit_doublets", "summed")
"""``multi_failure_flow``: the readings of eq. 1 with several failures, the default first."""

AUTO_SPEED = 0.05
"""m/s: under ``direction="auto"``, the least mean speed of the healthy agents whose heading is the
flight direction (slower, the bearing to the failures is taken)."""

_TRACK = int(Mode.TRACK)


def flight_direction(direction: float | str, vel_xy: np.ndarray, pos_xy: np.ndarray, failed_xy: np.ndarray) -> float:
    """Flight direction theta, rad, at an activation.

    Args:
        direction: degrees from world +x (counter-clockwise), or ``"auto"``: the heading of the
            healthy agents' mean velocity when it is at least :data:`AUTO_SPEED`, else the bearing
            from their centroid to the failed vehicles' centroid (a swarm at rest is taken to be
            heading for the failure in front of it), else 0.
        vel_xy: (H, 2) m/s, the healthy agents' x-y velocities.
        pos_xy: (H, 2) m, their x-y positions.
        failed_xy: (F, 2) m, the failed vehicles' centres z_f.
    """
    if direction != "auto":
        return math.radians(float(direction))
    v = vel_xy.mean(axis=0) if len(vel_xy) else np.zeros(2)
    if np.hypot(*v) >= AUTO_SPEED:
        return math.atan2(v[1], v[0])
    b = failed_xy.mean(axis=0) - pos_xy.mean(axis=0)
    return math.atan2(b[1], b[0]) if np.hypot(*b) > 0 else 0.0


def failure_strengths(rule: str, a_p: float, n_failures: int) -> np.ndarray | None:
    """Doublet strengths mu_f (N_f,) complex, m^2, of ``multi_failure_flow`` ``rule`` (None: the
    navigator solves them, ``"ring_streamlines"``: :func:`swarmscene.methods.cem.flow.doublet_strengths`).

    ``"unit_doublets"``: mu_f = a_p^2 each. ``"summed"`` is eq. 1 divided by N_f: scaling f by a
    constant keeps its streamlines, and line 20 of Algorithm 1 rescales the sliding step, so only
    mu_f = a_p^2 / N_f remains. With one failure every rule is eq. 1 exactly.
    """
    if rule == "ring_streamlines":
        return None
    a2 = a_p**2
    return np.full(n_failures, a2 if rule == "unit_doublets" else a2 / n_failures, dtype=complex)


@dataclass(frozen=True)
class Settings:
    """The options of Containment Exclusion Mode (the ``cem`` plugin's ``Params``, resolved).

    Attributes:
        K: sliding-step passes per tick (Algorithm 1 line 14).
        newton_iterations: Newton iterations n of CalcXY (Algorithm 2).
        sigma: saddle noise deviation, m (eq. 6).
        saddle_noise: when CalcXY draws eq. 6's noise (``flow.NOISE_RULES``).
        newton_stop: when CalcXY's Newton loop stops (``flow.NEWTON_STOPS``).
        branch_guard: move a command that converged inside a planned disk out through its circle.
        multi_failure_flow: eq. 1 with several failures (:data:`MULTI_FAILURE_FLOWS`).
        v_des: desired speed of the fastest agent, m/s.
        eps: vehicle enclosing radius epsilon, m.
        delta: bound on tracking error delta, m.
        a_f: failed vehicle's no-fly radius, m.
        direction: flight direction, degrees from world +x, or ``"auto"`` (:func:`flight_direction`).
        hand_back: return control to the formation (False: CEM keeps it to the end of the run).
        hand_back_rule: ``"clear_path"`` or ``"passed"`` (:class:`~swarmscene.methods.cem.handback.HandBack`).
        handback_distance: along-track distance past the last failure to hand back, m (None: 2 a_p).
    """

    K: int
    newton_iterations: int
    sigma: float
    saddle_noise: str
    newton_stop: str
    branch_guard: bool
    multi_failure_flow: str
    v_des: float
    eps: float
    delta: float
    a_f: float
    direction: float | str
    hand_back: bool
    hand_back_rule: str
    handback_distance: float | None

    @property
    def a_p(self) -> float:
        """Planned exclusion radius a_p = a_f + delta + eps (eq. 4), m."""
        return planned_exclusion_radius(self.a_f, self.delta, self.eps)


class ContainmentExclusionMode:
    """CEM over one run: inactive until a vehicle fails, then the healthy agents' commands.

    Args:
        n: number of agents.
        settings: the options (:class:`Settings`).
        dT: guidance period, s (Algorithm 1's Delta T).
        rng: the run's generator (eq. 6's noise).

    Attributes:
        a_f, a_p: the failed vehicle's no-fly radius and the planned exclusion radius (eq. 4), m.
        hand_back: when control returns to the formation (:class:`HandBack`).
        record: the running extremes behind the safety metrics (:class:`SafetyRecord`).
        nav: the navigator of the current (last) activation, None before the first.
        active: CEM commands the healthy agents.
        failed: failed agent -> its x-y centre z_f, m (where it was when it failed, Assumption 3).
        healthy_idx: (H,) the agents under CEM, in navigator order.
        theorem1, theorem2: each activation's Theorem 1 (eq. 7-8) and Theorem 2 (eq. 16) check.
        handback_time: s, the last hand-back (None: CEM holds control).
        start_inside: healthy agents found inside a_p at an activation.
    """

    def __init__(self, n: int, settings: Settings, dT: float, rng: np.random.Generator) -> None:
        s = self.settings = settings
        self.dT, self.rng = dT, rng
        self.a_f = s.a_f
        self.a_p = s.a_p
        distance = s.handback_distance if s.handback_distance is not None else 2 * self.a_p
        self.hand_back = HandBack(s.hand_back, s.hand_back_rule, distance, self.a_p, s.v_des)
        self.record = SafetyRecord(n, self.a_f, self.a_p, s.delta, s.eps)
        self.nav: CEMNavigator | None = None
        self.active = False
        self.healthy_idx = np.zeros(0, dtype=int)
        self.failed: dict[int, np.ndarray] = {}
        self.theorem1: list[Theorem1Check] = []
        self.theorem2: list[Theorem2Check] = []
        self.handback_time: float | None = None
        self._last_sp: Setpoints | None = None  # the formation's setpoints of this tick (measured after hand-back)
        self.start_inside = 0
        self._step_s: list[float] = []
        self._iters_done = (0, 0)  # (Newton iterations, ticks) of navigators replaced by a re-activation
        self._commanded = False  # CEM produced this tick's commands (measure at step end)

    # ---- activation -------------------------------------------------------------------------

    def fail(self, agents: Any, world: WorldState) -> None:
        """``agents`` failed (they hold where they are, Assumption 3): doublets from now on, and
        CEM (re)activated around every failed vehicle so far."""
        for a in agents:
            self.failed.setdefault(int(a), world.pos[a, :2].copy())
        self.activate(world)

    def activate(self, world: WorldState) -> None:
        """Algorithm 1 lines 5-10 for the healthy agents around every failed vehicle so far.

        A later activation (a new failure, or a formation setpoint that came within a_p after a
        hand-back while CEM was on) keeps the running flow's direction and origin, and the agents
        already under CEM restart from their current commands (no jump)."""
        healthy = np.flatnonzero(world.healthy)
        if not self.failed or healthy.size == 0:
            self.active = False
            return
        failed_xy = np.array(list(self.failed.values()))
        start = world.pos[healthy, :2].copy()
        theta, origin = None, None
        if self.active and self.nav is not None:  # a later failure: continue from the commands
            theta, origin = self.nav.theta, self.nav.origin
            slot = np.full(world.n, -1)
            slot[self.healthy_idx] = np.arange(self.healthy_idx.size)
            k = slot[healthy]
            start[k >= 0] = self.nav.positions[k[k >= 0]]
        if theta is None:
            theta = flight_direction(self.settings.direction, world.vel[healthy, :2], world.pos[healthy, :2],
                                     failed_xy)
        s = self.settings
        if self.nav is not None:  # keep the replaced navigator's iteration count
            (done_iters, done_ticks), (iters, ticks) = self._iters_done, self.nav.iterations_total
            self._iters_done = (done_iters + iters, done_ticks + ticks)
        self.nav = CEMNavigator(start, failed_xy, a_p=self.a_p, theta=theta, v_des=s.v_des, dT=self.dT, K=s.K,
                                n=s.newton_iterations, sigma=s.sigma, rng=self.rng, origin=origin,
                                noise_rule=s.saddle_noise,
                                strengths=failure_strengths(s.multi_failure_flow, self.a_p, len(failed_xy)),
                                newton_stop=s.newton_stop, branch_guard=s.branch_guard)
        self.healthy_idx = healthy
        self.nav.track_rows(healthy, _TRACK)
        self._k = self.nav.kernels  # the compiled kernels module (loaded with the navigator)
        self._failed_xy = np.ascontiguousarray(failed_xy, dtype=float)  # (F, 2) world x-y z_f
        self._measured = np.empty(self._k.N_MEAS)
        self._formation = np.empty(self._k.N_FORM)
        self.hand_back.arm(self.nav)
        self.active = True
        self.start_inside += int((self.nav.exclusion_margin() < 0).sum())
        self.theorem1.append(self.nav.theorem1(s.delta, s.eps))
        self.theorem2.append(self.nav.theorem2(s.delta, s.eps))

    # ---- guidance ---------------------------------------------------------------------------

    def formation_clear(self, world: WorldState, sp: Setpoints) -> bool:
        """The ``clear_path`` test on this tick's formation setpoints (:meth:`HandBack.formation_clear`)."""
        return self.hand_back.formation_clear(self._k, world, sp, self._failed_xy)

    def command(self, world: WorldState, sp: Setpoints) -> Setpoints:
        """This tick's commands: ``sp`` (the formation's setpoints) itself while inactive; else TRACK
        setpoints along the streamlines (Algorithm 1 lines 13-22), the altitude the formation's."""
        self._commanded = False
        self._last_sp = sp
        if not self.active:
            if (self.nav is None or self.settings.hand_back_rule == "passed"
                    or self.formation_clear(world, sp)):
                return sp
            self.activate(world)  # a setpoint after hand-back leads into a failed vehicle: CEM again
            if not self.active:  # no healthy agent left to navigate
                return sp
            self.handback_time = None
        elif self.hand_back.decide(cast(CEMNavigator, self.nav), self._k, world, sp, self._failed_xy):
            self.active = False
            self.handback_time = world.t
            return sp
        t0 = time.perf_counter()
        out = sp.copy()
        # TRACK with x-y position and velocity, zero x-y acceleration (first differences only); the
        # altitude (z) stays the formation's (Assumption 2). One compiled call: step and write-back.
        # active (activate() set self.nav, and a re-activation replaces it): cast costs nothing per tick
        cast(CEMNavigator, self.nav).step_into(out.mode, out.pos, out.vel, out.acc)
        self._step_s.append(time.perf_counter() - t0)
        self._commanded = True
        return out

    # ---- measurement ------------------------------------------------------------------------

    def measure(self, world: WorldState) -> None:
        """Record the safety quantities of this tick (after the physics), from the first activation
        to the end of the run: CEM's commands while it commands, the formation's after a hand-back."""
        if self.nav is None:
            return
        if self._commanded:
            self.record.measure_cem(self.nav, self._k, world, self._failed_xy, self.healthy_idx,
                                    bool(self.failed), self._measured)
        elif self._last_sp is not None:
            self.record.measure_formation(self._k, world, self._last_sp, self._failed_xy, self._formation)
        self.record.note_violations(world, self.failed, self._failed_xy)

    def iterations_mean(self) -> float | None:
        """Mean over active ticks of the Newton iterations of the tick's last CalcXY pass."""
        total, ticks = self._iters_done
        if self.nav is not None:
            t, k = self.nav.iterations_total
            total, ticks = total + t, ticks + k
        return total / ticks if ticks else None

    def metrics(self) -> dict[str, Any]:
        """The ``cem.*`` metrics of the run so far (JSON-serialisable, None for undefined).

        A theorem's precondition is met when it held at every activation (Theorem 2's applies to
        one failure at a time); its numbers are the last activation's."""

        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        t1, t2 = self.theorem1, self.theorem2
        last1, last2 = (t1[-1] if t1 else None), (t2[-1] if t2 else None)
        met1, met2 = bool(t1) and all(c.holds for c in t1), bool(t2) and all(c.holds for c in t2)
        return {
            "cem.a_f": float(self.a_f),
            "cem.a_p": float(self.a_p),
            "cem.activations": len(t1),
            "cem.handback_time": self.handback_time,
            "cem.handback_blocked_time": self.hand_back.blocked_time,
            "cem.start_inside_exclusion": self.start_inside,
            "cem.theorem1_precondition_met": met1,
            "cem.theorem2_precondition_met": met2,
            "cem.theorem2_applicable": bool(t2) and all(c.applicable for c in t2),
            "cem.theorem1_p_min0": num(last1.p_min0) if last1 else None,
            "cem.theorem1_lambda_max": num(last1.lambda_max) if last1 else None,
            "cem.theorem1_lhs": num(last1.lhs) if last1 else None,
            "cem.theorem1_rhs": num(last1.rhs) if last1 else None,
            "cem.theorem2_d_min0": num(last2.d_min0) if last2 else None,
            "cem.theorem2_bound": num(last2.bound) if last2 else None,
            **self.record.metrics(),
            "cem.step_ms_median": float(np.median(self._step_s) * 1e3) if self._step_s else None,
            "cem.newton_iterations_mean": self.iterations_mean(),
            **self.record.violation_metrics(),
        }
