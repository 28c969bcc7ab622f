"""The ``drift`` event kind: registered here; its semantics in :mod:`swarmscene.core.events`
(the motions :class:`~swarmscene.core.events.EventQueue` applies are the kernel's, so the class
lives in core)."""

from swarmscene.core.events import Drift
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`Drift` to the registry, so that an event's ``kind: drift`` chooses it."""
    register(Drift)
