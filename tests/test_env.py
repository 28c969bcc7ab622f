"""swarmscene.env: the third-party API suites, parity with the policy plugin, observations,
actions, rewards, failures, seeded resets, and a policy registered by name."""

from __future__ import annotations

import sys
from importlib.metadata import EntryPoint

import numpy as np
import pytest
import shapely
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

from swarmscene import api
from swarmscene.core.environment import Environment
from swarmscene.core.errors import ConfigError
from swarmscene.core.sensing import Sensing
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.env import make_env, make_gym_env
from swarmscene.methods.policy import policies
from swarmscene.methods.policy.observation import ObservationLayout, observe
from swarmscene.methods.policy.policies import make_policy

SHORT = ["clock.duration=3"]
# Agent 0 fails at t = 10 s (events=lead_fails) in a 12 s episode.
FAILING = ["events=lead_fails", "clock.duration=12"]
# One agent flying in the open at the single integrator's exact kinematics.
ALONE = ["swarm.n=1", "swarm.leader=null", "environment=open", "dynamics=single_integrator",
         "dynamics.u_max=10", "formation.shape=line", "clock.duration=2"]


def test_parallel_env_passes_pettingzoo_parallel_api_test():
    # 150 cycles run two 12 s episodes (120 ticks each), each with an agent failing at 10 s.
    parallel_api_test(make_env(FAILING), num_cycles=150)


def test_gym_env_passes_gymnasium_check_env():
    check_env(make_gym_env(SHORT), skip_render_check=True)


def test_env_driven_by_a_policy_flies_exactly_as_the_policy_plugin():
    """Actions computed from the env's observations by seek_reference reproduce, bit for bit, the
    run where the same policy flies as the avoidance plugin: same inputs, same kernel."""
    run = api.run([*FAILING, "seed=3", "avoidance=policy"])
    env = make_env(FAILING)
    env.reset(seed=3)
    episode = env.driver.episode
    seek = api.plugins()[1].get("policy", "seek_reference")
    policy = make_policy(seek, episode.policy.layout, episode.policy.spec, {})
    while env.agents:
        act = policy(episode.observe())
        _, _, _, _, infos = env.step({a: act[int(a.split("_")[1])] for a in env.agents})
    metrics = next(iter(infos.values()))["metrics"]
    assert np.array_equal(env.sim.world.pos, run.trajectory["pos"][-1])
    shared = set(metrics) & set(run.metrics)
    assert {"min_separation", "collisions", "steps", "connected", "healthy_at_end"} <= shared
    assert {k: metrics[k] for k in shared} == {k: run.metrics[k] for k in shared}
    assert metrics["steps"] == 120 and metrics["healthy_at_end"] == 4


def test_a_failed_agent_is_terminated_alone_and_leaves_agents():
    env = make_env(FAILING)
    env.reset(seed=0)
    ended_at = None
    while env.agents:
        acting = list(env.agents)
        _, _, terms, truncs, _ = env.step({a: np.zeros(3, dtype=np.float32) for a in acting})
        if terms.get("agent_0") and ended_at is None:
            ended_at = env.sim.world.t
            assert [a for a, t in terms.items() if t] == ["agent_0"]
            assert env.agents == ["agent_1", "agent_2", "agent_3", "agent_4"]
        elif ended_at is not None:
            assert "agent_0" not in terms
    assert ended_at == pytest.approx(10.1)  # the event at 10.0 s is applied in the tick ending at 10.1 s
    assert all(truncs.values()) and not any(terms.values())  # the others run to clock.duration


def test_seeded_reset_repeats_and_another_seed_differs():
    env = make_env(["swarm.start.layout=random", "swarm.start.spacing=1.0", *SHORT])
    first, _ = env.reset(seed=5)
    again, _ = env.reset(seed=5)
    other, _ = env.reset(seed=6)
    assert all(np.array_equal(first[a], again[a]) for a in first)
    assert not np.array_equal(first["agent_0"], other["agent_0"])
    assert env.sim.config.seed == 6
    # without a seed: the next draw of a generator seeded by the last seed given, so it repeats too
    env.reset(seed=5)
    env.reset()
    drawn = env.sim.config.seed
    env.reset(seed=5)
    env.reset()
    assert env.sim.config.seed == drawn == int(np.random.default_rng(5).integers(2**31 - 1))


def test_observation_rows_hold_neighbours_obstacle_and_reference():
    pos = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 3.0, 1.0], [0.0, 30.0, 1.0]])
    world = WorldState.at_rest(pos)
    world.vel[1] = [0.5, 0.0, 0.0]
    env = Environment([shapely.box(4.0, -1.0, 6.0, 1.0)])
    sensing = Sensing(world, env, comm_range=10.0)
    ref = Setpoints.hold(pos)
    ref.mode[0], ref.pos[0], ref.vel[0] = Mode.TRACK, [2.0, 1.0, 1.0], [1.0, 0.0, 0.0]
    ref.mode[1] = Mode.VELOCITY
    layout = ObservationLayout(2)
    obs = observe(sensing, ref, layout, radius=10.0, obstacle_radius=5.0)
    assert obs.shape == (4, layout.size) == (4, 33) and obs.dtype == np.float32
    f = layout.split(obs)
    np.testing.assert_array_equal(f["nbr_pos"][0], [[1.0, 0.0, 0.0], [0.0, 3.0, 0.0]])  # nearest first
    np.testing.assert_array_equal(f["nbr_vel"][0], [[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(f["nbr_mask"], [[1, 1], [1, 1], [1, 1], [0, 0]])  # agent 3 out of range
    np.testing.assert_array_equal(f["nbr_pos"][3], np.zeros((2, 3)))
    # agent 2 sees the box's corner (4, 1) at sqrt(20) m; agent 3 sees nothing within R_o = 5 m
    np.testing.assert_allclose(f["obs_clearance"][:, 0], [4.0, 3.0, np.sqrt(20.0), 5.0], rtol=1e-6)
    np.testing.assert_allclose(f["obs_dir"][:3], [[1, 0, 0], [1, 0, 0], [4 / 20**0.5, -2 / 20**0.5, 0]], rtol=1e-6)
    np.testing.assert_array_equal(f["obs_dir"][3], [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(f["obs_mask"][:, 0], [1, 1, 1, 0])
    np.testing.assert_array_equal(f["ref_offset"][:2], [[2.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(f["ref_mask"][:, 0], [1, 0, 0, 0])
    np.testing.assert_array_equal(f["ref_vel"][0], [1.0, 0.0, 0.0])


def test_velocity_and_acceleration_actions_through_the_dynamics():
    """Single integrator (r += T u): a velocity action a moves a * max_speed * T_s; an
    acceleration action a from rest commands T_s * a * max_accel."""
    env = make_gym_env([*ALONE, "avoidance=policy", "avoidance.max_speed=3"])
    env.reset(seed=0)
    start = env.sim.world.pos.copy()
    env.step(np.array([[1.0, -0.5, 0.0]], dtype=np.float32))
    np.testing.assert_allclose(env.sim.world.pos - start, [[0.3, -0.15, 0.0]], atol=1e-12)
    env = make_gym_env([*ALONE, "avoidance=policy", "avoidance.action=acceleration", "avoidance.max_accel=4"])
    env.reset(seed=0)
    env.step(np.array([[1.0, 0.0, 0.0]], dtype=np.float32))
    np.testing.assert_allclose(env.sim.world.vel, [[0.4, 0.0, 0.0]], atol=1e-12)
    env.step(np.array([[1.0, 0.0, 0.0]], dtype=np.float32))
    np.testing.assert_allclose(env.sim.world.vel, [[0.8, 0.0, 0.0]], atol=1e-12)


def test_reward_is_progress_minus_the_safety_penalties():
    # Progress: a reference that jumps to (3, 4, 1) at the second tick (formation speed 1000 m/s);
    # the agent at the origin flies 0.1 m straight at it: progress 0.1, effort 0.5 |a|^2 = 0.125.
    env = make_gym_env([*ALONE, "swarm.start.layout=explicit", "swarm.start.positions=[[0,0,1]]",
                        "formation.waypoints=[[3,4,1]]", "formation.speed=1000", "avoidance=policy",
                        "avoidance.max_speed=2"], {"reward": {"progress": 1.0, "effort": 0.5}})
    env.reset(seed=0)
    _, reward, *_ = env.step(np.zeros((1, 3), dtype=np.float32))
    assert reward == 0.0  # the reference starts where the agent is
    _, reward, *_ = env.step(np.array([[0.3, 0.4, 0.0]], dtype=np.float32))
    np.testing.assert_allclose(env.driver.episode.policy.reference.pos, [[3.0, 4.0, 1.0]])
    assert reward == pytest.approx(0.1 - 0.125, abs=1e-7)  # the action is float32
    # Separation: two agents 0.3 m apart (safety.separation_limit 0.5) cost 10 each per tick.
    env = make_env(["swarm.n=2", "swarm.start.layout=line", "swarm.start.spacing=0.3", "safety.start_overlap=warn",
                    "environment=open", *SHORT], {"reward": {"progress": 0.0}})
    env.reset(seed=0)
    _, rewards, *_ = env.step({a: np.zeros(3, dtype=np.float32) for a in env.agents})
    assert rewards == {"agent_0": -10.0, "agent_1": -10.0}


def test_the_complete_bonus_is_paid_once_whether_or_not_completion_ends_the_run(monkeypatch):
    """reward.complete, "+ complete * [the formation reports its mission complete]": with
    termination.on_complete=false it was never paid. Now the first tick the formation reports
    its mission complete pays it, once; the run goes on where completion does not end it."""
    for on_complete, ends in (("true", True), ("false", False)):
        env = make_gym_env([*ALONE, f"termination.on_complete={on_complete}"],
                           {"reward": {"progress": 0.0, "separation": 0.0, "clearance": 0.0, "complete": 100.0}})
        env.reset(seed=0)
        formation = env.driver.episode.sim.formation
        monkeypatch.setattr(formation, "complete", lambda world: False)
        zero = np.zeros((1, 3), dtype=np.float32)
        assert env.step(zero)[1] == 0.0
        monkeypatch.setattr(formation, "complete", lambda world: True)
        _, reward, terminated, *_ = env.step(zero)
        assert reward == 100.0 and terminated is ends, on_complete
        if not ends:
            assert [env.step(zero)[1] for _ in range(3)] == [0.0, 0.0, 0.0]


def test_an_avoidance_option_the_environment_would_drop_and_bad_options_are_one_line():
    """The environment flies avoidance=policy: an avoidance.<key> override of another avoidance was
    silently dropped (the command line refuses it). Bad environment options were a pydantic error
    of several lines; a config given as one string failed as 's: cannot parse override'."""
    with pytest.raises(ConfigError) as err:
        make_env([*SHORT, "avoidance.neighbours=8"])
    assert err.value.lines[0].startswith("avoidance.neighbours: the environment flies avoidance=policy in place of ")
    assert make_env([*SHORT, "avoidance=policy", "avoidance.neighbours=8"]).driver.layout_size == 19 + 7 * 8
    with pytest.raises(ConfigError) as err:
        make_env(SHORT, {"reward": {"efort": 1.0}})
    assert len(err.value.lines) == 1 and err.value.lines[0].startswith("reward.efort: unknown key")
    with pytest.raises(ConfigError) as err:
        make_env("scenario=swap")
    assert err.value.lines == ["config: a list of overrides or a composed mapping, not the string 'scenario=swap' "
                               "(write ['scenario=swap'])"]


def test_the_clearance_penalty_falls_on_the_agents_near_an_obstacle_only():
    """The default map's pillar (centre (12, 0), radius 1; safety.clearance_limit 0.3 m): an agent
    0.2 m from it pays 10 a tick, one 8 m away nothing; two agents far from it pay nothing, which
    the reward knows from the tick's own obstacle query without asking again."""
    def rewards(positions: str) -> tuple[dict, object]:
        env = make_env(["swarm.n=2", "swarm.start.layout=explicit", f"swarm.start.positions={positions}",
                        "safety.start_overlap=warn", *SHORT], {"reward": {"progress": 0.0}})
        env.reset(seed=0)
        return env.step({a: np.zeros(3, dtype=np.float32) for a in env.agents})[1], env.driver.episode.sim.sensing

    near, _ = rewards("[[12,1.2,2],[4,0,2]]")
    assert near == {"agent_0": -10.0, "agent_1": 0.0}
    far, sensing = rewards("[[4,0,2],[4,3,2]]")
    assert far == {"agent_0": 0.0, "agent_1": 0.0} and sensing.nothing_within(0.3)


def test_collision_ends_the_episode_with_termination_on_collision():
    env = make_env(["swarm.n=2", "swarm.start.layout=line", "swarm.start.spacing=0.3", "safety.start_overlap=warn",
                    "environment=open", "termination.on_collision=true", *SHORT])
    env.reset(seed=0)
    _, _, terms, truncs, infos = env.step({a: np.zeros(3, dtype=np.float32) for a in env.agents})
    assert terms == {"agent_0": True, "agent_1": True} and not any(truncs.values())
    assert env.agents == []
    assert infos["agent_0"]["metrics"]["stop_reason"] == "collision"
    assert infos["agent_0"]["metrics"]["collisions"] == 1


def test_the_policy_plugin_names_an_unknown_policy_in_one_line():
    with pytest.raises(ConfigError) as err:
        api.build(["avoidance=policy", "avoidance.policy=nope"])
    assert err.value.lines == ["avoidance.policy: unknown policy 'nope' (valid: seek_reference)"]


def test_a_packaged_policy_flies_as_a_plugin_by_name(tmp_path, monkeypatch):
    """A package's policy, found through the deprecated entry-point group swarmscene.policies (one
    more release, with a DeprecationWarning naming the hook), chosen by name in the scenario: here
    one that sends every agent up at half the top speed."""
    (tmp_path / "climb_policy.py").write_text(
        "import numpy as np\n"
        "def make(layout, spec, rate=0.5):\n"
        "    return lambda obs: np.tile([0.0, 0.0, rate], (len(obs), 1))\n"
    )
    monkeypatch.delitem(sys.modules, "climb_policy", raising=False)  # another test's module of that name
    monkeypatch.syspath_prepend(str(tmp_path))
    ep = EntryPoint(name="climb", value="climb_policy:make", group=policies.POLICY_GROUP)
    monkeypatch.setattr(policies, "entry_points", lambda group: [ep] if group == policies.POLICY_GROUP else [])
    with pytest.warns(DeprecationWarning, match="swarmscene_register_policies"):
        run = api.run([*ALONE, "avoidance=policy", "avoidance.policy=climb",
                       "avoidance.policy_options.rate=0.25", "avoidance.max_speed=4"])
    climb = run.trajectory["pos"][:, 0, 2] - run.trajectory["pos"][0, 0, 2]
    np.testing.assert_allclose(climb, np.arange(len(climb)) * 0.1, atol=1e-12)  # 1 m/s for 2 s


def test_neighbours_beyond_the_shared_knn_query_extend_it_in_order():
    """k <= NEAR_K reads the tick's shared kNN query, larger k queries the tree: same neighbours."""
    rng = np.random.default_rng(1)
    world = WorldState.at_rest(rng.uniform(0.0, 30.0, (300, 3)))
    small = ObservationLayout(4).split(observe(Sensing(world, Environment(), 20.0), None, ObservationLayout(4), 3.0, 5.0))
    large = ObservationLayout(9).split(observe(Sensing(world, Environment(), 20.0), None, ObservationLayout(9), 3.0, 5.0))
    np.testing.assert_array_equal(large["nbr_pos"][:, :4], small["nbr_pos"])
    np.testing.assert_array_equal(large["nbr_mask"][:, :4], small["nbr_mask"])
    assert 0 < small["nbr_mask"].mean() < 1  # some agents have fewer than 4 neighbours within 3 m
    dist = np.linalg.norm(large["nbr_pos"], axis=2)
    assert np.all(np.diff(np.where(large["nbr_mask"] > 0, dist, 1e9), axis=1) >= 0)  # nearest first, padding last


# -- what the entry points refuse ------------------------------------------------------------------
BAD_AGENT_ACTIONS = [
    (None, "action of agent_0: got None; expected an array of shape (3,) of finite numbers in [-1, 1]"),
    ([0.5], "action of agent_0: shape (1,); expected an array of shape (3,) of finite numbers in [-1, 1]"),
    (0.5, "action of agent_0: shape (); expected an array of shape (3,) of finite numbers in [-1, 1]"),
    ([0.1, np.nan, 0.0], "action of agent_0: holds NaN or infinite values; expected an array of shape (3,)"),
    ([0.1, np.inf, 0.0], "action of agent_0: holds NaN or infinite values; expected an array of shape (3,)"),
    (["a", "b", "c"], "action of agent_0: dtype <U1 is not a real number type"),
    ([True, False, True], "action of agent_0: dtype bool is not a real number type"),
    ([1j, 0, 0], "action of agent_0: dtype complex128 is not a real number type"),
]


@pytest.mark.parametrize("value, message", BAD_AGENT_ACTIONS)
def test_the_parallel_env_refuses_a_bad_action_in_one_line(value, message):
    env = make_env(SHORT)
    env.reset(seed=0)
    before = env.sim.world.pos.copy()
    with pytest.raises(ValueError) as info:
        env.step({"agent_0": value, **{a: np.zeros(3) for a in env.agents[1:]}})
    assert str(info.value).startswith(message) and "\n" not in str(info.value)
    assert env.sim.step_count == 0 and np.array_equal(env.sim.world.pos, before)  # nothing stepped


def test_the_parallel_env_names_an_unknown_agent_and_a_non_dict():
    env = make_env(SHORT)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions: unknown agent 'agent_99' \(agents: agent_0 \.\. agent_4\)$"):
        env.step({"agent_99": np.zeros(3)})
    with pytest.raises(ValueError, match=r"^actions: expected a dict \{agent name: action\}, got list$"):
        env.step([np.zeros(3)])


@pytest.mark.parametrize("value, message", [
    (None, "action: got None; expected an array of shape (5, 3)"),
    (np.zeros(3), "action: shape (3,); expected an array of shape (5, 3)"),
    (np.zeros((3, 5)), "action: shape (3, 5); expected an array of shape (5, 3)"),
    (np.zeros((5, 1)), "action: shape (5, 1); expected an array of shape (5, 3)"),
    (np.full((5, 3), np.nan), "action: holds NaN or infinite values"),
    (np.zeros((5, 3), dtype=object), "action: dtype object is not a real number type"),
])
def test_the_gym_env_refuses_a_bad_action_in_one_line(value, message):
    env = make_gym_env(SHORT)
    env.reset(seed=0)
    with pytest.raises(ValueError) as info:
        env.step(value)
    assert str(info.value).startswith(message)
    assert env.sim.step_count == 0


def test_the_gym_env_takes_float32_and_integer_actions_and_refuses_a_step_before_reset():
    env = make_gym_env(SHORT)
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros((5, 3)))
    env.reset(seed=0)
    env.step(env.action_space.sample())  # float32, as the space gives it
    env.step(np.zeros((5, 3), dtype=int))
    assert env.sim.step_count == 2


def test_every_preset_has_a_gymnasium_id_and_any_scenario_can_get_one():
    import gymnasium as gym

    from swarmscene import env as swarm_env
    from swarmscene.composition.groups import group_options

    assert swarm_env.GYM_IDS == [f"swarmscene/{p}-v0" for p in group_options("scenario")]
    made = gym.make("swarmscene.env:swarmscene/swap-v0")
    assert made.unwrapped.driver.scenario.config.name == "swap"
    envs = gym.make_vec("swarmscene.env:swarmscene/swap-v0", num_envs=2, vectorization_mode="sync")
    obs, _ = envs.reset(seed=0)
    assert obs.shape == (2, *made.observation_space.shape)
    swarm_env.register_scenario("swarmscene/tiny-v0", ["scenario=swap", "swarm.n=4"], max_episode_steps=3)
    tiny = gym.make("swarmscene/tiny-v0")
    assert tiny.unwrapped.driver.n == 4 and tiny.spec.max_episode_steps == 3


def test_the_flatten_wrapper_gives_a_flat_observation_of_the_same_values():
    import gymnasium as gym

    env = gym.make("swarmscene/swap-v0")
    flat = gym.wrappers.FlattenObservation(gym.make("swarmscene/swap-v0"))
    obs, _ = env.reset(seed=2)
    flat_obs, _ = flat.reset(seed=2)
    assert flat.observation_space.shape == (int(np.prod(env.observation_space.shape)),)
    np.testing.assert_array_equal(flat_obs, obs.reshape(-1))


def test_the_episode_metrics_hold_success_as_a_run_does():
    from swarmscene.env import make_gym_env

    env = make_gym_env(["scenario=swap", "swarm.n=4", "clock.duration=0.3"])
    env.reset(seed=0)
    done, info = False, {}
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        done = terminated or truncated
    metrics = info["metrics"]
    assert metrics["success"] is False  # 0.3 s of zero actions: the swap is not complete
    assert metrics["stop_reason"] == "duration" and "min_separation" in metrics


def test_rgb_array_frames_and_refused_render_modes():
    from swarmscene.env import FRAME_PIXELS, make_env, make_gym_env

    env = make_gym_env(["scenario=swap", "swarm.n=4"], render_mode="rgb_array")
    assert env.render() is None  # before reset: nothing to draw
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (FRAME_PIXELS[1], FRAME_PIXELS[0], 3) and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 2  # axes, agents: not a blank picture
    assert make_gym_env(["scenario=swap", "swarm.n=4"]).render() is None  # no render_mode: no frame
    with pytest.raises(ValueError, match=r"render_mode: must be one of rgb_array, human or None \(got 'video'\)"):
        make_env(["scenario=swap", "swarm.n=4"], render_mode="video")
