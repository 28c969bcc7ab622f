"""Potential barrier avoidance: the thesis' obstacle and collision terms and the input saturation.

Karydes (2020), section 5.3.3. For each follower i (the leader keeps its path input when
``exempt_leader``):

    w_obs = psi_obs(||o_i - r_i||) (o_i - r_i)/||o_i - r_i||         (eq. 5.32-5.34)
    w_col = sum over N_i(G_sigma) of psi_col(||r_ji||) r_ji/||r_ji||   (eq. 5.35-5.36)

are added to the formation's command and the sum is saturated at u_sat (eq. 5.30); o_i is the
nearest obstacle point in line of sight, G_sigma the sensed graph after edge deactivation. psi_obs
and psi_col are held at -K below d_o and d_c (see the notes that come with the source text).

Collision avoidance needs line of sight, as in the thesis: w_col sums over N_i(G_sigma), and
G_sigma is in G_s, whose edges need the joining segment d_l = 0.05 m clear of walls (eq. 5.8), so
two close agents on either side of a wall corner do not repel. Eq. 5.2-5.3 can still be grazed
where they cannot both hold: in the 0.5 m corridor's mouth two agents side by side had 0.298 m
and 0.097 m (they saw each other; psi_col and psi_obs are both held at 200 there, so the
saturated step splits the difference).

Units: the thesis' terms are displacements per sampling period T_s; they enter the setpoint as
velocities w / T_s (T_s = ``clock.guidance_period``). VELOCITY setpoints get the sum, saturated;
other modes get the term as feed-forward and their reference position shifted by one step of it.
When the formation is ``indoor_swarm`` the graphs are computed once per tick for both plugins.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.methods.indoor.control import TABLE_5_1, IndoorGains, avoidance_terms, barrier_command
from swarmscene.methods.indoor.shared import GraphParams, shared_snapshot
from swarmscene.plugin import Avoidance, BuildContext, Mode, Role, Setpoints, WorldState, hookimpl


class PotentialBarrier(Avoidance):
    """Obstacle and collision repulsion of thesis eq. 5.32-5.36, then saturation at u_sat."""

    name = "potential_barrier"

    class Params(GraphParams):
        d_o: float = Field(TABLE_5_1.d_o, gt=0, description="obstacle-free distance d_o, m")
        K_obs: float = Field(TABLE_5_1.K_obs, gt=0, description="obstacle avoidance gain, m per step")
        eps_obs: float = Field(TABLE_5_1.eps_obs, gt=0, description="obstacle avoidance slope")
        d_c: float = Field(TABLE_5_1.d_c, gt=0, description="collision-free distance d_c, m")
        l_c: float = Field(TABLE_5_1.l_c, gt=0, description="collision avoidance range l_c, m")
        K_col: float = Field(TABLE_5_1.K_col, gt=0, description="collision avoidance gain, m per step")
        eps_col: float = Field(TABLE_5_1.eps_col, gt=0, description="collision avoidance slope")
        u_sat: float = Field(TABLE_5_1.u_sat, gt=0, description="input saturation u_sat, m per step")
        exempt_leader: bool = Field(
            True, description="leave the leader's command alone (the thesis' leader has no avoidance)"
        )

    params: Params

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        fields = IndoorGains.__dataclass_fields__
        self.gains = replace(
            TABLE_5_1, T_s=ctx.guidance_period, **{k: v for k, v in params if k in fields}
        )
        # The compiled kernels (numba) load here, not when the plugin registers (start-up).
        from swarmscene.methods.indoor import kernels  # noqa: F401

    def terms(self, sensing: Any) -> np.ndarray:
        """w_obs + w_col (N, 2), m per step, from this tick's shared snapshot."""
        return avoidance_terms(shared_snapshot(sensing, self.gains), self.gains)

    def adjust(self, world: WorldState, sensing: Any, sp: Setpoints) -> Setpoints:
        """The thesis' saturated sum of the formation command and the barrier terms for VELOCITY rows
        (one compiled call); other modes get the terms as feed-forward and a shifted reference."""
        T = self.gains.T_s
        w = self.terms(sensing)
        out = sp.copy()
        # VELOCITY rows: the saturated sum, in place, one compiled call.
        others = barrier_command(
            out.vel, out.mode, world.healthy, world.role, w, T, self.gains.u_sat, self.params.exempt_leader
        )
        if others:  # other modes: the terms as feed-forward and a shifted reference
            acting = world.healthy.copy()
            if self.params.exempt_leader:
                acting &= world.role != Role.LEADER
            other = acting & (out.mode != Mode.VELOCITY)
            out.vel[other, :2] += w[other] / T
            out.pos[other, :2] += w[other]
        return out


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`PotentialBarrier` to the registry, so that ``avoidance=potential_barrier`` chooses it."""
    register(PotentialBarrier)
