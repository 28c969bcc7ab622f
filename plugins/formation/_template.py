"""Template of a formation plugin: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), add ``formation/<name>.yaml`` holding ``name: <name>``,
and check it with ``swarmscene.testing.check_formation(MyFormation)`` in your tests.
Cite the paper's section, symbols and equation numbers here, and say what you chose where the
paper is ambiguous.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydantic import Field

from swarmscene.plugin import (
    BuildContext,
    Formation,
    Mode,
    PluginParams,
    SetpointBatch,
    Setpoints,
    WorldState,
    hookimpl,
)


class MyFormation(Formation):
    """One line on what it does."""

    name = "my_formation"
    requires_leader = False  # True: validation refuses a scenario without swarm.leader

    class Params(PluginParams):
        spacing: float = Field(2.0, gt=0, description="distance between agents, m")

    def __init__(self, params: Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        self.home = ctx.initial.pos.copy()

    def setpoints(self, world: WorldState, sensing) -> Setpoints:
        sp = Setpoints.hold(world.pos)
        sp.mode[:] = Mode.POSITION
        sp.pos[:] = self.home  # vectorised over agents: no Python loop per agent
        return sp

    @classmethod
    def setpoints_batch(cls, formations: Sequence[MyFormation], worlds: Sequence[WorldState],
                        sensings: Sequence[object]) -> SetpointBatch | object:
        """Optional (delete it to plan world by world): ``setpoints`` of B worlds in one pass
        (docs/batched.md), each world's records bit for bit its own ``setpoints``' (the contract
        check ``formation.setpoints_batch_equals_worlds`` holds it). Elementwise numpy over the
        stacked agents gives each agent its own bits; return NotImplemented for a batch you
        cannot take whole."""
        if len({len(world.pos) for world in worlds}) != 1:
            return NotImplemented
        sp = Setpoints.hold(np.concatenate([world.pos for world in worlds]))
        sp.mode[:] = Mode.POSITION
        sp.pos[:] = np.concatenate([f.home for f in formations])
        return SetpointBatch(sp, len(worlds))  # one record of B N agents, world b's rows b N ...

    def complete(self, world: WorldState) -> bool | None:
        return bool(np.all(np.linalg.norm(world.pos - self.home, axis=1) < 0.1))


@hookimpl
def swarmscene_register_formations(register):
    register(MyFormation)
