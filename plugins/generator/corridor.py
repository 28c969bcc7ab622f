"""The ``corridor`` map generator: registered here; its geometry in :mod:`swarmscene.core.generators`
(shared by the three built-ins and by the environment schema, so it lives in core)."""

from swarmscene.core.generators import Corridor
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_generators(register):
    """Add :class:`Corridor` to the registry, so that ``environment.generator: corridor`` chooses it."""
    register(Corridor)
