"""The ``radio`` disturbance model: range, distance-dependent loss in bursts, latency, a message budget.

Numerics and sources: :mod:`swarmscene.methods.physics.radio` (log-distance path loss and the
packet reception rate of FSK, Zuniga and Krishnamachari 2004) over Gilbert-Elliott chains
(:mod:`swarmscene.methods.disturbances.links`). A communicate phase model that joins the engine's
broadcast channel and link layer as a delay and loss model (core/disturbances/channel.py):

* the shared picture (what formation and avoidance read): each sender's broadcast of a tick is
  lost when its chain is bad, or with probability 1 - PRR(d) at the distance d to its nearest
  member within ``range`` (every message is lost when none is); it arrives ``latency`` later;
* the per-link layer (``BuildContext.link_loss`` / ``link_delay``, for formations that keep
  per-link maps): each link (receiver i, sender j) has its own chain and distance, beyond
  ``range`` nothing arrives, each hop adds ``latency``, and a radio takes at most
  ``budget`` x T_s messages per tick, its nearest senders first.

Metrics: ``mean_reception`` (the mean PRR over the links within range, per tick, averaged),
``budget_dropped`` (messages the per-link layer dropped for the budget).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances import links
from swarmscene.methods.physics import radio
from swarmscene.plugin import Disturbance, DisturbanceParams, hookimpl


class Radio(Disturbance):
    """A Crazyflie-class 2.4 GHz radio: path loss, FSK reception, bursts, latency and budget."""

    name = "radio"
    phase = "communicate"

    class Params(DisturbanceParams):
        range: float | None = Field(None, gt=0, le=1e7, description="m: nothing arrives beyond it "
                                    "(null: comm.range)")
        tx_power: float = Field(0.0, ge=-100, le=60, description="P_t, dBm (Crazyflie nRF51: 0)")
        loss_d0: float = Field(float(radio.FRIIS_1M_2G4), ge=0, le=200,
                               description="PL(d_0 = 1 m), dB (Friis at 2.4 GHz: 40.05)")
        exponent: float = Field(2.0, gt=0, le=10, description="path-loss exponent n (free space 2; "
                                "indoors 2.7-3.5)")
        noise: float = Field(-93.0, ge=-200, le=0, description="P_n, dBm (puts the nRF24's -82 dBm "
                             "sensitivity at 2 Mbps at BER 1e-3)")
        frame_bytes: int = Field(32, ge=1, le=65535, description="L, bytes per message (ESB payload 32)")
        p_gb: float = Field(0.01, ge=0, le=1, description="Gilbert-Elliott good -> bad per tick")
        p_bg: float = Field(0.5, gt=0, le=1, description="Gilbert-Elliott bad -> good per tick "
                            "(mean burst 1 / p_bg ticks)")
        latency: float = Field(0.0, ge=0, le=60, description="s per message (per hop on the per-link "
                               "layer)")
        budget: float | None = Field(None, gt=0, le=1e9, description="messages a radio takes per "
                                     "second (null: no limit), on the per-link layer")

    params: Params

    def __init__(self, params: Radio.Params, ctx) -> None:
        super().__init__(params, ctx)
        from swarmscene.methods.physics.cells import nearest_distance  # numba: imported when built

        self._nearest = nearest_distance
        self.range = params.range if params.range is not None else ctx.comm_range
        self.T_s = ctx.guidance_period
        self.max_ticks = links.fixed_delay_ticks(params.latency, self.T_s)
        self.per_tick = None if params.budget is None else int(math.floor(params.budget * self.T_s + 1e-9))
        self.chains = links.GilbertElliott(ctx.n, self.rng, params.p_gb, params.p_bg, 0.0, 1.0)
        self.link_chains: links.GilbertElliott | None = None
        self.prr_sum = 0.0
        self.prr_count = 0
        self.dropped = 0

    def reception(self, d: np.ndarray) -> np.ndarray:
        """PRR at distances ``d`` (0 beyond ``range``)."""
        p = self.params
        prr = radio.reception_rate(d, p.tx_power, p.loss_d0, p.exponent, p.noise, p.frame_bytes)
        return np.where(np.asarray(d) <= self.range, prr, 0.0)

    def delays(self, world, sensing):
        """Ticks each sender's message takes, (N,): ceil(latency / T_s)."""
        return np.full(world.n, self.max_ticks, dtype=np.int64)

    def lost(self, world, sensing):
        """Each sender's broadcast lost this tick, (N,) bool (module docstring)."""
        n = world.n
        d = self._nearest(np.ascontiguousarray(world.pos, dtype=np.float64))  # to the nearest other agent
        prr = self.reception(d)
        within = np.isfinite(d) & (d <= self.range)
        if within.any():
            self.prr_sum += float(prr[within].mean())
            self.prr_count += 1
        bad = self.chains.step()
        return bad | (self.rng.random(n) >= prr)

    def link_delay(self, hops):
        """Per-link delays, ticks: ceil(hops latency / T_s), -1 where unreachable."""
        return links.hop_delay_ticks(hops, self.params.latency, self.T_s)

    def link_lost(self, world):
        """Messages (receiver i, sender j) lost this tick, (N, N) bool (module docstring)."""
        n = world.n
        if self.link_chains is None:
            self.link_chains = links.GilbertElliott((n, n), self.rng, self.params.p_gb, self.params.p_bg, 0.0, 1.0)
        diff = world.pos[:, None, :] - world.pos[None, :, :]
        d = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        prr = self.reception(d)
        arrived = ~self.link_chains.step() & (self.rng.random((n, n)) < prr)
        np.fill_diagonal(arrived, True)
        if self.per_tick is not None:
            others = arrived.copy()
            np.fill_diagonal(others, False)
            kept = radio.within_budget(d, others, self.per_tick)
            self.dropped += int(others.sum() - kept.sum())
            np.fill_diagonal(kept, True)
            arrived = kept
        return ~arrived

    def metrics(self):
        """``mean_reception`` and, with a budget, ``budget_dropped``."""
        out = {"mean_reception": self.prr_sum / self.prr_count if self.prr_count else None}
        if self.per_tick is not None:
            out["budget_dropped"] = self.dropped
        return out


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`Radio` to the registry, so that ``disturbances=[radio]`` chooses it."""
    register(Radio)
