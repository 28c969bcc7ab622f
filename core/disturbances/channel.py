"""The broadcast channel of the communicate phase: the messages in flight and the swarm's picture.

The picture the formation and avoidance plugins read (``world.pos``/``vel`` in the communicate
phase) is a broadcast channel: every tick each agent sends its own estimate; a message is lost or
delayed as the declared models say (a model joins by its methods: ``delays`` with ``max_ticks``,
``lost``; :class:`DelayModel`, :class:`LossModel`), and row j of the picture is the newest message
of j that has arrived (the last one is kept while none arrives). Loss and delay are drawn per sender
and tick, so every receiver sees the same row j: one array serves every plugin unchanged. A plugin
that keeps per-link maps (the thesis' ``outdoor_mission``) gets the per-link delay
(``BuildContext.link_delay``) and loss (``BuildContext.link_loss``) of the models that offer them
and reads the estimates without the channel's delay (``Formation.models_communication``). The
built-in models (``comm_delay``, ``packet_loss``, ``radio``) are plugins (``plugins/disturbance/``);
their numerics are :mod:`swarmscene.methods.disturbances.links`.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from ..state import WorldState
from .base import Disturbance

MAX_CHANNEL_BYTES = 2**30
"""Most memory the broadcast channel's message ring may take (validation refuses more)."""
MESSAGE_BYTES = 7 * 8
"""Per agent and tick kept: position and velocity (6 floats) and the arrival tick."""


def channel_errors(models: dict[str, tuple[type[Disturbance], Any]], n: int, T_s: float) -> list[str]:
    """One line when the declared models' delays (each model's ``channel_ticks``, known before the
    run) make the channel's ring exceed ``MAX_CHANNEL_BYTES``; it names the longest-delaying model
    and, where it declares one, its ``delay_option``."""
    ticks = {k: cls.channel_ticks(p, n, T_s) for k, (cls, p) in models.items()}
    delays = {k: t for k, t in ticks.items() if t > 0}
    if not delays:
        return []
    depth = sum(delays.values()) + 1
    need = depth * n * MESSAGE_BYTES
    if need <= MAX_CHANNEL_BYTES:
        return []
    key = max(delays, key=lambda k: delays[k])
    cls, params = models[key]
    option = getattr(cls, "delay_option", None)
    where, got = (f"{key}.{option}", f" (got {getattr(params, option)})") if option else (key, "")
    return [f"disturbances.{where}: the channel would keep {depth} ticks of {n} agents' messages "
            f"({need / 2**30:.3g} GiB, at most {MAX_CHANNEL_BYTES / 2**30:.3g}); shorten the delay or "
            f"lengthen clock.guidance_period{got}"]


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
    """A delay model of the channel (``comm_delay``'s, a package's): what the channel calls."""

    max_ticks: int

    def delays(self, world: WorldState, sensing: Any) -> np.ndarray:
        """Ticks each agent's message of this tick takes, (N,) int."""


class LossModel(Protocol):
    """A loss model of the channel (``packet_loss``'s, a package's): what the channel calls."""

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

