"""Template of an avoidance plugin: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), add ``avoidance/<name>.yaml`` holding ``name: <name>``,
and check it with ``swarmscene.testing.check_avoidance(MyAvoidance)`` in your tests. The packaged
example (docs/examples/swarmscene-slowdown) is this file with the names changed.
Cite the paper's section, symbols and equation numbers here.
"""

from __future__ import annotations

from pydantic import Field

from swarmscene.plugin import Avoidance, PluginParams, Setpoints, hookimpl


class MyAvoidance(Avoidance):
    """Agents with a neighbour closer than ``radius`` keep ``factor`` of their velocity."""

    name = "my_avoidance"

    class Params(PluginParams):
        radius: float = Field(3.0, gt=0, description="neighbour distance that triggers it, m")
        factor: float = Field(0.5, gt=0, le=1, description="fraction of velocity kept")

    params: Params  # self.params: the validated options, typed as this class's own (for mypy, editors)

    def __init__(self, params, ctx):
        super().__init__(params, ctx)
        self.slowed = 0

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        distance, _ = sensing.nearest  # the tick's shared k-d tree: each agent's nearest other
        near = (distance < self.params.radius) & world.healthy  # failed agents are left alone
        self.slowed += int(near.sum())
        out = sp.copy()  # never edit the formation's arrays in place
        out.vel[near] *= self.params.factor  # vectorised over agents: no Python loop per agent
        return out

    @hookimpl
    def swarmscene_run_end(self, sim, metrics):
        metrics["my_avoidance.agent_ticks_slowed"] = self.slowed  # prefixed with the plugin's name


@hookimpl
def swarmscene_register_avoidances(register):
    register(MyAvoidance)
