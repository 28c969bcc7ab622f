"""Actions: each agent's normalised command a_i in [-1, 1]^3 turned into a setpoint.

    velocity      v_ref = a_i * max_speed                      (Mode.VELOCITY)
    acceleration  v_ref = v_i + T_s * a_i * max_accel,          (Mode.VELOCITY, with the
                  feed-forward acceleration a_i * max_accel      acceleration as feed-forward)

An acceleration command goes through the chosen dynamics' own velocity loop, as one tick of the
commanded acceleration integrated from the current velocity: the same law for every dynamics
model (a single integrator takes the velocity, a double integrator or the quadrotor track it with
their saturations). Failed agents, and agents without a command, hold where they are.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState

ActionKind = Literal["velocity", "acceleration"]


@dataclass(frozen=True)
class ActionSpec:
    """How a normalised action is scaled (what a policy needs to know about its outputs)."""

    kind: ActionKind
    max_speed: float
    """m/s: a velocity action of 1 on an axis commands this speed along it"""
    max_accel: float
    """m/s^2: an acceleration action of 1 on an axis commands this acceleration along it"""
    guidance_period: float
    """T_s, s: a command holds for one guidance tick"""


def action_setpoints(world: WorldState, action: np.ndarray, active: np.ndarray, spec: ActionSpec) -> Setpoints:
    """Setpoints (N agents) from ``action`` (N, 3), clipped to [-1, 1]; rows not ``active`` hold."""
    a = np.clip(np.nan_to_num(np.asarray(action, dtype=float)), -1.0, 1.0)
    sp = Setpoints.hold(world.pos)
    go = active & world.healthy
    sp.mode[go] = Mode.VELOCITY
    if spec.kind == "velocity":
        sp.vel[go] = a[go] * spec.max_speed
    else:
        acc = a[go] * spec.max_accel
        sp.vel[go] = world.vel[go] + spec.guidance_period * acc
        sp.acc[go] = acc
    return sp
