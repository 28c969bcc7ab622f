"""CEM's hand-back and its safety record: when the formation gets control back, and what is measured
from the first activation to the end of the run (Romano et al., papers/cem-fluid-flow-navigation.md).

The paper is silent on the hand-back (healthy agents "safely pass them before continuing with their
individual trajectories"; its theorems cover CEM mode only): :class:`HandBack` holds the two rules
the ``cem`` plugin offers (``hand_back_rule``; the plugin's docstring gives both and their measured
effects). :class:`SafetyRecord` keeps the running minima and maxima behind the plugin's ``cem.*``
metrics: exclusion margin of the commands, clearance of the actual positions from every failed
vehicle, pairwise distances of healthy agents (x-y, the plane of the theorems), speeds and tracking
error, each tick from the first activation (after a hand-back too, on the formation's commands).

Symbols: a_f the failed vehicle's no-fly radius, a_p = a_f + delta + eps the planned exclusion radius
(eq. 4), delta the tracking-error bound, eps the vehicle's enclosing radius, z_f a failed vehicle's
x-y centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.core.vectors import min_distance_between, min_pair_distance

from .flow import CEMNavigator

HANDBACK_RULES = ("clear_path", "passed")
"""``hand_back_rule``: the default first."""

_TRACK, _POSITION = int(Mode.TRACK), int(Mode.POSITION)
_VELOCITY, _HOLD = int(Mode.VELOCITY), int(Mode.HOLD)


@dataclass
class HandBack:
    """When CEM returns control to the formation.

    Attributes:
        enabled: ``hand_back`` (False: CEM keeps control to the end of the run).
        rule: ``"clear_path"`` (every agent past, and every formation setpoint and the straight path
            to it at least a_p from every failed vehicle) or ``"passed"`` (the along-track test alone).
        distance: along-track distance past the most downstream failure, m (default 2 a_p).
        a_p: planned exclusion radius, m (eq. 4).
        v_des: desired speed of the fastest agent, m/s (the look-ahead of a VELOCITY setpoint).
        at: the flow-frame along-track coordinate every agent must pass, m (set by :meth:`arm`).
        blocked_time: s, the first tick at which every agent had passed but a formation setpoint or
            its path lay within a_p of a failed vehicle (None: never).
    """

    enabled: bool
    rule: str
    distance: float
    a_p: float
    v_des: float
    at: float = math.inf
    blocked_time: float | None = None

    def arm(self, nav: CEMNavigator) -> None:
        """At an activation: pass ``distance`` beyond the most downstream failed vehicle."""
        self.at = float(nav.centres.real.max() + self.distance)

    def passed(self, nav: CEMNavigator) -> bool:
        """Along-track test: every agent is ``distance`` past the most downstream failure."""
        return nav.along_track_min >= self.at

    def formation_clear(self, kernels: Any, world: WorldState, sp: Setpoints, failed_xy: np.ndarray) -> bool:
        """Each healthy agent's formation setpoint, and the straight path from it to that setpoint,
        at least a_p from every failed vehicle (the ``clear_path`` test). The target: the setpoint's
        position (TRACK, POSITION), the agent's own position (HOLD), or for VELOCITY the point it
        reaches flying the commanded velocity for distance / v_des seconds (the time CEM takes to
        clear a failure). One compiled call (``kernels.path_clear``: ``flow.segment_clearance``
        operation for operation), as it runs every tick after a hand-back."""
        if not len(failed_xy) or not world.healthy.any():
            return True
        lookahead = self.distance / self.v_des
        return bool(kernels.path_clear(world.healthy, world.pos, sp.mode, sp.pos, sp.vel, failed_xy,
                                       _HOLD, _VELOCITY, lookahead, self.a_p))

    def decide(self, nav: CEMNavigator, kernels: Any, world: WorldState, sp: Setpoints,
               failed_xy: np.ndarray) -> bool:
        """The hand-back decision of this tick (notes the first blocked tick)."""
        if not (self.enabled and self.passed(nav)):
            return False
        if self.rule == "passed" or self.formation_clear(kernels, world, sp, failed_xy):
            return True
        if self.blocked_time is None:
            self.blocked_time = world.t
        return False


class SafetyRecord:
    """The running extremes behind the ``cem.*`` safety metrics, from the first activation on.

    Args:
        n: number of agents.
        a_f, a_p, delta, eps: the radii and bounds of this run, m.
    """

    def __init__(self, n: int, a_f: float, a_p: float, delta: float, eps: float) -> None:
        self.a_f, self.a_p, self.delta, self.eps = a_f, a_p, delta, eps
        self.psi_drift = np.zeros(n)
        self.margin = math.inf
        self.clearance = math.inf
        self.pair = math.inf
        self.pair_cmd = math.inf
        self.speed = 0.0
        self.speed_actual = 0.0
        self.track_err = 0.0
        self.dphi_min = math.inf
        self.first: dict[str, tuple[float, list[int]]] = {}  # condition -> (first violation time, agents)

    @property
    def pair_bound(self) -> float:
        """2 (delta + eps), m: the theorems' bound on healthy pairs."""
        return 2.0 * (self.delta + self.eps)

    def measure_cem(self, nav: CEMNavigator, kernels: Any, world: WorldState, failed_xy: np.ndarray,
                    healthy_idx: np.ndarray, any_failed: bool, out: np.ndarray) -> None:
        """A tick under CEM's commands (one compiled call; ``out`` its scratch of N_MEAS values)."""
        k = kernels
        # an agent may have failed during this tick's events (counted live no more)
        live_n = nav.measure_tick(world.healthy, world.pos, world.vel, failed_xy, self.psi_drift, out)
        self.margin = min(self.margin, float(out[k.M_MARGIN]))
        if any_failed:
            self.clearance = min(self.clearance, float(out[k.M_CLEAR]) - self.a_f - self.eps)
        pair, pair_cmd = float(out[k.M_PAIR]), float(out[k.M_PAIR_CMD])
        if live_n > k.DENSE_PAIRS_MAX:  # a large swarm: the engine's cell list beats the O(N^2) loop
            live = world.healthy[healthy_idx]
            pair = min_pair_distance(world.pos[healthy_idx[live], :2])
            pair_cmd = min_pair_distance(nav.positions[live])
        self.pair = min(self.pair, pair)
        self.pair_cmd = min(self.pair_cmd, pair_cmd)
        self.speed = max(self.speed, float(out[k.M_SPEED]))
        if live_n:
            self.speed_actual = max(self.speed_actual, float(out[k.M_SPEED_ACT]))
            self.track_err = max(self.track_err, float(out[k.M_TRACK_ERR]))
        self.dphi_min = min(self.dphi_min, nav.dphi_used)

    def measure_formation(self, kernels: Any, world: WorldState, sp: Setpoints, failed_xy: np.ndarray,
                          out: np.ndarray) -> None:
        """A tick after hand-back: the formation's commands (TRACK and POSITION rows) and the healthy
        agents' actual positions, against the failed vehicles: one compiled call
        (``kernels.measure_formation``, core.vectors' arithmetic; ``out`` its scratch of N_FORM
        values), NumPy above its point limit."""
        k = kernels
        n, placed_n = k.measure_formation(world.healthy, world.pos, sp.mode, sp.pos, failed_xy,
                                          _TRACK, _POSITION, out)
        if n == 0:
            return
        if n > k.FORMATION_POINTS_MAX:
            self._measure_formation_numpy(world, sp, failed_xy)
            return
        self.clearance = min(self.clearance, float(out[k.F_CLEAR]) - self.a_f - self.eps)
        self.pair = min(self.pair, float(out[k.F_PAIR]))
        if placed_n:
            self.margin = min(self.margin, float(out[k.F_MARGIN]) - self.a_p)
            self.pair_cmd = min(self.pair_cmd, float(out[k.F_PAIR_CMD]))

    def _measure_formation_numpy(self, world: WorldState, sp: Setpoints, failed_xy: np.ndarray) -> None:
        """:meth:`measure_formation` for a large swarm (the engine's cell list for the pairs)."""
        agents = np.flatnonzero(world.healthy)
        xy = world.pos[agents, :2]
        self.clearance = min(self.clearance, min_distance_between(xy, failed_xy) - self.a_f - self.eps)
        self.pair = min(self.pair, min_pair_distance(xy))
        placed = agents[(sp.mode[agents] == _TRACK) | (sp.mode[agents] == _POSITION)]
        if placed.size:
            cmd = sp.pos[placed, :2]
            self.margin = min(self.margin, min_distance_between(cmd, failed_xy) - self.a_p)
            self.pair_cmd = min(self.pair_cmd, min_pair_distance(cmd))

    def note_violations(self, world: WorldState, failed: dict[int, np.ndarray], failed_xy: np.ndarray) -> None:
        """The first tick of each violated condition, with its agents (the running minima tell when;
        the agents are looked up only on that tick: this runs every tick)."""
        bound = self.pair_bound
        if self.pair < bound and "separation" not in self.first:
            healthy = np.flatnonzero(world.healthy)
            xy = world.pos[healthy, :2]
            d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
            np.fill_diagonal(d, np.inf)
            i, j = np.nonzero(np.triu(d < bound))
            self.first["separation"] = (float(world.t), sorted({*healthy[i].tolist(), *healthy[j].tolist()}))
        if self.clearance < 0.0 and "clearance" not in self.first:
            healthy = np.flatnonzero(world.healthy)
            d = np.linalg.norm(world.pos[healthy, None, :2] - failed_xy[None], axis=-1)
            near = d < self.a_f + self.eps
            ids = np.array(list(failed))
            agents = healthy[near.any(axis=1)].tolist() + ids[near.any(axis=0)].tolist()
            self.first["clearance"] = (float(world.t), agents)

    def metrics(self) -> dict[str, Any]:
        """The measured ``cem.*`` metrics (the ``cem`` plugin's docstring lists them)."""
        return {
            "cem.psi_drift_max": float(self.psi_drift.max()) if self.psi_drift.size else 0.0,
            "cem.psi_drift_per_agent": [float(x) for x in self.psi_drift],
            "cem.min_exclusion_margin": _finite(self.margin),
            "cem.min_actual_clearance": _finite(self.clearance),
            "cem.clearance_bound": float(self.a_f + self.eps),
            "cem.clearance_holds": bool(self.clearance >= 0.0) if math.isfinite(self.clearance) else True,
            "cem.min_pair_distance": _finite(self.pair),
            "cem.min_pair_distance_commanded": _finite(self.pair_cmd),
            "cem.pair_bound": self.pair_bound,
            "cem.separation_holds": bool(self.pair >= self.pair_bound) if math.isfinite(self.pair) else True,
            "cem.max_speed": float(self.speed),
            "cem.max_speed_actual": float(self.speed_actual),
            "cem.tracking_error_max": float(self.track_err),
            "cem.dphi_min": _finite(self.dphi_min),
        }

    def violation_metrics(self) -> dict[str, Any]:
        """``cem.violations.<condition>.first_time`` / ``.agents`` of each violated condition."""
        return {f"cem.violations.{c}.{part}": v for c, (t, agents) in sorted(self.first.items())
                for part, v in (("first_time", t), ("agents", agents))}


def _finite(x: float) -> float | None:
    """``x``, or None where it is undefined (no tick measured)."""
    return None if not math.isfinite(x) else float(x)
