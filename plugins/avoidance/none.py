"""No avoidance: the formation's setpoints pass through unchanged (a baseline for comparison)."""

from __future__ import annotations

from swarmscene.plugin import Avoidance, Setpoints, hookimpl


class NoAvoidance(Avoidance):
    """Pass-through."""

    name = "none"

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        """The formation's setpoints unchanged: the baseline with no avoidance."""
        return sp


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`NoAvoidance` to the registry, so that ``avoidance=none`` chooses it."""
    register(NoAvoidance)
