"""Slowdown: an avoidance method that scales down the velocity of agents near a neighbour.

A deliberately small example of a third-party swarmscene plugin: swarmscene's avoidance template
(plugins/avoidance/_template.py) with its names changed: a class with a ``name`` and a pydantic
``Params`` model, registered through a hook, with a lifecycle hook contributing a metric.
"""

from __future__ import annotations

from pydantic import Field

from swarmscene.plugin import Avoidance, PluginParams, Setpoints, hookimpl


class Slowdown(Avoidance):
    """Agents with a neighbour closer than ``radius`` keep ``factor`` of their velocity."""

    name = "slowdown"

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
        metrics["slowdown.agent_ticks_slowed"] = self.slowed  # prefixed with the plugin's name


@hookimpl
def swarmscene_register_avoidances(register):
    register(Slowdown)
