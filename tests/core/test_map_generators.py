"""Map generators: the shipped indoor maps are their presets vertex for vertex, the generated
geometry has the declared dimensions, the random field its density, gaps and free regions, the
parameters sweep from the command line and are recorded; bad input is one line naming the key."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from scipy import stats

from swarmscene import api
from swarmscene.core.config import ScenarioConfig
from swarmscene.core.environment import Environment
from swarmscene.core.errors import ConfigError
from swarmscene.core.geometry import build_obstacles
from swarmscene.core.obstacles import EnvironmentConfig
from swarmscene.core.registry import installed_registry
from swarmscene.methods.indoor.maps import building as thesis_building
from swarmscene.methods.indoor.maps import l_corridor, straight_corridor
from swarmscene.methods.maps import (
    building,
    building_free_space,
    corridor,
    corridor_axis,
    corridor_free_space,
    obstacle_field_discs,
)
from swarmscene.plugins.generator.building import BuildingParams
from swarmscene.plugins.generator.corridor import CorridorParams
from swarmscene.plugins.generator.obstacle_field import ObstacleFieldParams

INSTALLED = {"registry": installed_registry()}
"""The context a scenario validates in (the installed plugins choose a map generator)."""

LISTED = json.loads((Path(__file__).parent / "data" / "listed_indoor_maps.json").read_text())
"""The obstacles the indoor presets listed before they became generator presets (from git 5d3625c)."""
SCENARIOS = Path(api.__file__).resolve().parents[1] / "scenarios"


def preset(name: str) -> list:
    return build_obstacles(api.load([f"environment={name}"]).config.environment)[0]


# -- the shipped maps are presets with identical geometry ---------------------------------------
@pytest.mark.parametrize("name", sorted(LISTED))
def test_presets_build_exactly_the_polygons_they_listed(name):
    """Same polygons in the same order, every vertex the same double: the runs cannot differ
    (the indoor presets' metrics and trajectories were also compared before and after)."""
    built = preset(name)
    listed = [shapely.Polygon(points) for points in LISTED[name]]
    assert len(built) == len(listed)
    for a, b in zip(built, listed, strict=True):
        assert np.array_equal(shapely.get_coordinates(a), shapely.get_coordinates(b))


@pytest.mark.parametrize("width", [0.5, 0.65, 0.8, 1.3])
def test_corridors_equal_the_thesis_map_builders_at_any_width(width):
    for params, thesis in ((CorridorParams(width=width), straight_corridor(width)),
                           (CorridorParams(width=width, bend=90), l_corridor(width))):
        built = corridor(params)
        expected = thesis.wall_polygons(0.1)
        assert len(built) == len(expected)
        for a, b in zip(built, expected, strict=True):  # the same up to the 1 nm rounding of generated vertices
            np.testing.assert_allclose(shapely.get_coordinates(a), shapely.get_coordinates(b), atol=1e-9)
        assert corridor_free_space(params).equals(thesis.free_space)


@pytest.mark.parametrize("doors_open", [False, True])
def test_the_four_room_building_is_the_thesis_builders(doors_open):
    assert building_free_space(BuildingParams(doors_open=doors_open)).equals(
        thesis_building(doors_open).free_space)


# -- declared dimensions ------------------------------------------------------------------------
@pytest.mark.parametrize("width, length, bend", [(0.55, 10.0, 0.0), (0.7, 12.0, 45.0), (1.0, 12.0, -100.0)])
def test_corridor_has_width_w_and_length_along_its_axis(width, length, bend):
    params = CorridorParams(width=width, length=length, bend=bend)
    env = Environment(corridor(params))
    axis = corridor_axis(params)
    # Points on the axis at least w from its ends and its bend are w/2 from both walls.
    s = np.linspace(width + 0.5, length / 2 - width - 0.5 * abs(math.tan(math.radians(bend / 2))), 7)
    ends = [(axis[0], axis[1]), (axis[-1], axis[-2])]
    for start, towards in ends:
        t = (towards - start) / np.linalg.norm(towards - start)
        points = start + s[:, None] * t
        np.testing.assert_allclose(env.clearance(points), width / 2, atol=1e-9)
        normal = np.array([-t[1], t[0]])
        for side in (1, -1):  # a wall face at exactly w/2 on each side
            assert env.contains(points + side * (width / 2 + 1e-6) * normal).all()
    assert np.isclose(np.sum(np.linalg.norm(np.diff(axis, axis=0), axis=1)), length)
    # Two rooms and a mitred strip of width w and axis length L: the area is exactly 2 a^2 + w L.
    assert corridor_free_space(params).area == pytest.approx(2 * 6.0**2 + width * length, rel=1e-9)


@pytest.mark.parametrize("rooms", [2, 4, 6, 10])
@pytest.mark.parametrize("doors_open", [False, True])
def test_building_of_n_rooms(rooms, doors_open):
    """Closed doors: the floor and each room are separate pieces of free space; open: one piece
    (through doors of the declared width). The floor's size follows from the rooms."""
    params = BuildingParams(rooms=rooms, doors_open=doors_open)
    free = building_free_space(params)
    pieces = shapely.get_parts(free)
    assert len(pieces) == (1 if doors_open else 1 + rooms)
    room_area = 7.2 * 7.7
    assert sorted(p.area for p in pieces)[:-1] == ([] if doors_open else pytest.approx([room_area] * rooms))
    width = 10.0 + rooms // 2 * 7.2 + (rooms // 2 + 1) * 0.2 + 3.0
    assert free.bounds == pytest.approx((0.0, 0.0, width, 22.0))
    walls = shapely.union_all(building(params))
    assert walls.intersection(free).area < 1e-9  # walls are outside the free space
    if doors_open:  # a 0.9 m door: a disc of radius 0.44 m passes, 0.46 m does not
        door_mid = np.array([10.0 + 0.2 + 3.6, 3.0 + 0.1])
        assert Environment(building(params)).clearance(door_mid[None]) == pytest.approx(0.45, abs=1e-9)


def test_building_rooms_sweep_from_the_command_line():
    base = api.load(["scenario=indoor_building"]).obstacles
    six = api.load(["scenario=indoor_building", "environment.rooms=6"])
    assert len(six.obstacles) > len(base)
    assert six.data["environment"]["rooms"] == 6


# -- the random obstacle field ------------------------------------------------------------------
FIELD = {"bounds": [0.0, 0.0, 60.0, 40.0], "density": 0.08, "radius": {"uniform": [0.3, 1.2]},
         "gap": 0.8, "free_regions": [{"center": [5.0, 20.0], "radius": 4.0},
                                      {"center": [55.0, 20.0], "radius": 3.0}]}


def field(**changes) -> tuple[np.ndarray, np.ndarray]:
    return obstacle_field_discs(ObstacleFieldParams.model_validate({**FIELD, **changes}))


def test_field_density_gaps_and_free_regions():
    c, r = field()
    area = np.pi * np.sum(r**2)
    target = 0.08 * 60 * 40
    assert target <= area < target + np.pi * 1.2**2  # reached, passed by at most one obstacle
    assert (r >= 0.3).all() and (r <= 1.2).all()
    i, j = np.triu_indices(len(c), 1)
    assert (np.hypot(*(c[i] - c[j]).T) - r[i] - r[j]).min() >= 0.8  # the declared gap
    for centre, radius in ((np.array([5.0, 20.0]), 4.0), (np.array([55.0, 20.0]), 3.0)):
        assert (np.hypot(*(c - centre).T) - r).min() > radius  # free regions untouched
    assert ((c >= [0, 0]) & (c <= [60, 40])).all()


def test_sparse_field_draws_uniform_places_and_the_declared_sizes():
    """At low density few candidates are refused: the centres are uniform in the bounds and the
    radii follow their distribution (KS tests)."""
    c, r = field(bounds=[0.0, 0.0, 400.0, 400.0], density=0.01, gap=0.0, free_regions=[],
                 radius={"lognormal": [-0.5, 0.3]})
    assert len(c) > 500
    assert stats.kstest(c[:, 0], stats.uniform(0, 400).cdf).pvalue > 0.01
    assert stats.kstest(c[:, 1], stats.uniform(0, 400).cdf).pvalue > 0.01
    assert stats.kstest(r, stats.lognorm(0.3, scale=np.exp(-0.5)).cdf).pvalue > 0.01


def test_field_is_seeded_by_its_own_stream():
    a, b, other = field(seed=3), field(seed=3), field(seed=4)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0][:5], other[0][:5])


def test_a_field_leaves_the_run_generator_alone(data):
    data["swarm"]["start"] = {"layout": "random", "spacing": 1.0, "extent": 6.0, "center": [0, 0, 2]}
    plain = api.load(data)
    data["environment"] = {"name": "f", "generator": "obstacle_field", **FIELD,
                           "free_regions": [{"center": [0.0, 0.0], "radius": 6.0}]}
    with_field = api.load(data)
    assert with_field.rng_state == plain.rng_state
    assert np.array_equal(with_field.initial_positions, plain.initial_positions)


def test_an_unreachable_density_is_one_line(data):
    data["environment"] = {"name": "f", "generator": "obstacle_field", "bounds": [0, 0, 10, 10],
                           "density": 0.5, "radius": 1.0, "gap": 1.0}
    with pytest.raises(ConfigError) as exc:
        api.load(data)
    (line,) = exc.value.lines
    assert line.startswith("environment.density: obstacles of this radius and gap cover only ")
    assert line.endswith("random tries (got 0.5; lower density or gap)")


def test_shipped_obstacle_field_keeps_the_default_mission_free():
    scenario = api.load(["environment=obstacle_field"])
    env = Environment(scenario.obstacles)
    assert len(scenario.obstacles) > 20
    assert env.clearance(scenario.initial_positions).min() > 0  # the start region is free
    assert env.clearance(np.array([[24.0, 0.0]]))[0] > 3.0


# -- configuration: sweeps, records, listed obstacles, errors -------------------------------------
def test_width_sweeps_numerically_and_equals_the_file_preset():
    swept = api.load(["scenario=indoor_corridor", "environment.width=0.6"]).obstacles
    named = api.load(["scenario=indoor_corridor", "environment=indoor_corridor_w060"]).obstacles
    assert [shapely.get_coordinates(p).tolist() for p in swept] == \
        [shapely.get_coordinates(p).tolist() for p in named]


def test_generic_corridor_preset_bends_into_the_l_corridor():
    bent = api.load(["environment=indoor_corridor", "environment.bend=90"]).obstacles
    assert [shapely.get_coordinates(p).tolist() for p in bent] == \
        [shapely.get_coordinates(p).tolist() for p in preset("indoor_l_corridor_w080")]


def test_effective_config_records_every_generator_parameter_and_rebuilds_the_map():
    scenario = api.load(["scenario=indoor_l_corridor", "environment.width=0.65"])
    recorded = scenario.data["environment"]
    assert recorded == {"name": "indoor_l_corridor_w080", "generator": "corridor", "obstacles": [],
                        "width": 0.65, "length": 10.0, "bend": 90.0, "room": 6.0, "wall_thickness": 0.1}
    again = EnvironmentConfig.model_validate(recorded, context=INSTALLED)
    assert [p.wkb for p in build_obstacles(again)[0]] == [p.wkb for p in scenario.obstacles]


def test_listed_maps_are_recorded_as_before():
    assert api.load(["environment=pillar"]).data["environment"] == {
        "name": "pillar", "obstacles": [{"type": "circle", "center": [12.0, 0.0], "radius": 1.0}]}


def test_listed_obstacles_add_to_a_generated_map():
    env = EnvironmentConfig.model_validate({
        "name": "c", "generator": "corridor", "width": 0.8,
        "obstacles": [{"type": "circle", "center": [-3.0, 2.0], "radius": 0.5}]}, context=INSTALLED)
    polygons, errors = build_obstacles(env)
    assert not errors and len(polygons) == 13
    assert polygons[:12] == corridor(CorridorParams(width=0.8))
    assert polygons[12].centroid.coords[0] == pytest.approx((-3.0, 2.0))


BASE = {"swarm": {"n": 2}, "formation": {"name": "a"}, "avoidance": {"name": "b"}, "dynamics": {"name": "c"}}


@pytest.mark.parametrize("environment, line", [
    ({"generator": "corridor"}, "environment.width: is required"),
    ({"generator": "corridor", "width": 0}, "environment.width: must be > 0.0 (got 0)"),
    ({"generator": "corridor", "width": 0.5, "bend": 180}, "environment.bend: must be < 180.0 (got 180)"),
    ({"generator": "corridor", "width": 0.5, "rooms": 4},
     "environment.rooms: not a parameter of generator corridor (its parameters: width, length, bend, "
     "room, wall_thickness) (got 4)"),
    ({"width": 0.5},
     "environment.width: a parameter of environment.generator corridor, which is not chosen (got 0.5)"),
    ({"generator": "maze", "width": 0.5},
     "environment.generator: unknown map generator 'maze' (valid: building, corridor, obstacle_field) "
     "(got 'maze')"),
    ({"generator": "building", "rooms": 5}, "environment.rooms: must be even (two rows of rooms) (got 5)"),
    ({"generator": "building", "door_width": 8.0},
     "environment.door_width: must be < the room's width 7.2 m (got 8.0)"),
    ({"generator": "obstacle_field", "radius": 1.0}, "environment.density: is required"),
    ({"generator": "obstacle_field", "density": 0.1, "radius": {"normal": [1.0, 0.2]}},
     "environment.radius: must be a positive number or a distribution of positive values (uniform "
     "with low > 0, lognormal, exponential, choice of positives) (got {'normal': [1.0, 0.2]})"),
    ({"generator": "obstacle_field", "density": 0.1, "radius": {"uniform": [1.0, 0.5]}},
     "environment.radius.uniform: must be [low, high] with low <= high (got [1.0, 0.5])"),
    ({"generator": "obstacle_field", "density": 0.1, "radius": 1.0, "bounds": [0, 0, -1, 5]},
     "environment.bounds: must be [x_min, y_min, x_max, y_max] with x_min < x_max, y_min < y_max "
     "(got [0, 0, -1, 5])"),
    ({"generator": "obstacle_field", "density": 0.1, "radius": 1.0,
      "free_regions": [{"center": [0, 0]}]}, "environment.free_regions.0.radius: is required"),
])
def test_bad_generator_input_is_one_line_naming_the_key(environment, line):
    from pydantic import ValidationError

    from swarmscene.core.errors import format_validation_error

    data = {**BASE, "environment": {"name": "x", **environment}}
    with pytest.raises(ValidationError) as exc:
        ScenarioConfig.model_validate(data, context=INSTALLED)
    assert format_validation_error(exc.value, ScenarioConfig, data) == [line]


def test_shipped_environment_files_validate():
    for path in sorted((SCENARIOS / "environment").glob("*.yaml")):
        scenario = api.load([f"environment={path.stem}"])
        assert scenario.config.environment.name == path.stem


def test_a_cached_map_is_not_changed_by_its_users():
    env = EnvironmentConfig.model_validate({
        "name": "c", "generator": "corridor", "width": 0.7,
        "obstacles": [{"type": "circle", "center": [-3.0, 2.0], "radius": 0.5}]}, context=INSTALLED)
    first, _ = build_obstacles(env)
    second, _ = build_obstacles(env)  # the listed circle is added once, not to the cached walls
    assert len(first) == len(second) == 13
