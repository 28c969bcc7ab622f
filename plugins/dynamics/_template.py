"""Template of a dynamics plugin: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), add ``dynamics/<name>.yaml`` holding ``name: <name>``,
and check it with ``swarmscene.testing.check_dynamics(MyDynamics)`` in your tests.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Self

import numpy as np
from pydantic import Field

from swarmscene.plugin import Dynamics, Mode, PluginParams, Setpoints, WorldBatch, WorldState, hookimpl


class MyDynamics(Dynamics):
    """A kinematic point under a proportional position controller with velocity feed-forward."""

    name = "my_dynamics"
    # How a declared wind acts on it (docs/disturbances.md): "force" (the default: the kernel adds
    # a = drag_coefficient * w after each step), "carried" (a kinematic point flies relative to the
    # air, as this one does), or "integrated" (step() reads world.wind itself).
    wind_coupling = "carried"

    class Params(PluginParams):
        gain: float = Field(1.0, gt=0, description="position gain, 1/s")

    params: Params  # self.params: the validated options, typed as this class's own (for mypy, editors)

    def initialize(self, world: WorldState) -> None:
        self.u = np.zeros_like(world.pos)

    def control(self, world: WorldState, sp: Setpoints) -> None:
        """Once per guidance tick: the velocity command (N, 3) m/s, held until the next tick."""
        self.u = sp.vel + self.params.gain * (sp.pos - world.pos)
        velocity = sp.mode == Mode.VELOCITY  # VELOCITY setpoints ignore pos
        self.u[velocity] = sp.vel[velocity]
        hold = sp.mode == Mode.HOLD  # HOLD: stay where the setpoint says
        self.u[hold] = self.params.gain * (sp.pos[hold] - world.pos[hold])

    def step(self, world: WorldState, dt: float) -> None:
        world.pos += self.u * dt  # once per physics step, in place
        world.vel[:] = self.u

    # Optional (docs/batched.md): the same control for B worlds at once, on (B, N, 3) stacks. Without
    # it the engine calls control() world by world. worlds[b] is what world b's controller reads (its
    # own estimates), setpoints[b] its setpoints. It must give each world the bits control() gives it
    # (check_dynamics tests that): elementwise numpy operations do, at any shape.
    @classmethod
    def control_batch(cls, models: Sequence[Self], batch: WorldBatch, worlds: Sequence[WorldState],
                      setpoints: Sequence[Setpoints]) -> object:
        gain = models[0].params.gain
        if any(m.params.gain != gain for m in models):
            return NotImplemented  # one gain per batch here: else the engine calls control() per world
        pos, mode = np.stack([w.pos for w in worlds]), np.stack([sp.mode for sp in setpoints])
        sp_pos, sp_vel = np.stack([sp.pos for sp in setpoints]), np.stack([sp.vel for sp in setpoints])
        u = sp_vel + gain * (sp_pos - pos)
        velocity, hold = mode == Mode.VELOCITY, mode == Mode.HOLD
        u[velocity] = sp_vel[velocity]
        u[hold] = gain * (sp_pos[hold] - pos[hold])
        for model, own in zip(models, u, strict=True):
            model.u = own
        return None

    # Optional (docs/batched.md): the same step for B worlds at once. Without it the engine steps a
    # batch's worlds one by one with step(); with it, the (B, N, 3) arrays are updated in one go.
    # It must give each world the bits step() gives it (check_dynamics tests that).
    @classmethod
    def step_batch(cls, models: Sequence[Self], batch: WorldBatch, dt: float) -> None:
        u = batch.per_tick("my_dynamics.u", lambda: np.stack([m.u for m in models]))  # (B, N, 3)
        batch.pos += u * dt
        batch.vel[:] = u


@hookimpl
def swarmscene_register_dynamics(register):
    register(MyDynamics)
