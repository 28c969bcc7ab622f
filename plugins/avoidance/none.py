"""No avoidance: the formation's setpoints pass through unchanged (a baseline for comparison)."""

from __future__ import annotations

from collections.abc import Sequence

from swarmscene.plugin import Avoidance, SetpointBatch, Setpoints, hookimpl


class NoAvoidance(Avoidance):
    """Pass-through."""

    name = "none"

    def adjust(self, world, sensing, sp: Setpoints) -> Setpoints:
        """The formation's setpoints unchanged: the baseline with no avoidance."""
        return sp

    @classmethod
    def adjust_batch(cls, avoidances, worlds, sensings, setpoints: Sequence[Setpoints]) -> Sequence[Setpoints]:
        """Every world's setpoints unchanged, as they came: a formation's
        :class:`~swarmscene.core.setpoint.SetpointBatch` stays one, for the controllers' batched form."""
        return setpoints if isinstance(setpoints, SetpointBatch) else list(setpoints)


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Add :class:`NoAvoidance` to the registry, so that ``avoidance=none`` chooses it."""
    register(NoAvoidance)
