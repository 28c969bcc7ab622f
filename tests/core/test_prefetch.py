"""A batch's one pass over its small worlds' snapshots (core/prefetch.py) answers each
snapshot's first queries with the bits that snapshot's own lazy queries give."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene.core.environment import Environment
from swarmscene.core.prefetch import prefetch
from swarmscene.core.sensing import Sensing
from swarmscene.core.state import WorldState
from swarmscene.core.vectors import DENSE_POINTS, dense_pair_dist2, dense_pair_dist2_batch


def test_the_stacked_pair_lengths_are_each_sets_own_to_the_bit():
    rng = np.random.default_rng(3)
    for b, n, d in ((1, 2, 3), (7, 5, 3), (4, DENSE_POINTS, 3), (3, 6, 2)):
        # lengths over many scales, so that a changed order of the sums would show in the last bits
        points = rng.normal(size=(b, n, d)) * 10.0 ** rng.integers(-3, 4, size=(b, n, 1))
        i, j, d2 = dense_pair_dist2_batch(points)
        for k in range(b):
            own_i, own_j, own_d2 = dense_pair_dist2(points[k])
            assert np.array_equal(i, own_i) and np.array_equal(j, own_j)
            assert d2[k].tobytes() == own_d2.tobytes()


def worlds(rng: np.random.Generator) -> list[WorldState]:
    """Six small worlds: spread within range, spread beyond it, one agent failed, one radio lost,
    then two that prefetch must leave alone (another N, one agent)."""
    out = []
    for scale, n in ((1.0, 6), (9.0, 6), (1.0, 6), (1.0, 6), (1.0, 7), (1.0, 1)):
        out.append(WorldState.at_rest(rng.uniform(-scale, scale, (n, 3))))
    out[2].healthy[4] = False
    out[3].comm_ok[0] = False
    return out


def test_prefetched_snapshots_answer_as_their_own_queries():
    rng = np.random.default_rng(7)
    env = Environment()
    for _ in range(20):
        ws = worlds(rng)
        batch = [Sensing(w, env, comm_range=4.0) for w in ws]
        prefetch(batch)
        for w, fetched in zip(ws, batch, strict=True):
            own = Sensing(w, env, comm_range=4.0)
            assert fetched.min_separation == own.min_separation
            assert fetched.comm_connected is own.comm_connected
            if w.n >= 2:
                assert all(a.tobytes() == b.tobytes() for a, b in zip(fetched._every_pair, own._every_pair, strict=True))
                assert np.array_equal(fetched.pairs(2.5), own.pairs(2.5))


def test_prefetch_answers_what_it_can_and_leaves_the_rest_to_the_snapshot():
    rng = np.random.default_rng(1)
    ws = worlds(rng)
    ws[0].pos[:] = rng.uniform(-1.0, 1.0, (6, 3))  # all within range: a complete graph
    batch = [Sensing(w, Environment(), comm_range=4.0) for w in ws]
    prefetch(batch)
    answered = [sorted(k for k in ("_every_pair", "min_separation", "comm_connected") if k in s.__dict__)
                for s in batch]
    assert answered[0] == ["_every_pair", "comm_connected", "min_separation"]
    assert answered[1] == ["_every_pair", "min_separation"]  # beyond range: the sweeps decide
    assert answered[2] == answered[3] == ["_every_pair", "min_separation"]  # not every agent a member
    assert answered[4] == answered[5] == []  # another N; a single agent
    assert not batch[0].__dict__["_every_pair"][2].flags.writeable  # shared: read-only, as a query's


def test_worlds_far_from_the_obstacles_are_answered_as_their_own_queries():
    """Six worlds drift past a pillar tick by tick, their snapshots chained as a run chains them
    (the monitor's 0.5 m then a plugin's 2 m, so the next tick's first query works at 2 m): with
    the one pass before the queries, every answer and what each snapshot keeps for the next tick
    equal the snapshots queried on their own."""
    from shapely.geometry import Point

    env = Environment([Point(0.0, 0.0).buffer(1.0)])
    rng = np.random.default_rng(5)
    starts = [np.column_stack([rng.uniform(-12.0, -4.0, 5), rng.uniform(-2.5, 2.5, 5), np.ones(5)])
              for _ in range(6)]
    alone = [WorldState.at_rest(p.copy()) for p in starts]
    together = [WorldState.at_rest(p.copy()) for p in starts]
    own: list[Sensing | None] = [None] * 6
    fetched: list[Sensing | None] = [None] * 6
    answered = near = 0
    for tick in range(120):
        step = np.array([0.15, 0.02 * np.sin(0.1 * tick), 0.0])
        for a, b in zip(alone, together, strict=True):
            a.pos += step
            b.pos += step
        own = [Sensing(w, env, 3.0, previous) for w, previous in zip(alone, own, strict=True)]
        fetched = [Sensing(w, env, 3.0, previous) for w, previous in zip(together, fetched, strict=True)]
        prefetch(fetched)
        answered += sum(bool(s._nearest) for s in fetched)
        for mine, theirs in zip(own, fetched, strict=True):
            for radius in (0.5, 2.0):
                assert all(x.tobytes() == y.tobytes() for x, y in
                           zip(mine.obstacle_nearest(radius), theirs.obstacle_nearest(radius), strict=True))
            assert mine._none_within == theirs._none_within
            assert (mine._candidates is None) == (theirs._candidates is None)
            if mine._candidates is not None:
                assert np.array_equal(mine._candidates.xy, theirs._candidates.xy)
            near += bool((mine.obstacle_nearest(2.0)[0] >= 0).any())
    assert answered > 100 and near > 100  # worlds far from the pillar answered, others near it


def swarms(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Ten worlds of ``n`` agents: spread at several scales, on a 2 m lattice (equal distances),
    two agents at one point, and one spread far from the origin."""
    out = [rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-2, 3) for _ in range(6)]
    out.append(2.0 * rng.integers(0, 3, (n, 3)).astype(float))  # ties: the tree orders them its way
    out.append(2.0 * np.column_stack([np.arange(n), np.zeros(n), np.ones(n)]))  # a row: equal neighbours
    twin = rng.normal(size=(n, 3))
    twin[1] = twin[0]  # two agents at one point: a tie with each agent itself
    out.append(twin)
    out.append(rng.normal(size=(n, 3)) + 1e4)
    return out


def test_prefetched_nearest_neighbours_are_the_trees_bits_and_ties_are_left_to_it():
    """Where the last tick read ``Sensing.knn``, a batch answers it ahead from its pairs' lengths:
    the tree's distances and indices to the bit; a world where two lengths an agent ranks are
    equal is left to the tree, whose order of ties is its own."""
    rng = np.random.default_rng(11)
    env = Environment()
    lattices_left = 0
    for n in (2, 3, 5, 6, 9, DENSE_POINTS):
        for _ in range(15):
            ws = [WorldState.at_rest(p) for p in swarms(rng, n)]
            last = [Sensing(w, env, comm_range=4.0) for w in ws]
            for s in last:
                s.knn  # noqa: B018  (read: the next tick is answered ahead)
            batch = [Sensing(w, env, comm_range=4.0, previous=p) for w, p in zip(ws, last, strict=True)]
            prefetch(batch)
            ahead = [s._knn_ahead is not None for s in batch]
            assert all(ahead[:6]) and ahead[9]  # distinct lengths
            assert not ahead[8] and ahead[7] == (n == 2)  # equal lengths (but two agents in a row): the tree's
            lattices_left += not ahead[6]
            for w, fetched in zip(ws, batch, strict=True):
                own = Sensing(w, env, comm_range=4.0)
                assert all(a.dtype == b.dtype and a.tobytes() == b.tobytes()
                           for a, b in zip(fetched.knn, own.knn, strict=True))
                assert not fetched.knn[0].flags.writeable and not fetched.knn[1].flags.writeable
                assert fetched.nearest[1].tobytes() == own.nearest[1].tobytes()
    assert lattices_left > 60  # of 90 lattices, most have a tie an agent ranks


def test_nearest_neighbours_are_answered_ahead_only_after_a_tick_that_read_them():
    rng = np.random.default_rng(2)
    ws = [WorldState.at_rest(rng.normal(size=(6, 3))) for _ in range(4)]
    quiet = [Sensing(w, Environment(), comm_range=4.0) for w in ws]
    batch = [Sensing(w, Environment(), comm_range=4.0, previous=p) for w, p in zip(ws, quiet, strict=True)]
    prefetch(batch)
    assert all(s._knn_ahead is None for s in batch)  # nobody read them last tick
    batch[0].knn  # noqa: B018
    after = [Sensing(w, Environment(), comm_range=4.0, previous=p) for w, p in zip(ws, batch, strict=True)]
    prefetch(after)
    assert [s._knn_ahead is not None for s in after] == [True, False, False, False]
    after[0].knn  # noqa: B018  (an answer read ahead counts as read: the next tick is answered too)
    again = [Sensing(w, Environment(), comm_range=4.0, previous=p) for w, p in zip(ws, after, strict=True)]
    prefetch(again)
    assert again[0]._knn_ahead is not None and again[1]._knn_ahead is None


def after_a_tick_that_read_knn(ws: list[WorldState]) -> list[Sensing]:
    """The worlds' snapshots after one whose nearest neighbours were read, prefetched together."""
    last = [Sensing(w, Environment(), comm_range=4.0) for w in ws]
    for s in last:
        s.knn  # noqa: B018
    batch = [Sensing(w, Environment(), comm_range=4.0, previous=p) for w, p in zip(ws, last, strict=True)]
    prefetch(batch)
    return batch


def test_a_tie_at_the_last_neighbour_ranked_is_left_to_the_tree():
    """Agent 0's fourth and fifth nearest are equally far (4 m), on the two sides of the tree's
    split: the tree keeps the one in the leaf it searches first (agent 31), a sort by length the
    lower index (agent 1). The world is left to the tree; the same world moved a little (no
    tie) is answered ahead."""
    rng = np.random.default_rng(1)
    pos = np.zeros((DENSE_POINTS, 3))
    pos[:5] = [(-1, 0, 0), (3, 0, 0), (-1, -0.6, 0.8), (-2.2, -1.6, 0), (-1, -1.8, -2.4)]  # 1, 2, 3 m from agent 0
    pos[-1] = (-1, 4, 0)
    pos[5:-1] = np.column_stack([np.r_[rng.uniform(-100, -20, 13), rng.uniform(20, 100, 13)],  # far, 13 a side
                                 rng.uniform(-50, 50, (26, 2))])
    ws = [WorldState.at_rest(pos), WorldState.at_rest(pos + 0.5 * rng.normal(size=pos.shape))]
    batch = after_a_tick_that_read_knn(ws)
    assert [s._knn_ahead is not None for s in batch] == [False, True]
    assert batch[0].knn[1][0].tolist()[:3] == [2, 3, 4]  # then 31 or 1: the tree's own choice


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the squared length, on purpose
def test_a_length_that_overflows_is_left_to_the_tree():
    """Two agents 1e160 m apart: the squared length overflows to inf, which the tree reports as
    no neighbour found (index N); the world is left to it."""
    ws = [WorldState.at_rest(np.array([[0.0, 0.0, 0.0], [1e160, 0.0, 0.0]])),
          WorldState.at_rest(np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]))]
    batch = after_a_tick_that_read_knn(ws)
    assert [s._knn_ahead is not None for s in batch] == [False, True]
    assert batch[0].knn[1].tolist() == Sensing(ws[0], Environment(), comm_range=4.0).knn[1].tolist()


def test_nothing_within_is_known_only_from_a_query_at_that_range_or_wider():
    """``Sensing.nothing_within``: False until a query (or a batch's prefetch) has shown no obstacle
    in range; then True at that range and narrower; never a query of its own, but an ask (the next
    snapshot's first query works at the widest range asked)."""
    from shapely.geometry import Point

    env = Environment([Point(0.0, 0.0).buffer(1.0)])
    far = WorldState.at_rest(np.array([[20.0, 0.0, 1.0], [22.0, 1.0, 1.0]]))
    s = Sensing(far, env, comm_range=4.0)
    assert not s.nothing_within(3.0) and s._none_within < 0  # not known, and not queried
    assert s.asked["obstacles"] == 3.0
    s.obstacle_nearest(5.0)  # nothing within 5 m
    assert s.nothing_within(5.0) and s.nothing_within(2.0) and not s.nothing_within(30.0)
    assert Sensing(far, env, comm_range=4.0, previous=s)._hint["obstacles"] == 30.0
    near = Sensing(WorldState.at_rest(np.array([[2.0, 0.0, 1.0], [22.0, 1.0, 1.0]])), env, comm_range=4.0)
    near.obstacle_nearest(5.0)  # the pillar is 1 m from agent 0
    assert not near.nothing_within(5.0) and not near.nothing_within(0.5)
