"""Take-off and landing: the flight from the floor to the mission and back to it.

A mission (the formation, the avoidance, the events) starts with the swarm in the air, at its start
positions, at t = 0. With a ground (``environment.floor``, :mod:`swarmscene.core.floor`), a scenario
may add the flights that real vehicles make around it:

* **take-off** (``swarm.takeoff``, T_to s): the swarm starts at rest on the floor below its start
  positions, at t = -T_to, and each vehicle climbs straight up to its start position, arriving at
  rest at t = 0. The mission's clock is unchanged: the formation, the events and the termination
  rules see the same times as without a take-off.
* **landing** (``swarm.land``, T_l s): when the mission ends (``clock.duration``, or its completion
  under ``termination.on_complete``), each vehicle descends straight down from where it is to the
  floor in T_l s. Its reference ends ``LAND_PRESS`` below the floor so that it touches down (a
  real landing ends in contact; a reference on the floor would leave a vehicle that tracks it
  exactly hovering a hair above it). A healthy vehicle that has touched the floor during the
  landing stops its motors: it rests there, as it touched down, to the end (without it, the thrust
  that braked the descent lifts a quadrotor off again). The run ends T_l s after the landing began
  once every healthy vehicle is down; a vehicle that lags its reference gets at most another T_l
  (the reference waits below the floor), and one still in the air then is counted airborne.

Both flights follow the minimum-jerk profile between rest states (Flash & Hogan, J. Neurosci. 1985,
the quintic s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5, tau = elapsed / T), as a TRACK setpoint with its
velocity and acceleration feed-forward. During them the formation and the avoidance method are not
consulted: like the take-off and land commands of a Crazyflie's high-level commander, the flights
are scripted and vertical, so the swarm's horizontal spacing is kept. The safety monitor, the floor
and the observers run throughout.

Metrics (only with a phase): ``phases.takeoff`` (T_to, s), ``phases.land_start`` (the mission time
the landing began, s), ``phases.landed`` (healthy vehicles resting on the floor at the end) and
``phases.airborne`` (healthy vehicles still in the air at the end: a landing that did not end on
the floor, held against ``success``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .setpoint import Mode, Setpoints
from .state import WorldState
from .vectors import quat_yaw

LAND_PRESS = 0.05
"""m: how far below the floor a landing's reference ends (module docstring)."""


def min_jerk(tau: float) -> tuple[float, float, float]:
    """s, ds/dtau, d^2s/dtau^2 of the minimum-jerk profile s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5,
    tau clipped to [0, 1] (s rises from 0 to 1 with zero rate and curvature at both ends)."""
    u = min(max(tau, 0.0), 1.0)
    s = u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
    ds = 30.0 * u * u * (1.0 - u) ** 2
    dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u)
    return s, ds, dds


class Phases:
    """The take-off and landing of one run (module docstring).

    Args:
        floor: z_f, the ground's height, m.
        takeoff: T_to, s (None: the swarm starts in the air).
        land: T_l, s (None: the run ends in the air).
        guidance_period: T_s, s.
        targets: (N, 3) the mission's start positions, m (the take-off's ends).
    """

    def __init__(self, floor: float, takeoff: float | None, land: float | None, guidance_period: float,
                 targets: np.ndarray) -> None:
        self.floor = float(floor)
        self.T_s = guidance_period
        self.takeoff = takeoff
        self.land = land
        self.takeoff_ticks = 0 if takeoff is None else int(round(takeoff / guidance_period))
        self.land_ticks = 0 if land is None else int(round(land / guidance_period))
        self.targets = np.array(targets, dtype=float, copy=True)
        self.land_start: float | None = None  # mission time the landing began
        self.land_from: np.ndarray | None = None  # (N, 3) where each vehicle began its descent
        self.land_yaw: np.ndarray | None = None  # (N,) its heading then (kept while it descends)
        self.mission_complete: bool | None = None  # the formation's verdict when the mission ended
        self.completed = False  # the mission ended by its completion (the run ends "complete")
        self.down: np.ndarray | None = None  # (N,) bool: touched the floor during the landing, at rest

    def start(self) -> np.ndarray:
        """(N, 3) the swarm's first positions: on the floor below the targets with a take-off, else the targets."""
        pos = self.targets.copy()
        if self.takeoff is not None:
            pos[:, 2] = self.floor
        return pos

    def flying(self, t: float) -> bool:
        """Whether the tick at mission time ``t`` belongs to a phase (the formation rests)."""
        return t < 0.0 or self.land_start is not None

    def begin_landing(self, world: WorldState, mission_complete: bool | None, completed: bool) -> None:
        """The mission ended at ``world.t`` (``completed``: by its completion, not its duration): keep
        the formation's verdict and start the descent."""
        self.completed = completed
        self.land_start = float(world.t)
        self.land_from = world.pos.copy()
        self.land_yaw = yaw_of(world)
        self.mission_complete = mission_complete

    def keep_down(self, world: WorldState) -> None:
        """Before the floor's tick: the vehicles already down stay on it, at rest (motors stopped;
        so the floor sees them resting, not landing again)."""
        if self.down is not None:
            world.pos[self.down, 2] = self.floor
            world.vel[self.down] = 0.0

    def touch(self, world: WorldState) -> None:
        """After the floor's tick (it has judged each touchdown a landing or a crash): the healthy
        vehicles on it during the landing are down from now on."""
        if self.land_start is None:
            return
        if self.down is None:
            self.down = np.zeros(world.n, dtype=bool)
        self.down |= (world.pos[:, 2] <= self.floor) & world.healthy

    def over(self, world: WorldState) -> bool:
        """Whether the landing has ended at ``world.t``: its T_l s are up and every healthy vehicle
        is down, or another T_l s are up too (module docstring)."""
        if self.land_start is None:
            return False
        # whole ticks, as the clock counts them (a sum of floats could fall a hair short)
        ticks = (world.t - self.land_start) / self.T_s + 0.5
        if ticks < self.land_ticks:
            return False
        down = self.down if self.down is not None else np.zeros(world.n, dtype=bool)
        return bool(np.all(down | ~world.healthy)) or ticks >= 2 * self.land_ticks

    def setpoints(self, t: float) -> Setpoints:
        """The references of the tick at mission time ``t``: the climb before 0, the descent after
        the landing began (TRACK: position, velocity and acceleration along z)."""
        if self.land_start is None:
            assert self.takeoff is not None
            start = self.start()
            # over the whole ticks the clock gives it (from -takeoff_ticks T_s), so it starts on the floor
            flight = self.takeoff_ticks * self.T_s
            return _vertical(start, self.targets[:, 2], t + flight, flight, np.zeros(len(start)))
        assert self.land_from is not None and self.land is not None and self.land_yaw is not None
        return _vertical(self.land_from, np.full(len(self.land_from), self.floor - LAND_PRESS),
                         t - self.land_start, self.land_ticks * self.T_s, self.land_yaw)

    def metrics(self, world: WorldState) -> dict[str, Any]:
        """``phases.*`` (module docstring)."""
        out: dict[str, Any] = {}
        if self.takeoff is not None:
            out["phases.takeoff"] = float(self.takeoff)
        if self.land is not None:
            on_floor = world.pos[:, 2] <= self.floor
            healthy = world.healthy
            out["phases.land_start"] = self.land_start
            out["phases.landed"] = int(np.count_nonzero(on_floor & healthy))
            out["phases.airborne"] = int(np.count_nonzero(~on_floor & healthy))
        return out


def yaw_of(world: WorldState) -> np.ndarray:
    """(N,) each vehicle's heading about z, rad, from its attitude (zeros for a point mass)."""
    return np.zeros(world.n) if world.quat is None else quat_yaw(world.quat)


def _vertical(start: np.ndarray, z_end: np.ndarray, elapsed: float, duration: float, yaw: np.ndarray) -> Setpoints:
    """TRACK setpoints along the minimum-jerk profile from ``start`` (N, 3) straight up or down to
    heights ``z_end`` (N,) in ``duration`` s, ``elapsed`` s into it, holding heading ``yaw`` (N,)."""
    s, ds, dds = min_jerk(elapsed / duration)
    rise = z_end - start[:, 2]
    n = len(start)
    pos = start.copy()
    pos[:, 2] += s * rise
    vel = np.zeros((n, 3))
    vel[:, 2] = ds / duration * rise
    acc = np.zeros((n, 3))
    acc[:, 2] = dds / duration**2 * rise
    return Setpoints(mode=np.full(n, int(Mode.TRACK), dtype=np.int8), pos=pos, vel=vel, acc=acc, yaw=yaw.copy())
