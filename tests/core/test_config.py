"""Bad input: every problem is one line naming the dotted key, the value and what is allowed."""

from __future__ import annotations

import copy

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarmscene import api
from swarmscene.core.errors import ConfigError


def errors_of(data: dict) -> list[str]:
    with pytest.raises(ConfigError) as info:
        api.load(data)
    return info.value.lines


def test_default_config_validates(data):
    scenario = api.load(data)
    assert scenario.config.swarm.n == 5
    assert scenario.plugin_classes["formation"].name == "static_shape"


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["swarm"].update(n=0), "swarm.n: must be >= 1 (got 0)"),
        (lambda d: d["swarm"].update(n="abc"), "swarm.n: must be an integer (got 'abc')"),
        (lambda d: d["clock"].update(guidance_period=-0.1), "clock.guidance_period: must be > 0.0 (got -0.1)"),
        (
            lambda d: d["clock"].update(physics_step=0.03),
            "clock.physics_step: must divide clock.guidance_period = 0.1 (got 0.03)",
        ),
        (lambda d: d.update(bogus=1), "bogus: unknown key"),
        (lambda d: d["avoidance"].update(K=0), "avoidance.K: unknown key (valid keys: v_max, influence, obstacle_influence, lookahead) (got 0)"),
        (lambda d: d["avoidance"].update(v_max=0), "avoidance.v_max: must be > 0.0 (got 0)"),
        (lambda d: d["formation"].update(name="nope"), "formation.name: unknown formation 'nope' (valid: "),
        (lambda d: d["formation"].update(waypoints=[]), "formation.waypoints: must have at least 1 item(s) (got [])"),
        (
            lambda d: d.update(events=[{"at": 1.0, "agents": [9], "name": "hover"}]),
            "events.0.agents: agents are 0..4 (got [9])",
        ),
        (
            lambda d: d.update(events=[{"at": 1.0, "agents": [0], "name": "explode"}]),
            "events.0.name: unknown event kind 'explode' (valid: comm_loss, drift, hover, motor_failure, "
            "stuck)",  # the registered kinds, one validate_choice line like every kind's
        ),
        (
            lambda d: d["environment"].update(obstacles=[{"type": "polygon", "points": [[0, 0], [1, 1], [0, 1], [1, 0]]}]),
            "environment.obstacles.0.points: malformed polygon (Self-intersection",
        ),
        (
            lambda d: d["environment"].update(obstacles=[{"type": "circle", "center": [0, 0], "radius": 3}]),
            "swarm.start: agents [0, 1, 2, 3, 4] start inside an obstacle",
        ),
        (
            lambda d: d["environment"].update(obstacles=[{"type": "hexagon"}]),
            "environment.obstacles.0: unknown type (valid: 'polygon', 'circle', 'wall') (got {'type': 'hexagon'})",
        ),
        (
            lambda d: d["swarm"]["start"].update(spacing=0.2),
            "swarm.start: 10 pairs of agents start closer than safety.separation_limit = 0.5 m (first:",
        ),
        (lambda d: d["clock"].update(duration=float("inf")), "clock.duration: must be a finite number (got inf)"),
        (lambda d: d["swarm"].update(leader=7), "swarm.leader: must be < swarm.n = 5 (got 7)"),
        (
            lambda d: (d["swarm"].update(leader=None), d.update(formation={"name": "hex_lattice"})),
            "swarm.leader: formation 'hex_lattice' needs a leader (an agent index 0..4)",
        ),
    ],
)
def test_bad_input_gives_one_line(data, edit, expected):
    edit(data)
    lines = errors_of(data)
    assert len(lines) == 1, lines
    assert lines[0].startswith(expected), lines[0]


def test_start_overlap_can_be_a_warning(data):
    """Thesis 4.5.2 starts its agents closer than d_c on purpose: `warn` lets it run."""
    data["swarm"]["start"]["spacing"] = 0.2
    data["safety"]["start_overlap"] = "warn"
    with pytest.warns(UserWarning, match="start closer than safety.separation_limit"):
        api.load(data)


def test_all_problems_reported_at_once(data):
    data["swarm"]["n"] = 0
    data["avoidance"]["v_max"] = -1
    data["formation"]["waypoints"] = []
    lines = errors_of(data)
    assert {line.split(":")[0] for line in lines} == {"swarm.n", "avoidance.v_max", "formation.waypoints"}


def test_scenario_cannot_name_import_paths(data):
    """Plugins are chosen by registered name only: an import path is just an unknown name."""
    data["dynamics"]["name"] = "os.system"
    (line,) = errors_of(data)
    assert line.startswith("dynamics.name: unknown dynamics 'os.system'")
    data["dynamics"]["name"] = "double_integrator"
    data["dynamics"]["_target_"] = "os.system"
    (line,) = errors_of(data)
    assert line.startswith("dynamics._target_: unknown key")


# -- property: random override sets either run or fail with one-line errors ------------------

PATHS = [
    ("swarm", "n"),
    ("swarm", "leader"),
    ("swarm", "start", "spacing"),
    ("swarm", "start", "kind"),
    ("clock", "guidance_period"),
    ("clock", "physics_step"),
    ("clock", "duration"),
    ("safety", "separation_limit"),
    ("comm", "range"),
    ("formation", "spacing"),
    ("formation", "shape"),
    ("formation", "speed"),
    ("avoidance", "v_max"),
    ("avoidance", "name"),
    ("dynamics", "name"),
    ("dynamics", "u_sat"),
    ("seed",),
    ("events",),
]
VALUES = st.one_of(
    st.integers(-3, 40),
    st.floats(-5, 50),
    st.sampled_from([float("nan"), float("inf"), -float("inf"), 1e-9, 1e9]),
    st.sampled_from(["line", "grid", "circle", "v", "none", "potential", "single_integrator", "x", ""]),
    st.just([]),
    st.just([{"at": 0.5, "agents": [1], "name": "hover"}]),
    st.none(),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.sampled_from(PATHS), VALUES), min_size=1, max_size=4))
def test_random_overrides_run_or_fail_cleanly(default_data, edits):
    data = copy.deepcopy(default_data)
    data["clock"]["duration"] = 1.0
    data["output"]["trajectory"] = False
    for path, value in edits:
        node = data
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    try:
        scenario = api.load(data)
    except ConfigError as exc:
        assert exc.lines and all(": " in line and "\n" not in line for line in exc.lines)
        return
    cfg = scenario.config
    if cfg.clock.duration / cfg.clock.guidance_period * cfg.substeps * cfg.swarm.n > 200_000:
        return  # valid but long: the kernel is exercised by the other examples
    result = api.run(scenario)
    assert result.metrics["steps"] >= 1


def test_connected_random_start_redraws_until_connected_and_keeps_a_connected_first_draw():
    import networkx as nx
    import numpy as np

    from swarmscene.core.geometry import initial_positions

    def positions(edits: list[str]) -> np.ndarray:
        config = api.load(["swarm=grid", "swarm.n=12", "swarm.start.layout=random", "swarm.start.extent=9",
                           "swarm.start.spacing=0.6", "comm.range=3", *edits]).config
        return initial_positions(config, np.random.default_rng(config.seed))

    def connected(pos: np.ndarray) -> bool:
        d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
        return nx.is_connected(nx.from_numpy_array((d <= 3.0).astype(int)))

    plain = [positions([f"seed={s}"]) for s in range(20)]
    drawn = [positions([f"seed={s}", "swarm.start.connected=true"]) for s in range(20)]
    assert not all(connected(p) for p in plain)  # the case exercises redraws
    assert all(connected(p) for p in drawn)
    assert all(np.array_equal(a, b) for a, b in zip(plain, drawn, strict=True) if connected(a))
    lines = errors_of_overrides(["swarm=grid", "swarm.n=12", "swarm.start.layout=random", "swarm.start.extent=500",
                                 "swarm.start.connected=true", "comm.range=3"])
    assert lines == ["swarm.start: no connected swarm (comm.range = 3.0 m) in 200 random draws of 12 agents "
                     "2.0 m apart in a 500.0 m square; shrink swarm.start.extent"]
    # agents spacing apart cannot link at a shorter range: refused without drawing
    lines = errors_of_overrides(["swarm=grid", "swarm.n=12", "swarm.start.layout=random", "swarm.start.connected=true",
                                 "comm.range=1"])
    assert lines == ["swarm.start: agents 2.0 m apart cannot link at comm.range = 1.0 m "
                     "(swarm.start.connected needs comm.range >= swarm.start.spacing)"]


def errors_of_overrides(overrides: list[str]) -> list[str]:
    with pytest.raises(ConfigError) as info:
        api.load(overrides)
    return info.value.lines


def test_options_two_plugins_declare_for_one_shared_quantity_must_agree():
    """The thesis' formation and avoidance both declare the sensing graph's parameters (built once
    per tick for both): two values for one of them is refused in one line naming both keys."""
    from swarmscene import api
    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        api.load(["scenario=indoor_corridor", "formation.d_n=1.2"])
    assert err.value.lines == [
        "avoidance.d_n: must equal formation.d_n = 1.2 (got 1.0): both describe the thesis' sensing "
        "graphs (G_s, G_n, G_sigma), built once per tick for every plugin"
    ]
    api.load(["scenario=indoor_corridor", "formation.d_n=1.2", "avoidance.d_n=1.2"])  # agreeing: fine


def test_the_old_names_of_the_safety_limits_still_work_for_one_release_with_a_warning():
    """safety.min_separation / min_clearance named both the limit and the measured metric; the
    limits are now separation_limit / clearance_limit, and the old keys are accepted (and win over
    the new ones' defaults) with a one-line deprecation warning."""
    from swarmscene import api

    with pytest.warns(DeprecationWarning, match=r"safety.min_separation is deprecated: write safety.separation_limit"):
        scenario = api.load(["safety.min_separation=0.7"])
    assert scenario.config.safety.separation_limit == 0.7
    assert "min_separation" not in scenario.data["safety"]  # the record holds the new name only
    with pytest.warns(DeprecationWarning, match="BuildContext.min_clearance is deprecated"):
        sim = api.build(["safety.clearance_limit=0.4"])
        assert sim.formation.ctx.min_clearance == 0.4


@pytest.mark.parametrize(("overrides", "line"), [
    (["safety.min_separation=-1"], "safety.min_separation (now safety.separation_limit): must be >= 0.0 (got -1)"),
    (["scenario=cem_six_vehicle", "avoidance.n=0"],
     "avoidance.n (now avoidance.newton_iterations): must be >= 1 (got 0)"),
])
def test_a_bad_value_under_a_deprecated_name_is_reported_under_the_name_typed(overrides, line):
    """The error names the key the user wrote, with its new name; not only the new name, which the
    user never typed. The deprecation is a SwarmsceneDeprecationWarning (shown on the command line)."""
    from swarmscene import api
    from swarmscene.plugin import SwarmsceneDeprecationWarning

    with pytest.warns(SwarmsceneDeprecationWarning), pytest.raises(ConfigError) as err:
        api.load(overrides)
    assert err.value.lines == [line]
