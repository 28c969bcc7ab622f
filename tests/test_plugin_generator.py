"""A third-party map generator chosen by a scenario (issue #27): ``environment.generator=<plugin
name>`` builds the plugin's map, its options validated by its own ``Params`` in the schema's words,
an unknown name reported in ``validate_choice``'s one line, and the run's record loads back."""

from __future__ import annotations

import importlib
import pickle
import types

import pytest
import shapely

from swarmscene import api
from swarmscene.core import registry as registry_module
from swarmscene.core.errors import ConfigError
from swarmscene.core.obstacles import EnvironmentConfig

POSTS = "swarmscene_allkinds.plugin"
BASE = ["environment=open", "swarm.n=3", "swarm.start.layout=line", "clock.duration=1"]


class _EntryPoint:
    name, value = "allkinds", POSTS
    dist = types.SimpleNamespace(name="swarmscene-allkinds", version="1.0.0")

    def load(self):
        return importlib.import_module(self.value)


@pytest.fixture
def registry(monkeypatch):
    monkeypatch.setattr(registry_module, "entry_points", lambda group: [_EntryPoint()])
    return api.plugins()[1]


def _coordinates(polygons):
    return [shapely.get_coordinates(p).tolist() for p in polygons]


def _lines(overrides, registry):
    with pytest.raises(ConfigError) as exc:
        api.load([*BASE, *overrides], registry)
    return exc.value.lines


def test_a_scenario_chooses_the_plugin_generator_by_name_and_flies_among_its_posts(registry):
    scenario = api.load([*BASE, "environment.generator=ak_posts", "environment.count=2"], registry)
    # Posts: squares [5k, 5k + 1] x [20, 21], k = 0, 1
    assert _coordinates(scenario.obstacles) == [
        [[1.0, 20.0], [1.0, 21.0], [0.0, 21.0], [0.0, 20.0], [1.0, 20.0]],
        [[6.0, 20.0], [6.0, 21.0], [5.0, 21.0], [5.0, 20.0], [6.0, 20.0]],
    ]
    assert scenario.config.environment.generator_class is registry.get("generator", "ak_posts")
    assert scenario.data["environment"] == {"name": "open", "generator": "ak_posts", "obstacles": [],
                                            "count": 2}
    run = api.run(scenario)
    # its clearance is to the posts: 20 m north of a line of agents near the x axis
    xy = run.trajectory["pos"][:, :, :2].reshape(-1, 2)
    posts = shapely.union_all(scenario.obstacles)
    nearest = min(posts.distance(shapely.Point(p)) for p in xy)
    assert run.metrics["min_clearance"] == pytest.approx(nearest, rel=1e-9)
    assert 15.0 < nearest < 21.0
    again = api.load(scenario.data, registry)  # the run's record validates to itself
    assert again.data == scenario.data
    assert _coordinates(again.obstacles) == _coordinates(scenario.obstacles)


def test_the_plugin_generator_parameters_get_their_defaults_and_add_to_listed_obstacles(registry):
    scenario = api.load([*BASE, "environment.generator=ak_posts",
                         "environment.obstacles=[{type: circle, center: [-5, 5], radius: 1}]"], registry)
    assert scenario.data["environment"]["count"] == 3  # Posts.Params' default, recorded
    assert len(scenario.obstacles) == 4  # three posts, then the listed circle
    assert scenario.obstacles[3].centroid.coords[0] == pytest.approx((-5.0, 5.0))


@pytest.mark.parametrize("overrides, line", [
    (["environment.generator=ak_posts", "environment.count=0"],
     "environment.count: must be >= 1 (got 0)"),
    (["environment.generator=ak_posts", "environment.width=1.0"],
     "environment.width: not a parameter of generator ak_posts (its parameters: count) (got 1.0)"),
    (["environment.count=2"],
     "environment.count: a parameter of environment.generator ak_posts, which is not chosen (got 2)"),
    (["environment.generator=corridor", "environment.width=1.0", "environment.count=2"],
     "environment.count: not a parameter of generator corridor (its parameters: width, length, bend, "
     "room, wall_thickness) (got 2)"),
    (["environment.generator=maze"],
     "environment.generator: unknown map generator 'maze' (valid: ak_posts, building, corridor, "
     "obstacle_field)"),
    # a plugin generator's parameter goes with the unknown name, as a built-in's does: one line
    (["environment.generator=maze", "environment.count=2", "environment.width=1.0"],
     "environment.generator: unknown map generator 'maze' (valid: ak_posts, building, corridor, "
     "obstacle_field)"),
])
def test_bad_plugin_generator_input_is_one_line_naming_the_key(registry, overrides, line):
    assert _lines(overrides, registry) == [line]


def test_without_the_package_its_generator_is_an_unknown_name():
    lines = _lines(["environment.generator=ak_posts"], api.plugins()[1])
    assert lines == ["environment.generator: unknown map generator 'ak_posts' (valid: building, corridor, "
                     "obstacle_field)"]
    with pytest.raises(Exception, match="a map generator is chosen from a plugin registry"):
        EnvironmentConfig.model_validate({"generator": "corridor"})  # no registry: the engine lists none


def test_a_validated_plugin_map_survives_pickling(registry):
    """A sweep's launcher pickles the scenario: the chosen class and its parameters go with it."""
    env = api.load([*BASE, "environment.generator=ak_posts", "environment.count=1"], registry).config.environment
    back = pickle.loads(pickle.dumps(env))
    assert back.generator_class is env.generator_class and back.generator_params() == env.generator_params()
    assert _coordinates(back.generated()[0]) == _coordinates(env.generated()[0])


def test_a_plugin_generator_run_directory_reads_back_with_its_posts(registry, tmp_path):
    """Pictures, replay and export rebuild the map from the run's config.yaml with the installed
    registry: a plugin's generator is found there as in the run (it was refused before)."""
    from swarmscene.views import plots

    scenario = api.load([*BASE, "environment.generator=ak_posts", "environment.count=2"], registry)
    api.run(scenario, output_dir=tmp_path / "run")
    back = plots.load_run(tmp_path / "run")
    assert _coordinates(back.obstacles) == _coordinates(scenario.obstacles)


def test_a_check_across_a_generators_parameters_is_one_line_at_the_field_it_names(monkeypatch):
    """A third-party generator's model validator (`ValueError("a: must be < b")`, as the docs ask)
    was reported at the whole environment with the dict of parameters as its value."""
    from pydantic import Field, model_validator

    from swarmscene.plugin import MapGenerator, StrictModel

    class Strip(MapGenerator):
        name = "strip"

        class Params(StrictModel):
            a: float = Field(1.0, gt=0, description="m")
            b: float = Field(2.0, gt=0, description="m")

            @model_validator(mode="after")
            def _ordered(self):
                if self.a >= self.b:
                    raise ValueError(f"a: must be < b = {self.b} m")
                return self

        @classmethod
        def build(cls, params):
            return [shapely.box(0.0, 10.0, params.a, 11.0)]

    _, registry = api.plugins()
    registry.register("generator", Strip)
    with pytest.raises(ConfigError) as err:
        api.load([*BASE, "environment.generator=strip", "++environment.a=5"], registry)
    assert err.value.lines == ["environment.a: must be < b = 2.0 m (got 5)"]
