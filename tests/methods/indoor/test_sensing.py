"""Thesis section 5.2 (eq. 5.1-5.10): single integrator, collision model, line-of-sight sensing."""

import numpy as np
import pytest
import shapely
from scipy.spatial import cKDTree
from shapely import STRtree
from shapely.geometry import LineString, box

from swarmscene.methods.indoor.maps import building
from swarmscene.methods.indoor.sensing import (
    collision_free,
    nearest_obstacle,
    obstacle_free,
    obstacle_point_visible,
    pairwise_min_distance,
    saturate,
    segments_clear,
    sensing_pairs,
    single_integrator_step,
)

D_S, D_L = 2.0, 0.05  # Table 5.1


def _pairs(p):
    return {tuple(x) for x in np.asarray(p).tolist()}


def test_single_integrator_clips_input_to_u_max():
    r = np.array([[0.0, 0.0], [1.0, 1.0]])
    u = np.array([[0.03, 0.04], [0.01, 0.0]])  # norms 0.05 and 0.01
    nxt = single_integrator_step(r, u, u_max=0.025)
    np.testing.assert_allclose(nxt[0], [0.015, 0.02])  # same direction, norm 0.025
    np.testing.assert_allclose(nxt[1], [1.01, 1.0])


def test_saturate_keeps_small_and_zero_rows():
    w = np.array([[0.0, 0.0], [3.0, 4.0], [0.001, 0.0]])
    out = saturate(w, 1.0)
    np.testing.assert_allclose(out, [[0, 0], [0.6, 0.8], [0.001, 0]])


def test_collision_condition_eq_5_2():
    r = np.array([[0.0, 0.0], [0.3, 0.0], [1.0, 1.0]])
    assert pairwise_min_distance(r) == pytest.approx(0.3)
    assert collision_free(r, 0.3)
    assert not collision_free(r, 0.31)


def test_los_blocked_by_wall():
    wall = [LineString([(0.0, -1.0), (0.0, 1.0)])]
    r = np.array([[-0.5, 0.0], [0.5, 0.0], [-0.5, 0.6], [0.5, 0.6]])
    # 0-1 and 2-3 cross the wall; 0-2 and 1-3 stay on one side; the diagonals cross it too.
    assert _pairs(sensing_pairs(r, D_S, wall, D_L)) == {(0, 2), (1, 3)}
    assert _pairs(sensing_pairs(r, D_S, None, D_L)) == {(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)}


def test_los_clearance_d_l_eq_5_8():
    # Wall tip 0.04 m (blocked) or 0.06 m (clear) below the segment joining the two agents.
    a, b = np.array([[-0.5, 0.0]]), np.array([[0.5, 0.0]])
    near = [LineString([(0.0, -1.0), (0.0, -0.04)])]
    far = [LineString([(0.0, -1.0), (0.0, -0.06)])]
    assert not segments_clear(a, b, near, D_L)[0]
    assert segments_clear(a, b, far, D_L)[0]


def test_range_d_s_eq_5_7_and_third_agent_does_not_block():
    r = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.1, 0.0]])
    # Agent 1 sits on the segment 0-2: agents do not hide agents (section 5.2.4); 0-3 is too far.
    assert _pairs(sensing_pairs(r, D_S, [], D_L)) == {(0, 1), (0, 2), (1, 2), (1, 3), (2, 3)}


def test_prebuilt_trees_give_the_same_pairs():
    rng = np.random.default_rng(3)
    mp = building()
    r = rng.uniform((0, 12), (10, 22), size=(80, 2))
    plain = _pairs(sensing_pairs(r, 1.0, mp.walls, D_L))
    pos3 = np.column_stack([r, np.full(len(r), 1.5)])  # one altitude: the engine's 3D tree
    shared = _pairs(sensing_pairs(r, 1.0, STRtree(mp.walls), D_L, tree=cKDTree(pos3)))
    assert plain == shared and len(plain) > 50


def test_clearance_certificate_does_not_change_the_result():
    rng = np.random.default_rng(7)
    mp = building()
    r = np.concatenate([rng.uniform((0, 0), (28, 22), size=(300, 2))])
    r = r[shapely.contains_xy(mp.free_space, r[:, 0], r[:, 1])]
    _, dist = nearest_obstacle(r, mp.walls, max_distance=0.7)
    certified = _pairs(sensing_pairs(r, 1.0, mp.walls, D_L, clearance=np.minimum(dist, 0.7)))
    assert certified == _pairs(sensing_pairs(r, 1.0, mp.walls, D_L))
    # And both agree with a per-pair shapely check written out here.
    brute = set()
    for i in range(len(r)):
        for j in range(i + 1, len(r)):
            seg = LineString([r[i], r[j]])
            if seg.length <= 1.0 and min(seg.distance(w) for w in mp.walls) > D_L:
                brute.add((i, j))
    assert certified == brute


def test_nearest_obstacle_point_eq_5_32():
    walls = [LineString([(0.0, -5.0), (0.0, 5.0)]), LineString([(3.0, -5.0), (3.0, 5.0)])]
    r = np.array([[0.3, 1.0], [2.0, -2.0], [1.5, 0.0]])
    o, dist = nearest_obstacle(r, walls, max_distance=1.2)
    np.testing.assert_allclose(o[0], [0.0, 1.0])
    np.testing.assert_allclose(o[1], [3.0, -2.0])
    np.testing.assert_allclose(dist[:2], [0.3, 1.0])
    assert np.isnan(o[2]).all() and dist[2] == np.inf  # 1.5 m from both walls: beyond range


def test_nearest_obstacle_matches_shapely_distance_in_building():
    rng = np.random.default_rng(11)
    mp = building()
    r = rng.uniform((0, 0), (28, 22), size=(200, 2))
    o, dist = nearest_obstacle(r, mp.walls, max_distance=D_S)
    union = shapely.union_all(mp.walls)
    expect = shapely.distance(union, shapely.points(r))
    within = expect <= D_S
    np.testing.assert_allclose(dist[within], expect[within], atol=1e-12)
    assert np.all(dist[~within] == np.inf)
    np.testing.assert_allclose(np.linalg.norm(o[within] - r[within], axis=1), dist[within])


def test_obstacle_condition_eq_5_3():
    walls = [box(0.0, 0.0, 1.0, 1.0)]
    assert obstacle_free(np.array([[-0.2, 0.5]]), walls, 0.1)
    assert not obstacle_free(np.array([[-0.05, 0.5]]), walls, 0.1)
    assert not obstacle_free(np.array([[0.5, 0.5]]), walls, 0.1)  # inside the obstacle


def test_hidden_obstacle_point_eq_5_10():
    walls = [LineString([(1.0, -1.0), (1.0, 1.0)]), LineString([(2.0, -1.0), (2.0, 1.0)])]
    r = np.zeros((3, 2))
    r_o = np.array([[1.0, 0.0], [2.0, 0.0], [2.0, 0.9]])
    # The first wall hides the second one along both rays; the near point is seen.
    np.testing.assert_array_equal(obstacle_point_visible(r, r_o, walls, D_S), [True, False, False])
    # Out of range (eq. 5.9) even with nothing in between.
    assert not obstacle_point_visible(np.zeros((1, 2)), np.array([[2.0, 0.9]]), walls[1:], D_S)[0]
    assert obstacle_point_visible(np.zeros((1, 2)), np.array([[2.0, 0.0]]), walls[1:], D_S)[0]
