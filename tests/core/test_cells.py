"""The closest pair without a k-d tree: the compiled cell list and the dense pass against scipy's
cKDTree (the third-party oracle), to the bit, on the layouts swarms take."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swarmscene.core.cells import closest_pair_distance
from swarmscene.core.cells import pairs_within as compiled_pairs
from swarmscene.core.vectors import DENSE_POINTS, min_pair_distance, pairs_within


def _tree_min(points: np.ndarray) -> float:
    return float(cKDTree(points).query(points, k=2)[0][:, 1].min())


def _layouts(rng: np.random.Generator):
    n = 400
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n] * 3.0
    yield "jittered grid at one altitude", np.column_stack([grid + rng.normal(0, 0.3, grid.shape), np.full(n, 2.0)])
    yield "uniform 3-D", rng.uniform(0, 50, (n, 3))
    yield "planar 2-D", rng.uniform(-5, 5, (n, 2))
    yield "one line (x only)", np.column_stack([rng.uniform(0, 100, n), np.zeros(n), np.ones(n)])
    yield "a far outlier", np.vstack([rng.uniform(0, 1, (n - 1, 3)), [[1e4, 0, 0]]])
    yield "two far clusters", np.vstack([rng.normal(0, 0.1, (n // 2, 3)), rng.normal(500, 0.1, (n // 2, 3))])
    yield "a pair spanning cells", np.array([[0.0, 0, 0], [10, 0, 0], [20, 0, 0], [20.9, 0.5, 0], [40, 0, 0]] * 1
                                            + [[100.0 * k, 100, 0] for k in range(40)])
    yield "coincident agents", np.vstack([rng.uniform(0, 10, (n - 2, 3)), [[5.0, 5, 5], [5.0, 5, 5]]])
    yield "all at one point", np.zeros((50, 3))


@pytest.mark.parametrize("seed", range(3))
def test_closest_pair_equals_the_k_d_tree_to_the_bit(seed):
    for name, points in _layouts(np.random.default_rng(seed)):
        assert closest_pair_distance(points) == _tree_min(points), name
        assert min_pair_distance(points) == _tree_min(points), name


def test_the_dense_pass_for_few_agents_equals_the_tree():
    rng = np.random.default_rng(7)
    for n in (2, 3, 17, DENSE_POINTS):
        points = rng.uniform(0, 3, (n, 3))
        assert min_pair_distance(points) == _tree_min(points)
        _assert_tree_pairs(points, 1.2, *pairs_within(points, 1.2))


def _assert_tree_pairs(points, radius, pairs, d2):
    """The k-d tree's pairs, in lexicographic order, with the tree's distances to the bit."""
    tree = cKDTree(points)
    want = tree.query_pairs(radius, output_type="ndarray")
    want = want[np.lexsort((want[:, 1], want[:, 0]))]
    np.testing.assert_array_equal(pairs, want)
    if len(want):
        dist = tree.sparse_distance_matrix(tree, radius, output_type="dict")
        assert np.array_equal(np.sqrt(d2), [dist[(i, j)] for i, j in want.tolist()])


@pytest.mark.parametrize("seed", range(3))
def test_compiled_pairs_equal_the_k_d_tree(seed):
    rng = np.random.default_rng(seed)
    for _name, points in _layouts(rng):
        for radius in (0.0, 0.05, 1.0, 3.0, 25.0):
            pairs, d2 = compiled_pairs(np.ascontiguousarray(points, dtype=float), radius)
            _assert_tree_pairs(points, radius, pairs, d2)


def test_a_swarm_flat_to_micrometres_gets_a_planar_grid():
    """Hovering quadrotors differ in z by micrometres: a 3-D cell count over that box would be
    millions of empty cells (it once took gigabytes); the side must follow the plane."""
    from swarmscene.core.cells import _cell_side

    rng = np.random.default_rng(3)
    side = int(np.sqrt(900))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2) * 3.0
    points = np.column_stack([grid, 2.0 + rng.normal(0, 1e-6, len(grid))])
    assert _cell_side(points) == pytest.approx(87.0 / np.sqrt(450), rel=1e-9)
    assert closest_pair_distance(points) == _tree_min(points)


def test_compiled_nearest_obstacle_equals_shapelys_to_the_bit():
    """core/footprints.py on the building's walls and on polygons with holes: the nearest of
    each point's candidates and its distance, against the engine's shapely search."""
    import shapely
    from shapely.geometry import Point, Polygon

    from swarmscene.core.environment import Environment, nearest_within
    from swarmscene.core.footprints import nearest_of_candidates
    from swarmscene.methods.maps import building
    from swarmscene.plugins.generator.building import BuildingParams

    rng = np.random.default_rng(5)
    ring = Polygon([(0, 0), (6, 0), (6, 6), (0, 6)], [[(2, 2), (4, 2), (4, 4), (2, 4)]])
    for obstacles in (building(BuildingParams()), [ring, Point(8, 8).buffer(0.7)]):
        env = Environment(obstacles)
        lo, hi = shapely.total_bounds(env._geoms).reshape(2, 2)
        xy = rng.uniform(lo - 1.0, hi + 1.0, (3000, 2))
        candidates = env.near_pairs(xy, 1.2)
        want = nearest_within(env.tree, xy, 0.9, candidates)
        seg, start, polygonal, _ = env.footprints
        got = nearest_of_candidates(xy, candidates[0].astype(np.int64), candidates[1].astype(np.int64),
                                    seg, start, polygonal, 0.9)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        assert (want[0] >= 0).sum() > 100 and (want[1] == 0).any()  # near walls, some inside


def _torus_tree_connected(points: np.ndarray, radius: float, size: np.ndarray) -> bool:
    """The oracle: scipy's periodic k-d tree lists the links, its sparse graph labels the
    components (an axis beyond ``size`` gets a box too wide to fold any link)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pos, box = points.copy(), np.empty(points.shape[1])
    box[: size.size] = size
    if size.size < points.shape[1]:
        pos[:, size.size:] -= pos[:, size.size:].min(axis=0)
        box[size.size:] = pos[:, size.size:].max(axis=0) + 2.0 * radius + 1.0
    links = cKDTree(pos, boxsize=box).query_pairs(radius, output_type="ndarray")
    graph = coo_matrix((np.ones(len(links)), (links[:, 0], links[:, 1])), shape=(len(pos), len(pos)))
    return connected_components(graph, directed=False)[0] == 1


def test_the_torus_graph_is_connected_when_the_periodic_k_d_tree_says_so():
    """3,000 random swarms: 2-D and 3-D, one to three wrapped axes, boxes two to twelve radii long
    (some too short for distinct neighbour cells), dense and sparse (both of the kernel's paths),
    flocks astride the seams; then a 10,000-boid torus at two ranges."""
    import math

    from swarmscene.core.cells import _torus_cells, torus_disk_graph_connected

    rng = np.random.default_rng(11)
    answers, by_cells = [], []
    for _ in range(3000):
        n, dim = int(rng.integers(2, 400)), int(rng.integers(2, 4))
        wrapped = int(rng.integers(1, dim + 1))
        radius = float(rng.uniform(0.5, 6.0))
        size = rng.uniform(2.0 * radius, 12.0 * radius, wrapped)
        points = rng.uniform(0.0, 1.0, (n, dim)) * np.concatenate([size, rng.uniform(0.1, 3 * radius, dim - wrapped)])
        if rng.random() < 0.3:  # a flock astride the seams
            points[:, :wrapped] = np.mod(rng.normal(0.0, radius, (n, wrapped)), size)
            points[:, :wrapped] = np.where(points[:, :wrapped] >= size, 0.0, points[:, :wrapped])
        want = _torus_tree_connected(points, radius, size)
        assert torus_disk_graph_connected(points, radius, size) == want, (n, dim, size, radius)
        answers.append(want)
        _, _, shape, reach = _torus_cells(points, size, radius / math.sqrt(3.0) * (1.0 - 1e-9), radius)
        by_cells.append(shape.prod() <= 8 * n + 64 and all(shape[:wrapped] >= 2 * reach[:wrapped] + 1))
    assert 0.2 < np.mean(answers) < 0.8 and 0.2 < np.mean(by_cells) < 0.95  # both answers, both paths
    boids = np.column_stack([rng.uniform(0.0, 1000.0, (10_000, 2)), np.full(10_000, 2.0)])
    for radius in (8.0, 20.0):
        size = np.array([1000.0, 1000.0])
        assert torus_disk_graph_connected(boids, radius, size) == _torus_tree_connected(boids, radius, size)


def test_a_box_many_ranges_wide_is_walked_over_few_cells():
    """Boxes 50 to 10^7 ranges wide (a 10 km torus at a 1 m range): the pair-by-pair walk laid a
    cell per range along each wrapped axis, 10^8 cells or more to sort every tick (MemoryError at
    the far end). Its cells now widen until there are at most 8 N + 64, and the answers are still
    the periodic tree's: chains of agents astride a seam, whole or broken in two, and a chain with
    one agent far up an open axis."""
    from swarmscene.core.cells import torus_disk_graph_connected

    rng = np.random.default_rng(17)
    answers = []
    for case in range(400):
        n, dim = int(rng.integers(2, 60)), int(rng.integers(2, 4))
        wrapped = int(rng.integers(1, dim + 1))
        radius = float(rng.uniform(0.5, 2.0))
        size = radius * 10.0 ** rng.uniform(1.7, 7.0, wrapped)
        points = np.cumsum(rng.normal(0.0, 0.25 * radius, (n, dim)), axis=0)  # steps mostly within range
        if case % 2:
            points[n // 2:, 0] += 3.0 * radius  # broken in two (unless another link joins them)
        if wrapped < dim and case % 7 == 0:
            points[-1, -1] = 1e12  # far up an open axis
        points[:, :wrapped] = np.mod(points[:, :wrapped], size)
        points[:, :wrapped] = np.where(points[:, :wrapped] >= size, 0.0, points[:, :wrapped])
        want = _torus_tree_connected(points, radius, size)
        assert torus_disk_graph_connected(points, radius, size) == want, (case, n, dim, size, radius)
        answers.append(want)
    assert 0.2 < np.mean(answers) < 0.8  # both answers
    # finite coordinates whose difference overflows: the open axis' extent is infinite
    apart = np.array([[1.0, 1.0, -1e308], [2.0, 1.0, 1e308], [3.0, 1.0, 0.0]])
    assert torus_disk_graph_connected(apart, 5.0, np.array([100.0, 100.0])) is False
    apart[:, 2] = 0.0
    assert torus_disk_graph_connected(apart, 5.0, np.array([100.0, 100.0])) is True


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("axis", [0, 2])
def test_a_coordinate_that_is_not_finite_is_refused(bad, axis):
    """A NaN or an infinite coordinate has no cell: every compiled entry refuses it, as the k-d tree
    does, instead of reading and writing outside its arrays (a crash, or a wrong answer)."""
    from swarmscene.core.cells import disk_graph_connected, torus_disk_graph_connected

    points = np.random.default_rng(3).uniform(0.0, 100.0, (300, 3))
    points[5, axis] = bad
    calls = {
        "closest_pair_distance": lambda: closest_pair_distance(points),
        "pairs_within": lambda: compiled_pairs(points, 5.0),
        "disk_graph_connected": lambda: disk_graph_connected(points, 5.0),
        "torus_disk_graph_connected": lambda: torus_disk_graph_connected(points, 5.0, np.array([100.0, 100.0])),
    }
    for name, call in calls.items():
        with pytest.raises(ValueError, match=f"^{name}: every coordinate must be finite$"):
            call()
