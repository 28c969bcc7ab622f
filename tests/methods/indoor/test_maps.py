"""Maps of thesis section 5.4 and Appendix A, and the random connected initial swarms."""

import numpy as np
import pytest
import shapely
from oracles.indoor import random_connected_swarm
from shapely.geometry import LineString, Point, box

from swarmscene.methods.indoor.graphs import is_connected, neighbour_graph
from swarmscene.methods.indoor.maps import (
    building,
    in_region,
    l_corridor,
    open_map,
    resample_path,
    straight_corridor,
)
from swarmscene.methods.indoor.sensing import nearest_obstacle


def _corridor_part(mp):
    """Free space minus the two rooms: the corridor itself."""
    rooms = shapely.union_all([mp.end_region, mp.start_region.buffer(0.3, join_style="mitre")])
    return mp.free_space.difference(rooms)


@pytest.mark.parametrize("width", [0.5, 0.6, 0.7, 0.8, 0.9])
@pytest.mark.parametrize("build", [straight_corridor, l_corridor])
def test_corridor_is_10_m_long_and_w_wide(build, width):
    mp = build(width)
    assert _corridor_part(mp).area == pytest.approx(10.0 * width)  # length 10 m x width w
    # Every way-point inside the corridor sits on its axis: w / 2 from the nearest wall.
    corridor = _corridor_part(mp).buffer(-1e-9)
    inside = mp.waypoints[shapely.contains_xy(corridor, mp.waypoints[:, 0], mp.waypoints[:, 1])]
    _, dist = nearest_obstacle(inside, mp.walls, 5.0)
    np.testing.assert_allclose(dist, width / 2)
    assert len(inside) >= 30


@pytest.mark.parametrize("mp", [straight_corridor(0.7), l_corridor(0.7), building()], ids=str)
def test_walls_are_the_boundary_of_free_space(mp):
    assert all(len(w.coords) == 2 for w in mp.walls)
    assert sum(w.length for w in mp.walls) == pytest.approx(mp.free_space.boundary.length)
    assert mp.free_space.is_valid
    assert mp.free_space.contains(mp.start_region) and mp.free_space.contains(mp.end_region)
    # The leader path stays in free space, at least 0.3 m from every wall.
    path = LineString(mp.waypoints)
    assert mp.free_space.contains(path)
    assert min(path.distance(w) for w in mp.walls) >= 0.3
    assert mp.end_region.contains(Point(mp.waypoints[-1]))
    assert not mp.end_region.intersects(mp.start_region)


def test_l_corridor_turns_north():
    mp = l_corridor(0.8)
    assert mp.free_space.contains(Point(5.0, 4.0)) and not mp.free_space.contains(Point(3.0, 4.0))
    assert mp.end_region.bounds[1] == pytest.approx(5.0)  # exit room north of the 10 m axis


def test_building_has_rooms_and_a_path_around_the_block():
    mp = building()
    for room_centre in [(13.8, 15.0), (21.2, 15.0), (13.8, 7.0), (21.2, 7.0)]:
        assert mp.free_space.contains(Point(room_centre))
    # Doors closed: the four rooms are separate pieces of free space; open, one piece.
    assert len(shapely.get_parts(mp.free_space)) == 5
    opened = building(doors_open=True)
    assert opened.free_space.geom_type == "Polygon"
    assert opened.free_space.contains(LineString([(13.8, 15.0), (13.8, 20.5)]))  # through a door
    assert not mp.free_space.contains(Point(17.5, 11.0))  # inside a wall between rooms
    # Start and end halls are only joined the long way round: the direct line crosses walls.
    assert not mp.free_space.contains(LineString([(5.0, 17.0), (5.0, 5.0)]))
    assert LineString(mp.waypoints).length > 55.0
    np.testing.assert_array_less(np.linalg.norm(np.diff(mp.waypoints, axis=0), axis=1), 0.25 + 1e-9)


def test_resample_path_keeps_vertices_and_spacing():
    pts = resample_path(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.6]]), 0.25)
    assert len(pts) == 1 + 4 + 3
    np.testing.assert_allclose(pts[[0, 4, -1]], [[0, 0], [1, 0], [1, 0.6]])
    assert np.all(np.linalg.norm(np.diff(pts, axis=0), axis=1) <= 0.25 + 1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_random_connected_swarm_at_entrance(seed):
    mp = straight_corridor(0.7)
    r = random_connected_swarm(mp.start_region, 30, np.random.default_rng(seed))
    again = random_connected_swarm(mp.start_region, 30, np.random.default_rng(seed))
    np.testing.assert_array_equal(r, again)  # seeded
    assert in_region(r, mp.start_region).all()
    d = np.linalg.norm(r[:, None] - r[None], axis=2) + np.eye(30) * 9
    assert d.min() >= 0.4
    assert is_connected(neighbour_graph(r, mp.walls, 1.0, 0.05))  # G_n connected at k = 0


def test_random_swarms_differ_by_seed_and_fill_building_hall():
    mp = building()
    a = random_connected_swarm(mp.start_region, 100, np.random.default_rng(0))
    b = random_connected_swarm(mp.start_region, 100, np.random.default_rng(1))
    assert not np.allclose(a, b)
    assert is_connected(neighbour_graph(a, mp.walls, 1.0, 0.05))


def test_random_swarm_reports_an_impossible_request():
    with pytest.raises(ValueError, match="cannot place"):
        random_connected_swarm(box(0, 0, 1, 1), 40, np.random.default_rng(0))


def test_open_map_has_no_walls():
    mp = open_map(40.0)
    assert mp.walls == [] and mp.free_space.area == pytest.approx(1600.0)
