"""The ``constant_wind`` disturbance model: registered here, its numerics in
:mod:`swarmscene.core.disturbances.wind` (the kernel's phases call it, so the class lives in core)."""

from swarmscene.core.disturbances.wind import ConstantWind
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`ConstantWind` to the registry, so that ``disturbances.<key>.kind: constant_wind`` chooses it."""
    register(ConstantWind)
