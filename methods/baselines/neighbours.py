"""Each agent's nearest neighbours as a padded (N, K) table, from a list of close pairs."""

from __future__ import annotations

import numpy as np


def neighbour_table(pairs: np.ndarray, pos: np.ndarray, k: int | None) -> tuple[np.ndarray, np.ndarray]:
    """The up to ``k`` nearest partners of every agent among ``pairs`` (M, 2), nearest first.

    Args:
        pairs: index pairs (i < j) of agents close enough to matter (e.g. ``Sensing.pairs``).
        pos: (N, d) positions, m; the distance that orders the partners is measured on them.
        k: most neighbours per agent (RVO2's ``maxNeighbors``); ``None``: all of them.

    Returns:
        (index (N, K) int, valid (N, K) bool): padding has ``valid`` False and index 0. The order is
        RVO2's (ascending distance), which fixes the order of the ORCA lines.
    """
    n = len(pos)
    if len(pairs) == 0:
        width = 0 if k is None else k
        return np.zeros((n, width), dtype=np.intp), np.zeros((n, width), dtype=bool)
    agent = np.concatenate([pairs[:, 0], pairs[:, 1]])
    other = np.concatenate([pairs[:, 1], pairs[:, 0]])
    diff = pos[agent] - pos[other]
    dist2 = np.einsum("ij,ij->i", diff, diff)
    order = np.lexsort((other, dist2, agent))
    agent, other = agent[order], other[order]
    start = np.searchsorted(agent, np.arange(n))
    rank = np.arange(agent.size) - start[agent]
    width = int(rank.max()) + 1 if k is None else k
    keep = rank < width
    index = np.zeros((n, width), dtype=np.intp)
    valid = np.zeros((n, width), dtype=bool)
    index[agent[keep], rank[keep]] = other[keep]
    valid[agent[keep], rank[keep]] = True
    return index, valid
