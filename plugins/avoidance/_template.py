"""Template of an avoidance plugin: copy this file, rename the class and ``name``, fill in."""

from __future__ import annotations

from pydantic import Field

from swarmscene.core.plugin import Avoidance, PluginParams
from swarmscene.core.setpoint import Setpoints


class MyAvoidance(Avoidance):
    """One line on what it does."""

    name = "my_avoidance"

    class Params(PluginParams):
        radius: float = Field(1.0, gt=0, description="range of influence, m")

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        pairs = sensing.pairs(self.params.radius)  # the tick's shared k-d tree, (M, 2) indices
        out = sp.copy()  # never edit the formation's arrays in place
        # ... reshape out.pos / out.vel for the agents in `pairs`, vectorised ...
        del pairs
        return out


# @hookimpl
# def swarmscene_register_avoidances(register):
#     register(MyAvoidance)
