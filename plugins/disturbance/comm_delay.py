"""The ``comm_delay`` disturbance model: registered here, its numerics in
:mod:`swarmscene.core.disturbances.comm` (the kernel's phases call it, so the class lives in core)."""

from swarmscene.core.disturbances.comm import CommDelay
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`CommDelay` to the registry, so that ``disturbances.<key>.kind: comm_delay`` chooses it."""
    register(CommDelay)
