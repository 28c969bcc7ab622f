"""The thesis' swarm map (section 4.3.1, "Communication"), for every agent at once, as arrays.

Every agent broadcasts a message (agentId, swarmId, timeStamp, taskState, position, velocity,
input) each T_s; each agent keeps an unordered map of the last message received from every
other agent and removes entries not updated for more than T_msg. HEAVEN relays messages over
several hops, with a delay proportional to the hop distance (section 4.2):

    tau_ij = dist(i, j) tau_com                                                  (section 4.2)

Representation (vectorised, no per-agent dictionaries): a ring buffer holds the last ``depth``
broadcasts of every agent (tick-indexed history), and the maps are (N observers x N entries)
arrays: ``stamp[i, j]`` is the tick at which j sent the message i holds about j (-1: none), and
``state``, ``pos``, ``vel``, ``u`` hold that message's fields. At tick k observer i holds j's
message of tick k - ceil(tau_ij / T_s), when j was broadcasting then and the two are connected
now; the ring only needs ``T_msg / T_s + 1`` ticks since an older message would expire on
arrival.

Choices where the text is loose:
- An agent's own message enters its map through its network node like any other, one hop
  late (``self_hops``, default 1): a map is then one consistent snapshot of the swarm, the
  same for every agent at the same hop distances, so the distributed assignment (eq. 4.12)
  computed on it agrees between agents; control still uses the agent's own true state.
- The hop distance is taken on the communication graph of the current tick (range d_com,
  members: healthy agents with a working radio, exactly the engine's ``Sensing.comm_members``):
  a message in flight to an agent that has just been cut off is lost.
- Expiry: an entry is present while its age k - stamp is at most T_msg / T_s ticks.

The per-link delays are the engine's delay model (:mod:`swarmscene.methods.disturbances.links`,
``hop_delay_ticks``: the same ceil(h tau_com / T_s)), or the scenario's declared ``comm_delay``
disturbance when the plugin is given one (``link_delay``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import scipy  # scipy.spatial loads on first use (start-up of unrelated runs)

from swarmscene.methods.disturbances.links import adjacency_hop_counts, hop_delay_ticks
from swarmscene.methods.outdoor.apf_navigation import LEVEL_BAND, collision_gain

NO_ENTRY = -1
"""``stamp`` of an entry never received."""

DENSE_HOPS_LIMIT = 400
"""Up to this many agents the communication graph is built from a dense distance matrix."""


def hop_matrix(pos: np.ndarray, members: np.ndarray, d_com: float, tree=None) -> np.ndarray:
    """dist(i, j): hops between every pair over the communication graph, (N, N) float.

    Args:
        pos: (N, 3) positions.
        members: (N,) bool, agents taking part in communication.
        d_com: communication range, m (two members closer than this are one hop apart).
        tree: optional cKDTree over ``pos`` (used instead of a dense matrix for large N).

    Returns:
        hops, 0 on the diagonal, ``inf`` between agents not connected (and for non-members).
    """
    n = pos.shape[0]
    idx = np.flatnonzero(members)
    hops = np.full((n, n), np.inf)
    np.fill_diagonal(hops, 0.0)
    m = idx.size
    if m < 2:
        return hops
    if n <= DENSE_HOPS_LIMIT or tree is None:
        within = scipy.spatial.distance.pdist(pos[idx]) <= d_com
        if within.all():
            adjacent = None
        else:
            adjacent = scipy.spatial.distance.squareform(within)
    else:
        pairs = tree.query_pairs(d_com, output_type="ndarray")
        keep = members[pairs[:, 0]] & members[pairs[:, 1]]
        rank = np.full(n, -1)
        rank[idx] = np.arange(m)
        a, b = rank[pairs[keep, 0]], rank[pairs[keep, 1]]
        adjacent = np.zeros((m, m), dtype=bool)
        adjacent[a, b] = adjacent[b, a] = True
    if adjacent is None or adjacent.sum() == m * (m - 1):  # all in range of all: one hop
        sub = np.ones((m, m))
        np.fill_diagonal(sub, 0.0)
    else:
        sub = adjacency_hop_counts(adjacent)
    hops[np.ix_(idx, idx)] = sub
    return hops


class SwarmMap:
    """Every agent's local swarm map, updated once per guidance tick.

    Args:
        n: number of agents.
        T_s: broadcast (guidance) period, s.
        tau_com: single-hop delay tau_com, s (thesis: <= 3 T_s, measured ~0.2 s).
        T_msg: data storage time, s: entries older than this are removed.
        swarm_id: (N,) swarm identifier of each agent (messages of other swarms are dropped);
            None: all in swarm 0.
        self_hops: hops through which an agent's own message reaches its own map (see module).
        link_delay: ``hops (N, N) -> ticks (N, N)`` (-1: unreachable), the engine's declared delay
            model (``BuildContext.link_delay``); None: hop-proportional at ``tau_com``.
    """

    def __init__(self, n: int, T_s: float, tau_com: float, T_msg: float,
                 swarm_id: np.ndarray | None = None, self_hops: int = 1,
                 link_delay: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        self.n, self.T_s, self.tau_com, self.T_msg = n, T_s, tau_com, T_msg
        self.link_delay = link_delay or (lambda hops: hop_delay_ticks(hops, tau_com, T_s))
        self.msg_ticks = int(math.floor(T_msg / T_s + 1e-9))
        self.depth = self.msg_ticks + 1
        self.swarm_id = np.zeros(n, dtype=int) if swarm_id is None else np.asarray(swarm_id)
        self.same_swarm = self.swarm_id[:, None] == self.swarm_id[None, :]
        self.self_hops = self_hops
        # ring of broadcasts, indexed by tick % depth
        self.h_sent = np.zeros((self.depth, n), dtype=bool)
        self.h_state = np.zeros((self.depth, n), dtype=np.int8)
        self.h_kin = np.zeros((self.depth * n, 9))  # rows tick-slot * n + agent: pos, vel, u
        # the maps: observer i (row), entry j (column)
        self.stamp = np.full((n, n), NO_ENTRY, dtype=np.int64)
        self.row = np.zeros((n, n), dtype=np.int64)  # ring row (slot * n + j) of each entry
        self.state = np.zeros((n, n), dtype=np.int8)
        self.present = np.zeros((n, n), dtype=bool)
        self.k = -1
        self._hops: np.ndarray | None = None
        self._delay = np.zeros((n, n), dtype=np.int64)
        self._cols = np.broadcast_to(np.arange(n), (n, n))

    # The entries' (position, velocity, input) are read from the ring on demand: an entry is
    # present only while its message is at most T_msg old, i.e. still in the ring. An absent
    # entry reads some message of the same agent: callers mask with ``present``.

    def kin(self, i, j) -> np.ndarray:
        """(position, velocity, input) that observer(s) ``i`` hold about ``j``, shape (..., 9)."""
        return self.h_kin[self.row[i, j]]

    def positions(self, i, j) -> np.ndarray:
        """Position observer(s) ``i`` hold for agent(s) ``j``, shape (..., 3)."""
        return self.h_kin[self.row[i, j], 0:3]

    @property
    def pos(self) -> np.ndarray:
        """Every map's positions, (N, N, 3) (a full gather: for inspection and tests)."""
        return self.h_kin[self.row, 0:3]

    @property
    def vel(self) -> np.ndarray:
        """Every map's velocities, (N, N, 3)."""
        return self.h_kin[self.row, 3:6]

    @property
    def u(self) -> np.ndarray:
        """Every map's inputs, (N, N, 3)."""
        return self.h_kin[self.row, 6:9]

    def delay_ticks(self, hops: np.ndarray) -> np.ndarray:
        """The link delays, ticks, -1 where unreachable (inf hops): by default ceil(hops tau_com
        / T_s) (section 4.2), an agent's own message taking ``self_hops`` hops."""
        hops = np.array(hops, dtype=float, copy=True)
        np.fill_diagonal(hops, np.where(np.isfinite(np.diag(hops)), self.self_hops, np.inf))
        return self.link_delay(hops)

    def broadcast(self, k: int, sending: np.ndarray, state: np.ndarray, pos: np.ndarray,
                  vel: np.ndarray, u: np.ndarray) -> None:
        """Tick k: agents with ``sending`` True broadcast their (state, position, velocity, input).

        Called once per tick, k = 0, 1, 2, ... (the ring slots are then always current).
        """
        slot = k % self.depth
        self.k = k
        self.h_sent[slot] = sending
        self.h_state[slot] = state
        rows = self.h_kin[slot * self.n:(slot + 1) * self.n]
        rows[:, 0:3], rows[:, 3:6], rows[:, 6:9] = pos, vel, u

    def deliver(self, hops: np.ndarray, lost: np.ndarray | None = None) -> np.ndarray:
        """Update every map with the messages arriving at the current tick; returns ``present``.

        Args:
            hops: (N, N) hop distances of this tick (:func:`hop_matrix`), inf: not connected.
            lost: (N, N) bool, the messages (receiver i, sender j) lost on their way this tick
                (the engine's declared packet loss, ``BuildContext.link_loss``): the entry keeps
                the last message that arrived. None: none lost.
        """
        k, cols = self.k, self._cols
        if hops is not self._hops:  # a new graph: new delays (else the last tick's are reused)
            self._hops, self._delay = hops, self.delay_ticks(hops)
            self._reachable = (self._delay >= 0) & (self._delay < self.depth) & self.same_swarm
        sent = k - self._delay  # the tick of the message that arrives now
        slot = sent % self.depth
        usable = self._reachable
        if k < self.depth:  # the ring is not full yet
            usable = usable & (sent >= 0)
        if not self.h_sent.all():  # somebody was silent within the last T_msg
            usable = usable & self.h_sent[slot, cols]
        if lost is not None:
            usable = usable & ~lost
        update = usable & (sent > self.stamp)
        if update.all():  # the usual case: every entry refreshed
            self.stamp[...] = sent
            np.multiply(slot, self.n, out=self.row)
            self.row += cols
        elif update.any():
            self.stamp[update] = sent[update]
            self.row[update] = slot[update] * self.n + cols[update]
        self.state = self.h_state.reshape(-1)[self.row]
        self.present = (self.stamp != NO_ENTRY) & (k - self.stamp <= self.msg_ticks)
        return self.present

    def age(self) -> np.ndarray:
        """Age of every entry, s (inf where absent)."""
        return np.where(self.present, (self.k - self.stamp) * self.T_s, np.inf)


def map_repulsion(pos, smap: SwarmMap, present, pairs, navigating, d_c, v_sat) -> np.ndarray:
    """v_col of eq. 4.23-4.24 from each agent's own map, (N, 2).

    Agent i is repelled by every j of its map within 2 d_c horizontally and on its flight level
    (|dz| < 2/3 d_c), at the position its map holds for j. ``pairs`` (P, 2) are candidate pairs
    (from the true positions, with a margin); only rows with ``navigating[i]`` are computed.
    """
    n = pos.shape[0]
    v = np.zeros((n, 2))
    if pairs.size == 0:
        return v
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    keep = navigating[i] & present[i, j]
    i, j = i[keep], j[keep]
    delta = smap.positions(i, j) - pos[i]
    dist = np.hypot(delta[:, 0], delta[:, 1])
    on_level = (np.abs(delta[:, 2]) < LEVEL_BAND * d_c) & (dist < 2.0 * d_c)
    i, j, delta, dist = i[on_level], j[on_level], delta[on_level, :2], dist[on_level]
    coincident = dist < 1e-9
    # same fixed tie-break as apf_navigation_math: the lower index goes towards -x
    tie = np.where((i < j)[:, None], [1.0, 0.0], [-1.0, 0.0])
    unit = np.where(coincident[:, None], tie, delta / np.where(coincident, 1.0, dist)[:, None])
    push = collision_gain(dist, d_c, v_sat)[:, None] * unit
    for axis in range(2):
        v[:, axis] = np.bincount(i, push[:, axis], n)
    return v
