"""The ``packet_loss`` disturbance model: registered here, its numerics in
:mod:`swarmscene.core.disturbances.comm` (the kernel's phases call it, so the class lives in core)."""

from swarmscene.core.disturbances.comm import PacketLoss
from swarmscene.plugin import hookimpl


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`PacketLoss` to the registry, so that ``disturbances.<key>.kind: packet_loss`` chooses it."""
    register(PacketLoss)
