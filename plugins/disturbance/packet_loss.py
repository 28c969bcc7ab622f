"""The ``packet_loss`` disturbance model: lost broadcasts (Bernoulli, Gilbert-Elliott bursts, or by range).

A communicate phase model that joins the engine's broadcast channel (``lost``, per sender and tick)
and its per-link layer (``link_lost``, per link and tick). Numerics and sources:
:mod:`swarmscene.methods.disturbances.links` (Gilbert 1960, Elliott 1963).
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances import links
from swarmscene.plugin import Disturbance, DisturbanceContext, DisturbanceParams, WorldState, hookimpl


class PacketLossParams(DisturbanceParams):
    """``name: packet_loss``: the loss law and its probabilities."""

    model: Literal["bernoulli", "gilbert_elliott", "range"] = Field(
        "bernoulli", description="bernoulli: independent losses of probability p; "
        "gilbert_elliott: bursts (two-state Markov chain per sender); range: p rises with the "
        "distance to the nearest member linked to the sender")
    p: float = Field(0.1, ge=0.0, le=1.0, description="bernoulli: loss probability; range: p_0 "
                     "within range_start")
    p_gb: float = Field(0.05, ge=0.0, le=1.0, description="gilbert_elliott: good -> bad per tick")
    p_bg: float = Field(0.5, gt=0.0, le=1.0, description="gilbert_elliott: bad -> good per tick "
                        "(mean burst 1 / p_bg ticks when loss_bad = 1, loss_good = 0)")
    loss_good: float = Field(0.0, ge=0.0, le=1.0, description="gilbert_elliott: loss probability, good")
    loss_bad: float = Field(1.0, ge=0.0, le=1.0, description="gilbert_elliott: loss probability, bad")
    range_start: float = Field(
        0.5, ge=0.0, le=1.0, description="range: fraction of comm.range up to which the loss is p")


class PacketLoss(Disturbance):
    """Loss of broadcasts: Bernoulli, Gilbert-Elliott bursts, or rising with range."""

    name = "packet_loss"
    phase = "communicate"
    Params = PacketLossParams

    params: PacketLossParams

    def __init__(self, params: PacketLossParams, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.comm_range = ctx.comm_range
        self.chains = (links.GilbertElliott(ctx.n, self.rng, params.p_gb, params.p_bg,
                                            params.loss_good, params.loss_bad)
                       if params.model == "gilbert_elliott" else None)
        self.link_chains: links.GilbertElliott | None = None

    def lost(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Which agents' messages of this tick are lost, (N,) bool."""
        p, n = self.params, world.n
        if p.model == "bernoulli":
            return self.rng.random(n) < p.p
        if p.model == "gilbert_elliott":
            assert self.chains is not None  # built for this model in __init__
            return self.chains.step()
        d = sensing.nearest[0] if n > 1 else np.full(n, np.inf)
        prob = links.range_loss_probability(d, p.p, p.range_start * self.comm_range, self.comm_range)
        return self.rng.random(n) < prob

    def link_lost(self, world: WorldState) -> np.ndarray:
        """Which messages (receiver i, sender j) of this tick are lost, (N, N) bool, for plugins
        that keep per-link maps: the same laws per link (Gilbert-Elliott: a chain per link; range:
        the link's length)."""
        p, n = self.params, world.n
        if p.model == "bernoulli":
            return self.rng.random((n, n)) < p.p
        if p.model == "gilbert_elliott":
            if self.link_chains is None:
                self.link_chains = links.GilbertElliott((n, n), self.rng, p.p_gb, p.p_bg, p.loss_good, p.loss_bad)
            return self.link_chains.step()
        diff = world.pos[:, None, :] - world.pos[None, :, :]
        d = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        prob = links.range_loss_probability(d, p.p, p.range_start * self.comm_range, self.comm_range)
        return self.rng.random((n, n)) < prob


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`PacketLoss` to the registry, so that ``disturbances.<key>.name: packet_loss`` chooses it."""
    register(PacketLoss)
