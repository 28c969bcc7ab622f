"""The ``gust`` disturbance model: registered here, its numerics in
:mod:`swarmscene.core.disturbances.wind` (the kernel's phases call it, so the class lives in core)."""

from swarmscene.core.disturbances.wind import Gust
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Gust` to the registry, so that ``disturbances.<key>.kind: gust`` chooses it."""
    register(Gust)
