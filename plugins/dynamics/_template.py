"""Template of a dynamics plugin: copy this file, rename the class and ``name``, fill in."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.core.plugin import Dynamics, PluginParams
from swarmscene.core.setpoint import Setpoints
from swarmscene.core.state import WorldState


class MyDynamics(Dynamics):
    """One line on the model and its controller."""

    name = "my_dynamics"

    class Params(PluginParams):
        gain: float = Field(1.0, gt=0, description="position gain, 1/s")

    def initialize(self, world: WorldState) -> None:
        self.u = np.zeros_like(world.pos)

    def control(self, world: WorldState, sp: Setpoints) -> None:
        self.u = sp.vel + self.params.gain * (sp.pos - world.pos)  # once per guidance tick

    def step(self, world: WorldState, dt: float) -> None:
        world.pos += self.u * dt  # once per physics step, in place
        world.vel[:] = self.u


# @hookimpl
# def swarmscene_register_dynamics(register):
#     register(MyDynamics)
