"""No avoidance: the formation's setpoints pass through unchanged (a baseline for comparison)."""

from __future__ import annotations

from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import Avoidance
from swarmscene.core.setpoint import Setpoints


class NoAvoidance(Avoidance):
    """Pass-through."""

    name = "none"

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        return sp


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    register(NoAvoidance)
