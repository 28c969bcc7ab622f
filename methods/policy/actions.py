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

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from swarmscene.core.errors import SwarmsceneDeprecationWarning
from swarmscene.core.setpoint import Mode, SetpointBatch, Setpoints
from swarmscene.core.state import WorldState

ActionCommand = Literal["velocity", "acceleration"]
"""What an action commands (a policy avoidance's ``action`` option)."""
ActionKind = ActionCommand
"""Deprecated name of :data:`ActionCommand` (until 0.9.0: ``kind`` names a plugin's kind only)."""


@dataclass(frozen=True)
class ActionSpec:
    """How a normalised action is scaled (what a policy needs to know about its outputs)."""

    command: ActionCommand
    """velocity: an action of 1 on an axis commands ``max_speed`` along it; acceleration:
    ``max_accel``"""
    max_speed: float
    """m/s: a velocity action of 1 on an axis commands this speed along it"""
    max_accel: float
    """m/s^2: an acceleration action of 1 on an axis commands this acceleration along it"""
    guidance_period: float
    """T_s, s: a command holds for one guidance tick"""

    @property
    def kind(self) -> ActionCommand:
        """Deprecated alias of :attr:`command` (until 0.9.0)."""
        warnings.warn("ActionSpec.kind is deprecated: read ActionSpec.command (kind is removed in 0.9.0)",
                      SwarmsceneDeprecationWarning, stacklevel=2)
        return self.command


def action_setpoints(world: WorldState, action: np.ndarray, active: np.ndarray, spec: ActionSpec) -> Setpoints:
    """Setpoints (N agents) from ``action`` (N, 3), clipped to [-1, 1]; rows not ``active`` hold."""
    return Setpoints(*_action_fields(world.pos, world.vel, world.healthy, action, active, spec))


def action_setpoints_batch(worlds: Sequence[WorldState], actions: Sequence[np.ndarray], actives: Sequence[np.ndarray],
                           spec: ActionSpec) -> SetpointBatch:
    """:func:`action_setpoints` of B worlds of N agents in one elementwise pass over their stacked
    rows: world b's setpoints are the bits of ``action_setpoints(worlds[b], actions[b], actives[b],
    spec)``, the B records one :class:`~swarmscene.core.setpoint.SetpointBatch` (a controller's
    batched form reads it whole)."""
    pos, vel, healthy = (np.stack([getattr(w, name) for w in worlds]) for name in ("pos", "vel", "healthy"))
    fields = _action_fields(pos, vel, healthy, np.stack(actions), np.stack(actives), spec)
    rows = pos.shape[0] * pos.shape[1]
    return SetpointBatch(Setpoints(*(field.reshape(rows, *field.shape[2:]) for field in fields)), len(worlds))


def _action_fields(pos: np.ndarray, vel: np.ndarray, healthy: np.ndarray, action: np.ndarray, active: np.ndarray,
                   spec: ActionSpec) -> tuple[np.ndarray, ...]:
    """The setpoints' (mode, pos, vel, acc, yaw) of agents (..., N): those ``active`` and healthy
    fly their action; the others hold where they are (``Setpoints.hold``'s fields)."""
    a = np.clip(np.asarray(action, dtype=float), -1.0, 1.0)  # an infinite action: +-1
    a[np.isnan(a)] = 0.0  # a NaN: 0 (np.nan_to_num's, then clipped; without its ~10 us a world)
    go = active & healthy
    mode = np.full(go.shape, int(Mode.HOLD), dtype=np.int8)  # an int: numpy converts an enum slowly
    mode[go] = int(Mode.VELOCITY)
    ref_vel, acc = np.zeros(pos.shape), np.zeros(pos.shape)
    if spec.command == "velocity":
        ref_vel[go] = a[go] * spec.max_speed
    else:
        commanded = a[go] * spec.max_accel
        ref_vel[go] = vel[go] + spec.guidance_period * commanded
        acc[go] = commanded
    return mode, np.array(pos, dtype=float, copy=True), ref_vel, acc, np.zeros(go.shape)
