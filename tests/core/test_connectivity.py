"""The safety monitor's connectivity certificate: exact against networkx, and actually reused."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

from swarmscene.core.environment import Environment
from swarmscene.core.monitors import ConnectivityCertificate
from swarmscene.core.sensing import Sensing
from swarmscene.core.state import WorldState


def comm_graph(world: WorldState, radius: float) -> nx.Graph:
    members = np.flatnonzero(world.healthy & world.comm_ok)
    d = np.linalg.norm(world.pos[:, None] - world.pos[None], axis=2)
    graph = nx.Graph()
    graph.add_nodes_from(members.tolist())
    graph.add_edges_from((a, b) for a in members for b in members if a < b and d[a, b] <= radius)
    return graph


class CountingSensing(Sensing):
    built = 0

    def comm_spanning_tree(self):
        CountingSensing.built += 1
        return super().comm_spanning_tree()


def run(steps: int, move, n: int = 60, radius: float = 2.0, seed: int = 0):
    """(certificate verdicts, networkx verdicts, spanning trees built) over a moving swarm."""
    rng = np.random.default_rng(seed)
    world = WorldState.at_rest(np.column_stack([rng.uniform(0, 8, (n, 2)), np.zeros(n)]))
    certificate, got, want = ConnectivityCertificate(), [], []
    CountingSensing.built = 0
    for k in range(steps):
        move(world, rng, k)
        sensing = CountingSensing(world, Environment(), comm_range=radius)
        got.append(certificate.connected(sensing))
        want.append(nx.is_connected(comm_graph(world, radius)))
    return got, want, CountingSensing.built


def test_certificate_is_exact_and_reused_on_a_slow_swarm():
    def drift(world, rng, k):
        world.pos[:, :2] += rng.normal(0, 0.03, (world.n, 2))
        world.pos[:, :2] *= 1.004 if k < 150 else 0.99  # spread out until it splits, then gather
        world.comm_ok[:] = True
        if 60 <= k < 70:
            world.comm_ok[3] = False  # a radio drop changes the members

    got, want, built = run(300, drift)
    assert got == want
    assert True in want and False in want  # both verdicts were exercised
    assert built < 60  # most ticks were proven by a kept tree, not by an exact test


def test_certificate_backs_off_on_a_graph_that_changes_every_tick():
    def shuffle(world, rng, k):
        world.pos[:, :2] = rng.uniform(0, 5, (world.n, 2))

    got, want, built = run(400, shuffle)
    assert got == want and all(want)
    assert built <= 20  # short-lived trees pause further builds (up to MAX_PAUSE ticks)


def test_spanning_tree_is_a_minimum_spanning_tree_of_the_members():
    rng = np.random.default_rng(2)
    pos = np.column_stack([rng.uniform(0, 6, (50, 2)), np.zeros(50)])
    pos[7] = pos[8]  # co-located members still get their link
    world = WorldState.at_rest(pos)
    world.comm_ok[0] = False
    graph = comm_graph(world, 2.0)
    assert nx.is_connected(graph)
    links = Sensing(world, Environment(), comm_range=2.0).comm_spanning_tree()
    tree = nx.Graph(links.tolist())
    assert len(links) == 48 and set(tree.nodes) == set(graph.nodes) and nx.is_tree(tree)
    assert all(graph.has_edge(a, b) for a, b in links.tolist())
    for a, b in graph.edges:
        graph.edges[a, b]["w"] = float(np.linalg.norm(pos[a] - pos[b]))
    weight = sum(np.linalg.norm(pos[a] - pos[b]) for a, b in links.tolist())
    assert weight == pytest.approx(nx.minimum_spanning_tree(graph, weight="w").size(weight="w"))
    world.pos[:25, 0] -= 50.0  # two groups out of range of each other
    assert Sensing(world, Environment(), comm_range=2.0).comm_spanning_tree() is None


@pytest.mark.parametrize("seed", range(4))
def test_large_swarms_are_judged_by_the_compiled_union_find_exactly(seed):
    """Above DENSE_LIMIT members the test joins them by union-find over a cell list: against
    networkx on swarms around the connectivity threshold, flat and 3-D, with radios down."""
    from swarmscene.core.sensing import DENSE_LIMIT

    rng = np.random.default_rng(seed)
    verdicts = set()
    for n, spread, flat in [(300, 18.0, True), (300, 22.0, True), (400, 9.0, False), (DENSE_LIMIT + 1, 12.0, True)]:
        pos = rng.uniform(0, spread, (n, 3))
        if flat:
            pos[:, 2] = 2.0 + rng.normal(0, 1e-6, n)  # hovering: z differs by micrometres
        world = WorldState.at_rest(pos)
        world.comm_ok[rng.choice(n, 5, replace=False)] = False
        for radius in (1.0, 1.6, 2.5):
            want = nx.is_connected(comm_graph(world, radius))
            assert Sensing(world, Environment(), comm_range=radius).comm_connected == want
            verdicts.add(want)
    assert verdicts == {True, False}


@pytest.mark.parametrize("seed", range(3))
def test_both_cell_walks_of_the_union_find_agree_with_networkx(seed):
    """The clique-per-cell walk (cells narrower than radius / sqrt 3) and the pair-by-pair walk
    give networkx's verdict on the same swarms, also at distances a hair either side of the radius."""
    from swarmscene.core.cells import _connected_by_pairs, disk_graph_connected

    rng = np.random.default_rng(seed)
    for n, spread in [(200, 10.0), (300, 14.0), (60, 3.0)]:
        pos = np.column_stack([rng.uniform(0, spread, (n, 2)), np.full(n, 2.0)])
        world = WorldState.at_rest(pos)
        for radius in (0.8, 1.2, 2.0):
            want = nx.is_connected(comm_graph(world, radius))
            assert disk_graph_connected(pos, radius) == want
            assert _connected_by_pairs(pos, radius, radius) == want
    chain = np.column_stack([np.arange(40) * 1.0, np.zeros(40), np.zeros(40)])  # links of exactly 1 m
    assert disk_graph_connected(chain, 1.0) and not disk_graph_connected(chain, 1.0 - 1e-12)


def test_a_ticks_shared_arrays_are_read_only_so_an_in_place_edit_fails_at_once():
    """Every plugin and the safety monitor read the same arrays of a tick: one plugin clipping its
    distances in place changed what the others saw. Now the edit raises; a copy edits freely."""
    import numpy as np
    import pytest
    import shapely

    from swarmscene.core.environment import Environment
    from swarmscene.core.sensing import Sensing
    from swarmscene.core.state import WorldState

    pos = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [5.0, 0.0, 1.0]])
    env = Environment([shapely.Point(0.0, 3.0).buffer(1.0)])
    sensing = Sensing(WorldState.at_rest(pos), env, comm_range=4.5)
    dist, idx = sensing.nearest
    for array in (dist, idx, sensing.pairs(2.0), sensing.clearance, sensing.clearance_within(3.0),
                  *sensing.obstacle_nearest(3.0), sensing.comm_members, sensing.comm_edges, *sensing.knn):
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0
    mine = dist.copy()
    mine[:] = 0.0
    assert sensing.nearest[0].tolist() == [1.0, 1.0, 4.0]  # the shared answer is untouched
    assert sensing.pairs(2.0).tolist() == [[0, 1]] and sensing.world.pos.flags.writeable  # the truth is not frozen


def test_on_a_torus_agents_across_a_seam_are_linked():
    """The flocking preset's connectivity FAIL at 1 s: a flock crossing the seam of its 100 m torus
    looked split by plain distances. With the formation's periodic box, links use the minimum image."""
    import numpy as np

    from swarmscene.core.environment import Environment
    from swarmscene.core.sensing import Sensing
    from swarmscene.core.state import WorldState

    pos = np.array([[1.0, 50.0, 2.0], [98.0, 50.0, 2.0], [94.0, 50.0, 2.5], [99.5, 53.0, 2.0]])
    plain = Sensing(WorldState.at_rest(pos), Environment(), comm_range=5.0)
    assert not plain.comm_connected
    torus = Sensing(WorldState.at_rest(pos), Environment(), comm_range=5.0)
    torus.periodic = (np.zeros(2), np.full(2, 100.0))
    assert torus.comm_connected  # x = 1 and 98 are 3 m apart across the seam
    apart = pos.copy()
    apart[2] = [50.0, 20.0, 2.0]  # now alone in the middle: the graph is split, torus or not
    split = Sensing(WorldState.at_rest(apart), Environment(), comm_range=5.0)
    split.periodic = torus.periodic
    assert not split.comm_connected


@pytest.mark.parametrize("n", [100, 400])  # the k-d tree's side of DENSE_LIMIT and the cell list's
def test_a_ring_around_the_torus_is_connected_through_its_seam_only(n):
    """n agents on a ring along x of a 100 m torus, the gap between two neighbours the comm range
    less a millimetre: connected through the seam; one agent gone from the ring's middle and it is
    still one chain; a second one gone elsewhere splits it, on either path."""
    x = np.arange(n) * (100.0 / n)
    pos = np.column_stack([x, np.full(n, 50.0), np.full(n, 2.0)])

    def connected(world, comm_range):
        sensing = Sensing(world, Environment(), comm_range=comm_range)
        sensing.periodic = (np.zeros(2), np.full(2, 100.0))
        return sensing.comm_connected

    step = 100.0 / n
    assert connected(WorldState.at_rest(pos), step + 1e-3)
    assert not connected(WorldState.at_rest(pos), step - 1e-3)
    world = WorldState.at_rest(pos)
    world.healthy[n // 2] = False  # the ring opened once: a chain through the seam
    assert connected(world, step + 1e-3)
    world.healthy[n // 4] = False  # and twice: two chains
    assert not connected(world, step + 1e-3)
