"""The ``hover`` event kind: an abrupt failure; the vehicle stops where it is and stays there.

It stays for the rest of the run, a physical obstacle (the CEM paper's failure model, its
Assumption 3).
"""

from swarmscene.plugin import EventKindPlugin, Motion, hookimpl


class Hover(EventKindPlugin):
    """Abrupt failure: stops where it is and stays (the CEM paper's failure model)."""

    name = "hover"
    motion = Motion.HOLD
    stays_where_failed = True

    @classmethod
    def apply(cls, event, world, idx):
        """Hover: the agent fails and stops where it is (velocity zero, held by the queue)."""
        super().apply(event, world, idx)
        world.vel[idx] = 0.0


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`Hover` to the registry, so that an event's ``name: hover`` chooses it."""
    register(Hover)
