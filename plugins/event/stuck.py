"""The ``stuck`` event kind: registered here; its semantics in :mod:`swarmscene.core.events`
(the motions :class:`~swarmscene.core.events.EventQueue` applies are the kernel's, so the class
lives in core)."""

from swarmscene.core.events import Stuck
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`Stuck` to the registry, so that an event's ``kind: stuck`` chooses it."""
    register(Stuck)
