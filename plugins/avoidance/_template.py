"""Template of an avoidance plugin: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), add ``avoidance/<name>.yaml`` holding ``name: <name>``,
and check it with ``swarmscene.testing.check_avoidance(MyAvoidance)`` in your tests.
Cite the paper's section, symbols and equation numbers here.
"""

from __future__ import annotations

from pydantic import Field

from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import Avoidance, PluginParams
from swarmscene.core.setpoint import Setpoints


class MyAvoidance(Avoidance):
    """Agents closer than ``radius`` to another keep ``factor`` of their velocity setpoint."""

    name = "my_avoidance"

    class Params(PluginParams):
        radius: float = Field(1.0, gt=0, description="range of influence, m")
        factor: float = Field(0.5, gt=0, le=1, description="fraction of the velocity kept")

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        distance, _ = sensing.nearest  # the tick's shared k-d tree: each agent's nearest other
        near = (distance < self.params.radius) & world.healthy  # failed agents are left alone
        out = sp.copy()  # never edit the formation's arrays in place
        out.vel[near] *= self.params.factor  # vectorised over agents: no Python loop per agent
        return out


@hookimpl
def swarmscene_register_avoidances(register):
    register(MyAvoidance)
