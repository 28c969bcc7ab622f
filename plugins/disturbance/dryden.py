"""The ``dryden`` disturbance model: registered here, its numerics in
:mod:`swarmscene.core.disturbances.wind` (the kernel's phases call it, so the class lives in core)."""

from swarmscene.core.disturbances.wind import Dryden
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Dryden` to the registry, so that ``disturbances.<key>.kind: dryden`` chooses it."""
    register(Dryden)
