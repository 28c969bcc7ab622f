"""A batch's first queries of its worlds' new snapshots, answered in one pass over the worlds.

:mod:`swarmscene.core.batch` calls :func:`prefetch` once a tick, after every world has settled:
what each :class:`~swarmscene.core.sensing.Sensing` snapshot's own lazy queries would compute
first, for all worlds at once, to the bit (tests/core/test_prefetch.py). A snapshot then answers
those queries from what it was handed; anything else it queries as it would alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import numpy as np

from .sensing import NEAR_K, ObstacleCandidates, Sensing, _nothing_near, read_only
from .vectors import DENSE_POINTS, dense_pair_dist2_batch, every


def prefetch(sensings: Sequence[Sensing]) -> None:
    """The first queries of B worlds' new snapshots, answered in one pass over the worlds.

    A batch's tick (core/batch.py) calls it; each snapshot gets the values its own lazy queries
    would give:

    * the small worlds' pairs, and their nearest neighbours where the last tick read them
      (:func:`_prefetch_few`);
    * the worlds with no obstacle near any agent (:func:`_prefetch_clear`).

    Anything else is left to each snapshot's own queries, as is any query already made."""
    _prefetch_few(sensings)
    _prefetch_clear(sensings)


def _prefetch_few(sensings: Sequence[Sensing]) -> None:
    """Every pair's squared length (:attr:`Sensing._every_pair`), the closest pair
    (:attr:`Sensing.min_separation`) and, where every agent is a member and every member is in
    range of every other, :attr:`Sensing.comm_connected`, over the worlds' stacked positions
    (:func:`~.vectors.dense_pair_dist2_batch`); and where the previous snapshot read
    :attr:`Sensing.knn`, each agent's nearest others (:func:`_nearest_ranked`; a world with a tie
    among them is left to its tree). Each snapshot gets the bits its own queries give (the same
    lengths; a least and a greatest value do not depend on the order they are sought in).
    Snapshots of more than ``DENSE_POINTS`` or fewer than two agents, of another N than the first's,
    or not float64, are left alone."""
    few = [s for s in sensings if 2 <= s._n <= DENSE_POINTS and s.world.pos.dtype == np.float64
           and "_every_pair" not in s.__dict__]
    few = [s for s in few if s._n == few[0]._n and s.world.pos.shape[1] == few[0].world.pos.shape[1]]
    if len(few) < 2:
        return
    i, j, d2 = dense_pair_dist2_batch(np.stack([s.world.pos for s in few]))
    closest = np.sqrt(np.minimum.reduce(d2, axis=1)).tolist()
    widest = np.maximum.reduce(d2, axis=1).tolist()
    for s, own, least, most in zip(few, d2, closest, widest, strict=True):
        s.__dict__["_every_pair"] = read_only((i, j, own))
        s.__dict__.setdefault("min_separation", least)
        if (s.periodic is None and most <= s.comm_range * s.comm_range
                and every(s.world.healthy) and every(s.world.comm_ok)):
            s.__dict__.setdefault("comm_connected", True)
    asked = [b for b, s in enumerate(few) if s._knn_hint and "knn" not in s.__dict__]
    if asked:
        dist, idx, distinct = _nearest_ranked(i, j, d2[asked], few[0]._n)
        for b, own_dist, own_idx, alone in zip(asked, dist, idx, distinct.tolist(), strict=True):
            if alone:
                few[b]._knn_ahead = (own_dist, own_idx)


def _nearest_ranked(i: np.ndarray, j: np.ndarray, d2: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each agent's ``NEAR_K`` nearest others in B worlds of ``n`` agents from their pairs' squared
    lengths ``d2`` (B, M) (pairs ``i`` < ``j``), as :attr:`Sensing.knn`'s tree query gives them:
    distances and indices (B, n, k - 1), and whether each world's answer is surely the tree's.

    The tree returns the k nearest (the agent itself first, at 0) in order of distance, and breaks
    a tie in an order of its own. Where each agent's k + 1 least lengths (all, in a smaller world)
    are distinct, the order is the lengths' alone, and the lengths are the tree's bits (the same
    sums of squares, :func:`~.vectors.dense_pair_dist2_batch`, and their square roots); a world
    with a tie there (a lattice, two agents at one point, a non-finite length) is not answered."""
    full = np.zeros((len(d2), n, n))
    full[:, i, j] = d2
    full[:, j, i] = d2
    order = np.argsort(full, axis=2)  # (any sort: only worlds without ties are kept)
    ranked = np.take_along_axis(full, order, axis=2)
    k = min(n, NEAR_K + 1)
    distinct = np.logical_and.reduce(np.diff(ranked[:, :, :min(n, k + 1)], axis=2) > 0, axis=(1, 2))
    distinct &= np.isfinite(ranked[:, :, k - 1]).all(axis=1)  # (an overflow: the tree marks it missing)
    return np.sqrt(ranked[:, :, 1:k]), order[:, :, 1:k], distinct


def _prefetch_clear(sensings: Sequence[Sensing]) -> None:
    """:meth:`Sensing.obstacle_nearest` at the range the previous tick asked for (where the first
    query of a tick works), for the snapshots whose kept obstacle candidates (a Verlet list,
    :class:`ObstacleCandidates`) hold none and still cover that range: nothing is within it. The
    cover test of every such world is one pass over their stacked positions (the same
    differences, squares and sums as :meth:`ObstacleCandidates.cover`; the greatest of them does
    not depend on the order). A query made afterwards at a range within it is answered from it, as
    after the snapshot's own first query; a wider one queries as it would have."""
    empty = [s for s in sensings if s._candidates is not None and not s._candidates.point.size
             and not s._nearest and 0.0 < s._hint["obstacles"] <= s._candidates.radius
             and s.world.pos.dtype == np.float64 and s._candidates.xy.shape == (s._n, 2)]
    empty = [s for s in empty if s._n == empty[0]._n]
    if len(empty) < 2:
        return
    moved = np.stack([s.world.pos[:, :2] for s in empty])
    moved -= np.stack([cast("ObstacleCandidates", s._candidates).xy for s in empty])
    moved *= moved
    farthest = np.maximum.reduce(moved[:, :, 0] + moved[:, :, 1], axis=1, initial=0.0).tolist()
    for s, far in zip(empty, farthest, strict=True):
        reach = s._hint["obstacles"]
        if far <= (cast("ObstacleCandidates", s._candidates).radius - reach) ** 2:
            index, clearance = _nothing_near(s._n)
            s._none_within, s._nearest[reach] = reach, (index.copy(), clearance.copy())
