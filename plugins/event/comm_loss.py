"""The ``comm_loss`` event kind: the agent's radio fails (``comm_ok`` False); it flies on.

It leaves the communication graph but keeps flying on its last information; it is no failure
(``healthy`` stays).
"""

from swarmscene.plugin import EventKindPlugin, hookimpl


class CommLoss(EventKindPlugin):
    """Radio lost: leaves the communication graph, keeps flying on its last information."""

    name = "comm_loss"
    failure = False


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`CommLoss` to the registry, so that an event's ``name: comm_loss`` chooses it."""
    register(CommLoss)
