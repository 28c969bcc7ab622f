"""The thesis' leader-follower outdoor mission (Karydes 2020, section 4.3.1, Fig. 4.1-4.4).

A thin adapter: the workflow (states INIT, FORM, FLOW, LEAD, STOP; the leader's waits, eq.
4.1-4.2; the followers' assignment, eq. 4.12-4.13, and APF navigation, eq. 4.21-4.28) and its
choices where the text is loose are :mod:`swarmscene.methods.outdoor.mission`. This module turns
the scenario's options into a :class:`~swarmscene.methods.outdoor.mission.MissionWorkflow`, hands
it each tick's world and sensing, and writes its figures as metrics.

Metrics (``outdoor.*``): milestones (``last_flow_at``: last follower in FLOW, ``formed_at``,
``departed_at``, ``path_done_at``, ``leader_done_at``, ``last_home_at``), ``mission_complete``,
``waypoints_visited``, ``ignored`` and ``ignored_at``, and the thesis' figures over the following
sequence (leader on its path, FLOW followers): ``mean_neighbour_distance`` and
``neighbour_distance_min``/``max`` over the formation graph's edges (Fig. 4.21),
``tracking_error_mean``/``max`` to r_N + h_slot (Fig. 4.24).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field

from swarmscene.methods.outdoor.mission import LeaderLogic, MissionWorkflow, Task, WorkflowParameters
from swarmscene.plugin import BuildContext, Formation, PluginParams, Setpoints, WorldState, hookimpl

if TYPE_CHECKING:  # pragma: no cover
    from swarmscene.plugin import RunView, Sensing

__all__ = ["LeaderLogic", "OutdoorMission", "Task"]  # the workflow's names, re-exported for callers


class OutdoorMission(Formation):
    """Leader-follower mission on a hexagonal lattice with swarm-map communication (chapter 4)."""

    name = "outdoor_mission"
    metric_prefix = "outdoor"
    requires_leader = True
    models_communication = True  # its swarm maps apply per-link delays and losses (ctx.link_*)

    class Params(PluginParams):
        d_r: float = Field(5.0, gt=0, description="formation spacing d_r, m (Table 4.3)")
        alpha_deg: float = Field(0.0, description="formation yaw alpha, deg from North towards East")
        d_c: float = Field(1.65, gt=0, description="collision-free distance d_c, m (Table 4.3)")
        v_sat: float = Field(0.5, gt=0, description="APF speed bound v_sat, m/s (Table 4.3)")
        eps_r: float = Field(0.5, gt=0, description="control tolerance eps_r, m (eq. 4.28)")
        waypoints: list[tuple[float, float, float]] = Field(
            default_factory=lambda: [(0.0, 0.0, 0.0)], min_length=1,
            description="leader path as offsets from its home, [x east, y north, z up] m")
        leader_speed: float = Field(0.5, gt=0, description="speed of the leader's reference, m/s")
        catchup_threshold: float | None = Field(
            None, gt=0, description="Delta_W,th of eq. 4.1, m (null: d_r / 2; Table 4.3: 2 m)")
        T_msg: float = Field(2.0, gt=0, description="data storage time: map entries expire, s")
        T_ini: float = Field(5.0, ge=0, description="initialization delay (stable map), s")
        T_fol: float = Field(10.0, ge=0, description="follower delay (no leader: stop), s")
        T_led: float = Field(10.0, ge=0, description="leader delay (no follower: abort), s")
        T_del: float = Field(5.0, ge=0, description="catch-up delay, s")
        T_for: float = Field(40.0, ge=0, description="formation delay (followers to FLOW), s")
        T_end: float = Field(10.0, ge=0, description="end delay (followers to STOP), s")
        tau_com: float = Field(
            0.2, ge=0, description="single-hop delay tau_com, s (thesis ~0.2), of the engine's hop "
            "delay model; a declared comm_delay disturbance replaces it")
        self_hops: int = Field(1, ge=0, description="hops of an agent's own message to its own map")
        level_offset: float = Field(1.0, description="navigation flight level above target, in d_c")
        altitude_gain: float = Field(1.0, gt=0, description="vertical speed per m on the flight level, 1/s")

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        leader = ctx.initial.leader
        assert leader is not None  # requires_leader: validation checked it
        if ctx.n < 2:
            raise ValueError("outdoor_mission needs a follower besides the leader (swarm.n >= 2)")
        options = params.model_dump()
        options["waypoints"] = tuple(tuple(w) for w in options["waypoints"])
        self.mission = MissionWorkflow(
            ctx.initial.pos.copy(), leader, ctx.guidance_period, WorkflowParameters(**options),
            ctx.comm_range, link_delay=ctx.link_delay, link_loss=ctx.link_loss)

    def setpoints(self, world: WorldState, sensing: Sensing) -> Setpoints:
        """The workflow's tick: every agent's setpoint from its own swarm map."""
        return self.mission.setpoints(world, sensing)

    def complete(self, world: WorldState) -> bool:
        """Formation reached, every waypoint visited, leader done and every healthy follower home."""
        return self.mission.complete(world)

    @hookimpl
    def swarmscene_run_end(self, sim: RunView, metrics: dict[str, Any]) -> None:
        """``outdoor.*`` metrics: the mission's milestones and the thesis' figures 4.21-4.24."""
        mission = self.mission
        s, lead = mission.stats, mission.leader
        f = mission.is_follower
        nm = s["neighbour_mean"]
        metrics.update({
            "outdoor.mission_complete": mission.complete(sim.world),
            "outdoor.formed_at": lead.formed_at,
            "outdoor.departed_at": lead.departed_at,
            "outdoor.path_done_at": lead.path_done_at,
            "outdoor.leader_done_at": lead.done_at,
            "outdoor.waypoints_visited": int(lead.visited.sum()),
            "outdoor.aborted": lead.aborted,
            "outdoor.ignored": np.flatnonzero(lead.ignored).tolist(),
            "outdoor.ignored_at": lead.ignored_at,
            "outdoor.last_flow_at": (float(np.nanmax(s["flow_at"]))
                                     if np.isfinite(s["flow_at"]).any() else None),
            "outdoor.followers_home": int(mission.home_done[f].sum()),
            "outdoor.last_home_at": float(np.nanmax(s["home_at"])) if mission.home_done.any() else None,
            "outdoor.mean_neighbour_distance": float(np.mean(nm)) if nm else None,
            "outdoor.neighbour_distance_min": float(s["neighbour_min"]) if nm else None,
            "outdoor.neighbour_distance_max": float(s["neighbour_max"]) if nm else None,
            "outdoor.tracking_error_mean": float(np.mean(s["tracking"])) if s["tracking"] else None,
            "outdoor.tracking_error_max": float(np.max(s["tracking"])) if s["tracking"] else None,
            "outdoor.assignment_solves": s["solves"],
        })


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Register ``outdoor_mission``."""
    register(OutdoorMission)
