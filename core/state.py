"""World state: one array per field, agents along the first axis.

World frame (the one frame of the engine): right-handed, x east, y north, z up, metres,
seconds, radians. The thesis works in North-East-Down; its plugins convert at their boundary
(x_world = y_NED, y_world = x_NED, z_world = -z_NED). The CEM paper's plane is the world x-y
plane; the VRB paper is already z-up.

A failed vehicle is masked (``healthy[i] = False``), never deleted, so agent indices are stable
for the whole run and equal the agent ids used in config (0 .. N-1).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np


class Role(IntEnum):
    """Role of an agent in ``WorldState.role``."""

    FOLLOWER = 0
    LEADER = 1


@dataclass
class WorldState:
    """State of every agent at the current time.

    Attributes:
        t: simulated time, s.
        pos: positions, shape (N, 3), m, world frame.
        vel: velocities, shape (N, 3), m/s, world frame.
        healthy: (N,) bool; False once a failure event hit the agent (it then holds still).
        comm_ok: (N,) bool; False once the agent lost its radio (``comm_loss`` event): it drops
            out of the communication graph but keeps flying.
        role: (N,) int8, values of :class:`Role`.
        quat: orientation quaternions (w, x, y, z), body to world, shape (N, 4); ``None`` unless
            the dynamics model has attitude.
        omega: body angular rates, shape (N, 3), rad/s, body frame; ``None`` unless the dynamics
            model has attitude.
        rotor_speed: (N, 4) rad/s, for rotor-level models, else ``None``.
        acc: (N, 3) m/s^2, world frame: the acceleration input the dynamics model applied this
            tick (thesis u, eq. 3.21), for models with one; ``None`` otherwise. Formations use it
            as the leader's feed-forward (thesis eq. 4.11).
        wind: (N, 3) m/s, world frame: the air's velocity at each agent during the current physics
            step (the ``disturbances`` wind phase sets it before ``dynamics.step``); ``None`` when
            no wind model is declared. A model with ``wind_coupling = "integrated"`` reads it.
        wind_moment_arm: height of the centre of pressure above the centre of gravity, m (the
            wind models' ``moment_arm``): models with attitude take the wind force's moment there.
        force: (N, 3) m/s^2, world frame: the force per unit mass of the ``disturbances`` force
            phase (downwash, ground effect, drag, a battery's limit) during the current physics
            step; ``None`` when no force model is declared.
    """

    t: float
    pos: np.ndarray
    vel: np.ndarray
    healthy: np.ndarray
    comm_ok: np.ndarray
    role: np.ndarray
    quat: np.ndarray | None = None
    omega: np.ndarray | None = None
    rotor_speed: np.ndarray | None = None
    acc: np.ndarray | None = None
    wind: np.ndarray | None = None
    wind_moment_arm: float = 0.0
    force: np.ndarray | None = None

    @classmethod
    def at_rest(cls, pos: np.ndarray, leader: int | None = None) -> WorldState:
        """A swarm at rest at ``pos`` (N, 3), all healthy, agent ``leader`` (if any) leading."""
        pos = np.array(pos, dtype=float, copy=True)
        n = pos.shape[0]
        role = np.full(n, Role.FOLLOWER, dtype=np.int8)
        if leader is not None:
            role[leader] = Role.LEADER
        return cls(
            t=0.0,
            pos=pos,
            vel=np.zeros_like(pos),
            healthy=np.ones(n, dtype=bool),
            comm_ok=np.ones(n, dtype=bool),
            role=role,
        )

    @property
    def n(self) -> int:
        """Number of agents, healthy or not."""
        return self.pos.shape[0]

    @property
    def leader(self) -> int | None:
        """Index of the leader, or ``None`` when the swarm has none."""
        idx = np.flatnonzero(self.role == Role.LEADER)
        return int(idx[0]) if idx.size else None
