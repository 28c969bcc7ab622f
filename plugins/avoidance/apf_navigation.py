"""APF navigation with flight levels (thesis section 4.3.3, eq. 4.21-4.28) as an avoidance method.

The formation says where each agent should be (``sp.pos``); this plugin gets agents there
without collisions when the target is far, and hands them back to the formation's own setpoint
when it is near, exactly as the thesis' followers do in their FORM and STOP sequences:

- An agent *engages* when its target is more than ``engage_distance`` away horizontally (default
  d_c): a new slot or the way home, not the small errors of tracking a moving slot.
- While engaged and farther than d_c / 2 horizontally (eq. 4.27), it flies the APF velocity
  reference (eq. 4.21-4.26: target attraction plus repulsion from agents on its flight level,
  limited to v_sat) at the flight level t_z + level_offset * d_c.
- Within d_c / 2 the formation's setpoint passes through (position/tracker control on t_i).
- It disengages on arrival, ||t_i - r_i|| < eps_r (eq. 4.28).

Agents not engaged (and the leader, and failed agents) keep their setpoints and still repel the
engaged agents on their level. The vectorised maths is in
:mod:`~swarmscene.methods.outdoor.apf_navigation`; neighbours come from the tick's shared
k-d tree.

Frames: world (z up). The thesis' altitude reference t^T z_o - d_c is in NED (z_o down), i.e.
d_c *above* the target level ("go above its position in formation", section 4.5.3), hence
``level_offset = +1``. The kernel's setpoint has one mode per agent, so the thesis' split
(horizontal velocity control, altitude position control) is sent as a VELOCITY setpoint whose
vertical part is ``altitude_gain * (z_ref - z)``, limited to ``v_sat``.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.methods.outdoor.apf_navigation import apf_navigation
from swarmscene.plugin import Avoidance, BuildContext, Mode, PluginParams, Role, Setpoints, WorldState, hookimpl


class ApfNavigation(Avoidance):
    """Thesis APF navigation: target attraction, same-level repulsion, flight levels."""

    name = "apf_navigation"
    metric_prefix = "apf"

    class Params(PluginParams):
        d_c: float = Field(1.65, gt=0, description="collision-free distance d_c, m (Table 4.3)")
        v_sat: float = Field(0.5, gt=0, description="speed bound v_sat of the APF reference, m/s")
        eps_r: float = Field(0.5, gt=0, description="arrival tolerance eps_r, m (eq. 4.28)")
        engage_distance: float | None = Field(
            None, gt=0, description="horizontal distance to the target beyond which an agent "
            "starts navigating, m (null: d_c)")
        level_offset: float = Field(
            1.0, description="flight level of navigating agents above the target level, in d_c "
            "(thesis: +1; -1 flies below)")
        altitude_gain: float = Field(
            1.0, gt=0, description="vertical speed per metre of altitude error on the flight level, 1/s")
        include_leader: bool = Field(
            False, description="let the leader navigate too (thesis: it never does)")

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        self.engaged = np.zeros(ctx.n, dtype=bool)
        self.arrival_time = np.full(ctx.n, np.nan)
        self.max_command = 0.0

    @property
    def engage_distance(self) -> float:
        """Distance from its reference beyond which an agent navigates by the APF, m: ``engage_distance``,
        else d_c."""
        return self.params.d_c if self.params.engage_distance is None else self.params.engage_distance

    def adjust(self, world: WorldState, sensing, sp: Setpoints) -> Setpoints:
        """An agent farther than the engage distance from its reference flies the APF navigation
        command (VELOCITY, altitude held) until it arrives; the others, failed agents and (without
        ``include_leader``) the leader keep the formation's setpoints."""
        p = self.params
        cmd = apf_navigation(world.pos, sp.pos, p.d_c, p.v_sat, p.eps_r, tree=sensing.tree,
                             level_offset=p.level_offset)
        may_navigate = world.healthy.copy()
        if not p.include_leader:
            may_navigate &= world.role != Role.LEADER
        far = np.linalg.norm(sp.pos[:, :2] - world.pos[:, :2], axis=1) > self.engage_distance
        self.engaged = may_navigate & (self.engaged | far) & ~cmd.arrived
        arrived_now = ~self.engaged & np.isnan(self.arrival_time) & cmd.arrived & may_navigate
        self.arrival_time[arrived_now] = world.t

        navigating = self.engaged & ~cmd.position_mode
        if not navigating.any():
            return sp
        out = sp.copy()
        vz = np.clip(p.altitude_gain * (cmd.z_ref - world.pos[:, 2]), -p.v_sat, p.v_sat)
        out.mode[navigating] = Mode.VELOCITY
        out.vel[navigating, :2] = cmd.vel_xy[navigating]
        out.vel[navigating, 2] = vz[navigating]
        out.acc[navigating] = 0.0
        out.pos[navigating] = world.pos[navigating]  # ignored in VELOCITY mode; kept meaningful
        self.max_command = max(self.max_command, float(np.linalg.norm(cmd.vel_xy[navigating], axis=1).max()))
        return out

    @hookimpl
    def swarmscene_run_end(self, sim, metrics: dict) -> None:
        """``apf.*`` metrics: how many still navigate, last arrival, largest horizontal command."""
        arrived = self.arrival_time[~np.isnan(self.arrival_time)]
        metrics["apf.engaged_at_end"] = int(self.engaged.sum())
        metrics["apf.last_arrival_time"] = float(arrived.max()) if arrived.size else None
        metrics["apf.max_horizontal_command"] = self.max_command


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`ApfNavigation` to the registry, so that ``avoidance=apf_navigation`` chooses it."""
    register(ApfNavigation)
