"""Communication models of the ``disturbances`` group: delay and packet loss.

The picture the formation and avoidance plugins read (``world.pos``/``vel`` in the communicate
phase) is a broadcast channel: every tick each agent sends its own estimate; a message is lost or
delayed as the models say, and row j of the picture is the newest message of j that has arrived
(the last one is kept while none arrives). Loss and delay are drawn per sender and tick, so every
receiver sees the same row j: one array serves every plugin unchanged. A plugin that keeps per-link
maps (the thesis' ``outdoor_mission``) gets the per-link delay model itself
(``BuildContext.link_delay``, hop-proportional, thesis section 4.2) and loss
(``BuildContext.link_loss``, per link and tick) and reads the estimates without the channel's
delay (``Formation.models_communication``). Numerics: :mod:`~swarmscene.core.disturbances.links`.
"""

from __future__ import annotations

from typing import Any, Literal, Protocol

import numpy as np
from pydantic import Field

from ..state import WorldState
from . import links as numerics
from .base import Disturbance, DisturbanceContext, DisturbanceParams

MAX_DELAY = 60.0
"""s: the longest delay a model accepts, and the most the channel keeps of messages."""
MAX_CHANNEL_BYTES = 2**30
"""Most memory the broadcast channel's message ring may take (validation refuses more)."""
MESSAGE_BYTES = 7 * 8
"""Per agent and tick kept: position and velocity (6 floats) and the arrival tick."""


class CommDelay(Disturbance):
    """Latency of every agent's broadcast: fixed, hop-proportional, or random."""

    kind = "comm_delay"
    phase = "communicate"

    class Params(DisturbanceParams):
        model: Literal["fixed", "hops", "random"] = Field(
            "hops", description="fixed: tau; hops: tau per hop (thesis 4.2: tau_ij = dist(i, j) "
            "tau_com; in the shared picture, the mean over the sender's reachable receivers); "
            "random: tau plus an exponential delay of mean jitter")
        tau: float = Field(
            0.2, ge=0.0, le=MAX_DELAY, description="latency, s (hops: the single-hop delay tau_com; "
            "thesis ~0.2 s)")
        jitter: float = Field(
            0.1, ge=0.0, le=MAX_DELAY, description="random: mean of the exponential extra delay, s")

    params: Params

    def __init__(self, params: CommDelay.Params, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.T_s = ctx.guidance_period
        self.tau_com = params.tau
        self.max_ticks = max_delay_ticks(params, ctx.n, self.T_s)

    def delays(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Ticks each agent's message of this tick takes, (N,) int."""
        p, n = self.params, world.n
        if p.model == "fixed":
            return np.full(n, numerics.fixed_delay_ticks(p.tau, self.T_s))
        if p.model == "random":
            return numerics.random_delay_ticks(self.rng, n, p.tau, p.jitter, self.T_s)
        from scipy.sparse.csgraph import shortest_path

        hops = shortest_path(sensing.comm_adjacency, unweighted=True)
        ticks = numerics.hop_delay_ticks(hops, p.tau, self.T_s).astype(float)
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
            return numerics.hop_delay_ticks(hops, p.tau, self.T_s)
        reachable = np.isfinite(hops)
        if p.model == "fixed":
            ticks = np.full(hops.shape, numerics.fixed_delay_ticks(p.tau, self.T_s))
        else:
            ticks = numerics.random_delay_ticks(self.rng, hops.shape, p.tau, p.jitter, self.T_s)
        return np.where(reachable, ticks, -1).astype(np.int64)


def max_delay_ticks(params: CommDelay.Params, n: int, T_s: float) -> int:
    """The longest delay the channel must keep, ticks: fixed tau; hops (n - 1) tau (the mean over
    receivers is at most that); random tau + 10 jitter (P(X > 10 jitter) = e^-10: rarer, longer
    delays are cut to it); never more than ``MAX_DELAY``."""
    span = {"fixed": params.tau, "hops": max(n - 1, 1) * params.tau,
            "random": params.tau + 10.0 * params.jitter}[params.model]
    return numerics.fixed_delay_ticks(min(span, MAX_DELAY), T_s)


def channel_errors(models: dict[str, tuple[type, Any]], n: int, T_s: float) -> list[str]:
    """One line when the declared delays make the channel's ring exceed ``MAX_CHANNEL_BYTES``."""
    delays = {k: p for k, (cls, p) in models.items() if cls is CommDelay}
    if not delays:
        return []
    depth = sum(max_delay_ticks(p, n, T_s) for p in delays.values()) + 1
    need = depth * n * MESSAGE_BYTES
    if need <= MAX_CHANNEL_BYTES:
        return []
    key = max(delays, key=lambda k: max_delay_ticks(delays[k], n, T_s))
    return [f"disturbances.{key}.tau: the channel would keep {depth} ticks of {n} agents' messages "
            f"({need / 2**30:.3g} GiB, at most {MAX_CHANNEL_BYTES / 2**30:.3g}); shorten the delay or "
            f"lengthen clock.guidance_period (got {delays[key].tau})"]


class PacketLoss(Disturbance):
    """Loss of broadcasts: Bernoulli, Gilbert-Elliott bursts, or rising with range."""

    kind = "packet_loss"
    phase = "communicate"

    class Params(DisturbanceParams):
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

    params: Params

    def __init__(self, params: PacketLoss.Params, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        self.comm_range = ctx.comm_range
        self.chains = (numerics.GilbertElliott(ctx.n, self.rng, params.p_gb, params.p_bg,
                                               params.loss_good, params.loss_bad)
                       if params.model == "gilbert_elliott" else None)
        self.link_chains: numerics.GilbertElliott | None = None

    def lost(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Which agents' messages of this tick are lost, (N,) bool."""
        p, n = self.params, world.n
        if p.model == "bernoulli":
            return self.rng.random(n) < p.p
        if p.model == "gilbert_elliott":
            assert self.chains is not None  # built for this model in __init__
            return self.chains.step()
        d = sensing.nearest[0] if n > 1 else np.full(n, np.inf)
        prob = numerics.range_loss_probability(d, p.p, p.range_start * self.comm_range, self.comm_range)
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
                self.link_chains = numerics.GilbertElliott((n, n), self.rng, p.p_gb, p.p_bg,
                                                           p.loss_good, p.loss_bad)
            return self.link_chains.step()
        diff = world.pos[:, None, :] - world.pos[None, :, :]
        d = np.sqrt(np.einsum("ijk,ijk->ij", diff, diff))
        prob = numerics.range_loss_probability(d, p.p, p.range_start * self.comm_range, self.comm_range)
        return self.rng.random((n, n)) < prob


class Channel:
    """The broadcast channel of the communicate phase: messages in flight and the picture.

    Each tick k every agent j sends (pos, vel); the message arrives at k + d_j unless lost; row j of
    the picture is the newest arrived message of j (by send time). Kept for ``depth`` ticks.
    """

    def __init__(self, pos: np.ndarray, vel: np.ndarray, depth: int) -> None:
        n = pos.shape[0]
        self.depth = depth + 1
        self.sent_pos = np.repeat(pos[None], self.depth, axis=0)
        self.sent_vel = np.repeat(vel[None], self.depth, axis=0)
        self.arrive = np.full((self.depth, n), np.iinfo(np.int64).max)
        self.shown = np.full(n, -1, dtype=np.int64)      # send tick of the row shown
        self.pos, self.vel = pos.copy(), vel.copy()
        self.k = 0
        self.sent = self.lost = self.age_sum = 0

    def send(self, pos: np.ndarray, vel: np.ndarray, delay: np.ndarray,
             lost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Send this tick's states, each message delayed ``delay`` ticks or ``lost``; returns the
        picture of each agent the others hold now, (pos, vel): its newest message that has arrived."""
        k, slot = self.k, self.k % self.depth
        n = pos.shape[0]
        self.sent_pos[slot], self.sent_vel[slot] = pos, vel
        self.arrive[slot] = np.where(lost, np.iinfo(np.int64).max, k + np.minimum(delay, self.depth - 1))
        # newest arrived message per sender: send ticks of the slots, masked where not arrived
        ticks = k - (slot - np.arange(self.depth)) % self.depth
        arrived = (self.arrive <= k) & (ticks[:, None] > self.shown[None, :]) & (ticks[:, None] >= 0)
        newest = np.where(arrived, ticks[:, None], -1).max(axis=0)
        update = newest > self.shown
        idx = np.flatnonzero(update)
        src = newest[idx] % self.depth
        self.pos[idx], self.vel[idx] = self.sent_pos[src, idx], self.sent_vel[src, idx]
        self.shown[update] = newest[update]
        self.sent += n
        self.lost += int(lost.sum())
        self.age_sum += int((k - np.maximum(self.shown, 0)).sum())
        self.k += 1
        return self.pos.copy(), self.vel.copy()


class DelayModel(Protocol):
    """A delay model of the channel (``CommDelay``, a plugin's): what the channel calls."""

    max_ticks: int

    def delays(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Ticks each agent's message of this tick takes, (N,) int."""


class LossModel(Protocol):
    """A loss model of the channel (``PacketLoss``, a plugin's): what the channel calls."""

    def lost(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Which agents' messages of this tick are lost, (N,) bool."""


class ChannelModels:
    """The communicate phase's models of one run, combined into one channel (delays add, a message
    lost by any loss model is lost)."""

    def __init__(self, delays: list[DelayModel], losses: list[LossModel]) -> None:
        self.delays, self.losses = delays, losses
        self.channel: Channel | None = None

    def communicate(self, world: WorldState, sensing: Any, pos: np.ndarray, vel: np.ndarray):
        """The communicate phase: delays of every delay model add, a message lost by any loss model
        is lost; returns what the swarm sees of each agent, (pos, vel)."""
        n = world.n
        delay = np.zeros(n, dtype=np.int64)
        for model in self.delays:
            delay = delay + model.delays(world, sensing)
        lost = np.zeros(n, dtype=bool)
        for loss in self.losses:
            lost |= loss.lost(world, sensing)
        if self.channel is None:
            depth = sum(m.max_ticks for m in self.delays)
            self.channel = Channel(pos, vel, depth)
        return self.channel.send(pos, vel, delay, lost)

    def metrics(self) -> dict[str, Any]:
        """Fraction of messages lost and mean age of the picture, in ticks, over the run (none before
        a message is sent)."""
        c = self.channel
        if c is None or not c.sent:
            return {}
        return {"disturbances.comm.loss_rate": c.lost / c.sent,
                "disturbances.comm.mean_age": c.age_sum / c.sent}


MODELS = (CommDelay, PacketLoss)
