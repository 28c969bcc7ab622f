"""The ``comm_loss`` event kind: registered here; its semantics in :mod:`swarmscene.core.events`
(the motions :class:`~swarmscene.core.events.EventQueue` applies are the kernel's, so the class
lives in core)."""

from swarmscene.core.events import CommLoss
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`CommLoss` to the registry, so that an event's ``kind: comm_loss`` chooses it."""
    register(CommLoss)
