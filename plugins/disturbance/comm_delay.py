"""The ``comm_delay`` disturbance model: the latency of every agent's broadcast, fixed, per hop or random.

A communicate phase model that joins the engine's broadcast channel (``delays``) and its per-link
layer (``link_delay``, for plugins that keep per-link maps). Numerics:
:mod:`swarmscene.methods.disturbances.links` (delays in guidance ticks; thesis section 4.2 for the
hop-proportional delay tau_ij = dist(i, j) tau_com).
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances import links
from swarmscene.plugin import Disturbance, DisturbanceContext, DisturbanceParams, WorldState, hookimpl


class CommDelayParams(DisturbanceParams):
    """``name: comm_delay``: the delay's law and its latencies."""

    model: Literal["fixed", "hops", "random"] = Field(
        "hops", description="fixed: tau; hops: tau per hop (thesis 4.2: tau_ij = dist(i, j) "
        "tau_com; in the shared picture, the mean over the sender's reachable receivers); "
        "random: tau plus an exponential delay of mean jitter")
    tau: float = Field(
        0.2, ge=0.0, le=links.MAX_DELAY, description="latency, s (hops: the single-hop delay tau_com; "
        "thesis ~0.2 s)")
    jitter: float = Field(
        0.1, ge=0.0, le=links.MAX_DELAY, description="random: mean of the exponential extra delay, s")


class CommDelay(Disturbance):
    """Latency of every agent's broadcast: fixed, hop-proportional, or random."""

    name = "comm_delay"
    phase = "communicate"
    Params = CommDelayParams
    delay_option = "tau"

    params: CommDelayParams

    def __init__(self, params: CommDelayParams, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.T_s = ctx.guidance_period
        self.tau_com = params.tau
        self.max_ticks = self.channel_ticks(params, ctx.n, self.T_s)

    @classmethod
    def channel_ticks(cls, params: Any, n: int, guidance_period: float) -> int:
        """The longest delay of a message, ticks (:func:`~swarmscene.methods.disturbances.links.max_delay_ticks`)."""
        return links.max_delay_ticks(params.model, params.tau, params.jitter, n, guidance_period)

    def delays(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Ticks each agent's message of this tick takes, (N,) int."""
        p, n = self.params, world.n
        if p.model == "fixed":
            return np.full(n, links.fixed_delay_ticks(p.tau, self.T_s))
        if p.model == "random":
            return links.random_delay_ticks(self.rng, n, p.tau, p.jitter, self.T_s)
        hops = links.hop_counts(sensing.comm_edges, n)
        ticks = links.hop_delay_ticks(hops, p.tau, self.T_s).astype(float)
        ticks[ticks < 0] = np.nan
        np.fill_diagonal(ticks, np.nan)
        with np.errstate(invalid="ignore"):
            mean = np.nanmean(ticks, axis=0) if n > 1 else np.zeros(n)
        return np.ceil(np.nan_to_num(mean, nan=0.0) - 1e-9).astype(np.int64)

    def link_delay(self, hops: np.ndarray) -> np.ndarray:
        """Per-link delays, ticks, of hop distances ``hops`` (N, N) (inf: unreachable, -1 out):
        hops: ceil(h tau_com / T_s) (thesis 4.2); fixed: ceil(tau / T_s) on every reachable link;
        random: a new draw per link at each call (a plugin calls it when its graph changes)."""
        p = self.params
        if p.model == "hops":
            return links.hop_delay_ticks(hops, p.tau, self.T_s)
        reachable = np.isfinite(hops)
        if p.model == "fixed":
            ticks = np.full(hops.shape, links.fixed_delay_ticks(p.tau, self.T_s))
        else:
            ticks = links.random_delay_ticks(self.rng, hops.shape, p.tau, p.jitter, self.T_s)
        return np.where(reachable, ticks, -1).astype(np.int64)


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`CommDelay` to the registry, so that ``disturbances.<key>.name: comm_delay`` chooses it."""
    register(CommDelay)
