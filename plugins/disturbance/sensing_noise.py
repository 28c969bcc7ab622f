"""The ``sensing_noise`` disturbance model: registered here, its numerics in
:mod:`swarmscene.core.disturbances.noise` (the kernel's phases call it, so the class lives in core)."""

from swarmscene.core.disturbances.noise import SensingNoise
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`SensingNoise` to the registry, so that ``disturbances.<key>.kind: sensing_noise`` chooses it."""
    register(SensingNoise)
