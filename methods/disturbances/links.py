"""Communication numerics: link delays and packet-loss processes, vectorised over links.

Delays are counted in guidance ticks (messages leave and arrive at ticks):

* fixed:  d = ceil(tau / T_s)
* hops:   d_ij = ceil(h_ij tau_com / T_s), h_ij the hop distance over the communication graph
          (thesis section 4.2: tau_ij = dist(i, j) tau_com; unreachable: -1)
* random: d = ceil((tau + X) / T_s), X ~ Exponential(mean ``jitter``) (a fixed latency plus a
          queueing delay, the M/M/1 sojourn law), so P(d <= k) = 1 - exp(-(k T_s - tau) / jitter)
          for k T_s >= tau.

Loss:

* Bernoulli: each message lost independently with probability p.
* Gilbert-Elliott (Gilbert 1960, Elliott 1963): each link is a two-state Markov chain, good -> bad
  with probability p_gb per tick, bad -> good with p_bg; a message is lost with probability e_g in
  the good state and e_b in the bad one. Stationary P(bad) = p_gb / (p_gb + p_bg); loss rate
  P(good) e_g + P(bad) e_b; with e_g = 0, e_b = 1 the bursts of losses are geometric with mean
  length 1 / p_bg ticks.
* range: loss probability p_0 up to distance r_0, rising linearly to 1 at the comm range R:
  p(d) = p_0 + (1 - p_0) clip((d - r_0) / (R - r_0), 0, 1) (a simple stand-in for the packet error
  rate of a log-distance path-loss model, which rises steeply near the range's edge).
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-9  # a delay of exactly k ticks (e.g. 0.2 s at T_s = 0.1 s) is k ticks despite rounding


def fixed_delay_ticks(tau: float, T_s: float) -> int:
    """ceil(tau / T_s): the ticks a message of latency ``tau`` s takes."""
    return int(np.ceil(tau / T_s - _EPS)) if tau > 0 else 0


def hop_delay_ticks(hops: np.ndarray, tau_com: float, T_s: float) -> np.ndarray:
    """ceil(hops tau_com / T_s) as int, -1 where unreachable (inf hops) (thesis section 4.2)."""
    reachable = np.isfinite(hops)
    ticks = np.ceil(np.where(reachable, hops, 0.0) * tau_com / T_s - _EPS)
    return np.where(reachable, np.maximum(ticks, 0), -1).astype(np.int64)


DENSE_HOPS = 64
"""Up to this many agents the hops come from a breadth-first search on a dense matrix
(:func:`dense_hop_counts`); more from scipy's sparse ``shortest_path``."""


def hop_counts(edges: np.ndarray, n: int) -> np.ndarray:
    """Hops of a shortest path between every two of ``n`` agents over the undirected links
    ``edges`` (M, 2), (N, N) float: 0 on the diagonal, inf where unreachable (scipy's unweighted
    ``shortest_path``, the same numbers): :func:`dense_hop_counts` up to ``DENSE_HOPS`` agents."""
    if n > DENSE_HOPS:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import shortest_path

        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
        return shortest_path(graph.tocsr(), unweighted=True, directed=False)
    adjacent = np.zeros((n, n), dtype=bool)
    adjacent[edges[:, 0], edges[:, 1]] = adjacent[edges[:, 1], edges[:, 0]] = True
    return dense_hop_counts(adjacent)


def adjacency_hop_counts(adjacent: np.ndarray) -> np.ndarray:
    """:func:`hop_counts` of a graph given as a dense (M, M) bool adjacency: the breadth-first
    search of :func:`dense_hop_counts` up to ``DENSE_HOPS`` agents, scipy's sparse
    ``shortest_path`` beyond."""
    if len(adjacent) <= DENSE_HOPS:
        return dense_hop_counts(adjacent)
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import shortest_path

    return shortest_path(csr_matrix(adjacent), unweighted=True, directed=False)


def dense_hop_counts(adjacent: np.ndarray) -> np.ndarray:
    """Hops of a shortest path between every two agents of the undirected graph ``adjacent``
    (M, M) bool, (M, M) float: 0 on the diagonal, inf where unreachable (scipy's unweighted
    ``shortest_path``, the same numbers), by a breadth-first search from every agent at once: about
    10 us for 5 agents, where a sparse graph's checks alone cost about 0.5 ms a call. For a few
    agents (``DENSE_HOPS``): each hop is a product of M x M matrices."""
    m = len(adjacent)
    step = adjacent.astype(np.int16)
    hops = np.full((m, m), np.inf)
    reached = np.eye(m, dtype=bool)
    hops[reached] = 0.0
    frontier = reached.astype(np.int16)
    for h in range(1, m):
        new = ((frontier @ step) > 0) & ~reached  # row i: agents one more hop from agent i
        if not new.any():
            break
        hops[new] = h
        reached |= new
        frontier = new.astype(np.int16)
    return hops


def random_delay_ticks(rng: np.random.Generator, shape, tau: float, jitter: float, T_s: float) -> np.ndarray:
    """ceil((tau + X) / T_s), X ~ Exponential(mean ``jitter``) (0: the fixed delay)."""
    extra = rng.exponential(jitter, shape) if jitter > 0 else np.zeros(shape)
    return np.maximum(np.ceil((tau + extra) / T_s - _EPS), 0).astype(np.int64)


def random_delay_cdf(k: np.ndarray, tau: float, jitter: float, T_s: float) -> np.ndarray:
    """P(d <= k) of :func:`random_delay_ticks` (the reference of its tests)."""
    slack = np.asarray(k, dtype=float) * T_s - tau
    return np.where(slack >= 0, 1.0 - np.exp(-np.maximum(slack, 0.0) / jitter), 0.0)


def range_loss_probability(d: np.ndarray, p0: float, r0: float, comm_range: float) -> np.ndarray:
    """p(d) = p_0 + (1 - p_0) clip((d - r_0) / (R - r_0), 0, 1)."""
    span = max(comm_range - r0, 1e-12)
    return p0 + (1.0 - p0) * np.clip((np.asarray(d) - r0) / span, 0.0, 1.0)


class GilbertElliott:
    """Gilbert-Elliott channels, one per link (or per sender), stepped together.

    Args:
        shape: the channels' array shape.
        rng: the disturbance stream.
        p_gb, p_bg: transition probabilities per tick, good -> bad and bad -> good.
        loss_good, loss_bad: loss probabilities in each state.
    The chains start in their stationary distribution.
    """

    def __init__(self, shape, rng: np.random.Generator, p_gb: float, p_bg: float,
                 loss_good: float, loss_bad: float) -> None:
        self.rng = rng
        self.p_gb, self.p_bg = p_gb, p_bg
        self.loss_good, self.loss_bad = loss_good, loss_bad
        self.bad = rng.random(shape) < self.stationary_bad

    @property
    def stationary_bad(self) -> float:
        """pi_B = p_GB / (p_GB + p_BG): the long-run share of time a link spends in the bad state."""
        total = self.p_gb + self.p_bg
        return self.p_gb / total if total > 0 else 0.0

    @property
    def loss_rate(self) -> float:
        """Long-run fraction of messages lost."""
        pb = self.stationary_bad
        return (1.0 - pb) * self.loss_good + pb * self.loss_bad

    def step(self) -> np.ndarray:
        """Move every chain one tick; return which of this tick's messages are lost (bool)."""
        u = self.rng.random(self.bad.shape)
        self.bad = np.where(self.bad, u >= self.p_bg, u < self.p_gb)
        p = np.where(self.bad, self.loss_bad, self.loss_good)
        return self.rng.random(self.bad.shape) < p


MAX_DELAY = 60.0
"""s: the longest delay the ``comm_delay`` model accepts, and the most the channel keeps of its messages."""


def max_delay_ticks(model: str, tau: float, jitter: float, n: int, T_s: float) -> int:
    """The longest delay a ``comm_delay`` model of ``model`` (fixed, hops, random) puts on a message,
    ticks: fixed tau; hops (n - 1) tau (the mean over receivers is at most that); random
    tau + 10 jitter (P(X > 10 jitter) = e^-10: rarer, longer delays are cut to it); never more than
    :data:`MAX_DELAY`."""
    span = {"fixed": tau, "hops": max(n - 1, 1) * tau, "random": tau + 10.0 * jitter}[model]
    return fixed_delay_ticks(min(span, MAX_DELAY), T_s)
