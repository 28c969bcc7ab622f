"""Communication models against their analytic laws: delay distributions, loss rates, burst lengths,
and the broadcast channel's picture (exact ages, held rows)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.core.setpoint import Setpoints
from swarmscene.methods.disturbances import links

# -- numerics ----------------------------------------------------------------------------------


def test_hop_delays_are_the_thesis_ceiling():
    hops = np.array([[0, 1, 2, np.inf], [1, 0, 1, np.inf]])
    np.testing.assert_array_equal(links.hop_delay_ticks(hops, 0.2, 0.1), [[0, 2, 4, -1], [2, 0, 2, -1]])
    # tau_com = 0.25 s at T_s = 0.1 s: ceil(2.5) = 3 ticks per hop, ceil(5.0) = 5 for two
    np.testing.assert_array_equal(links.hop_delay_ticks(np.array([1.0, 2.0]), 0.25, 0.1), [3, 5])


@pytest.mark.parametrize("seed", range(3))
def test_hop_counts_are_scipys_shortest_paths(seed):
    """300 random graphs of 1-90 agents (the dense search up to 64, scipy's beyond), sparse and
    dense, connected and split: the hops equal scipy's unweighted ``shortest_path``, inf and all."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import shortest_path

    rng = np.random.default_rng(seed)
    for _ in range(300):
        n = int(rng.integers(1, 91))
        i, j = np.triu_indices(n, 1)
        keep = rng.random(i.size) < rng.uniform(0.0, 0.3)
        edges = np.column_stack([i[keep], j[keep]])
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
        want = shortest_path((graph + graph.T).tocsr(), unweighted=True)
        assert np.array_equal(links.hop_counts(edges, n), want), (n, len(edges))


def test_random_delays_follow_their_distribution():
    rng = np.random.default_rng(3)
    d = links.random_delay_ticks(rng, 400_000, 0.15, 0.2, 0.1)
    k = np.arange(0, 15)
    empirical = np.array([(d <= kk).mean() for kk in k])
    # Kolmogorov-Smirnov: 400,000 samples, the empirical CDF is within 1.63 / sqrt(n) = 0.0026 of
    # the true one with 99 % probability
    np.testing.assert_allclose(empirical, links.random_delay_cdf(k, 0.15, 0.2, 0.1), atol=0.0026)
    assert d.min() == 2  # ceil(0.15 / 0.1): no message is faster than the latency


def test_gilbert_elliott_loss_rate_and_burst_lengths():
    rng = np.random.default_rng(5)
    ge = links.GilbertElliott(2000, rng, p_gb=0.05, p_bg=0.25, loss_good=0.0, loss_bad=1.0)
    lost = np.array([ge.step() for _ in range(1000)])  # (ticks, channels)
    assert ge.loss_rate == pytest.approx(0.05 / 0.30)
    assert lost.mean() == pytest.approx(0.05 / 0.30, rel=0.02)
    # bursts: runs of losses, geometric with mean 1 / p_bg = 4 ticks (interior runs only)
    runs = []
    for column in lost.T:
        edges = np.flatnonzero(np.diff(np.r_[0, column.astype(int), 0]))
        starts, ends = edges[::2], edges[1::2]
        keep = (starts > 0) & (ends < len(column))
        runs.append(ends[keep] - starts[keep])
    runs = np.concatenate(runs)
    assert runs.mean() == pytest.approx(4.0, rel=0.02)
    for k in (1, 2, 3, 6):
        assert (runs == k).mean() == pytest.approx(0.75 ** (k - 1) * 0.25, abs=0.005)


def test_gilbert_elliott_with_partial_losses():
    rng = np.random.default_rng(6)
    ge = links.GilbertElliott(4000, rng, p_gb=0.1, p_bg=0.3, loss_good=0.02, loss_bad=0.6)
    lost = np.array([ge.step() for _ in range(500)])
    assert lost.mean() == pytest.approx(0.75 * 0.02 + 0.25 * 0.6, rel=0.02)


def test_range_loss_law():
    p = links.range_loss_probability(np.array([0.0, 5.0, 7.5, 10.0, 12.0]), 0.1, 5.0, 10.0)
    np.testing.assert_allclose(p, [0.1, 0.1, 0.55, 1.0, 1.0])


# -- through the kernel -----------------------------------------------------------------------


def moving(data: dict, disturbances: dict, ticks: int = 120, n: int = 9):
    """A grid flying 20 m east on single integrators; per tick, the picture the formation received
    and the true positions then."""
    data["swarm"] = {"n": n, "leader": None, "start": {"layout": "grid", "spacing": 3.0, "center": [0, 0, 5]}}
    data["environment"] = {"name": "open", "obstacles": []}
    data["clock"].update(duration=ticks * 0.1, guidance_period=0.1, physics_step=0.1)
    data["avoidance"] = {"name": "none"}
    data["dynamics"] = {"name": "single_integrator", "u_max": 1.0}
    data["formation"] = {"name": "static_shape", "waypoints": [[0.0, 0.0, 5.0]]}
    data["termination"]["on_complete"] = False
    data["comm"] = {"range": 4.0}
    data["disturbances"] = disturbances
    sim = api.build(data)
    target = sim.world.pos + np.array([20.0, 0.0, 0.0])
    seen, truth = [], []

    def setpoints(world, sensing):
        seen.append(world.pos.copy())
        truth.append(sim.world.pos.copy())
        return Setpoints.hold(target)

    sim.formation.setpoints = setpoints
    result = sim.run()
    return sim, result, np.array(seen), np.array(truth)


def test_fixed_delay_shows_the_estimate_of_d_ticks_before(data):
    _, result, seen, truth = moving(data, {"comm_delay": {"model": "fixed", "tau": 0.3}})
    np.testing.assert_array_equal(seen[3:], truth[:-3])
    np.testing.assert_array_equal(seen[:3], np.repeat(truth[:1], 3, axis=0))  # known start
    assert result.metrics["disturbances.comm.loss_rate"] == 0.0


def test_bernoulli_losses_hold_the_last_row_at_rate_p(data):
    _, result, seen, truth = moving(data, {"packet_loss": {"p": 0.3}}, ticks=400, n=25)
    held = np.all(seen[1:] == seen[:-1], axis=2)  # the agents move every tick: a repeat is a loss
    fresh = np.all(seen == truth, axis=2)
    assert held.mean() == pytest.approx(0.3, abs=0.015)
    assert fresh.mean() == pytest.approx(0.7, abs=0.015)
    assert result.metrics["disturbances.comm.loss_rate"] == pytest.approx(0.3, abs=0.015)


def test_hop_delay_in_the_picture_is_the_mean_over_receivers(data):
    """A line of 4 agents 3 m apart, comm range 4 m: hops from agent 0 are 1, 2, 3 -> 2, 4, 6 ticks
    at tau_com = 0.2 s, mean 4; from agent 1: 1, 1, 2 -> 2, 2, 4, mean 8/3 -> 3 ticks."""
    data["swarm"] = {"n": 4, "leader": None, "start": {"layout": "line", "spacing": 3.0, "center": [0, 0, 5]}}
    data["comm"] = {"range": 4.0}
    data["disturbances"] = {"comm_delay": {"model": "hops", "tau": 0.2}}
    data["avoidance"] = {"name": "none"}
    data["dynamics"] = {"name": "single_integrator"}
    data["formation"] = {"name": "static_shape", "waypoints": [[0.0, 0.0, 5.0]]}
    sim = api.build(data)
    model = sim.disturbances.models["comm_delay"]
    np.testing.assert_array_equal(model.delays(sim.world, sim.sensing), [4, 3, 3, 4])


# -- the thesis' outdoor mission flies the engine's delay model ---------------------------------


def _outdoor(*overrides):
    result = api.run(["scenario=outdoor_square", "output.summary=false", *overrides])
    metrics = {k: v for k, v in result.metrics.items()
               if k not in {"wall_time", "realtime_factor", "step_ms_median"} and "_ms" not in k
               and "seconds" not in k and not k.startswith("disturbances.")}
    return result.trajectory["pos"], metrics


@pytest.mark.parametrize("tau", [0.2, 0.5])
def test_outdoor_mission_delays_are_the_declared_comm_delay(tau):
    """A declared hop-proportional comm_delay replaces the plugin's own tau_com: the run equals,
    bit for bit, the one whose plugin option says the same (the swarm map takes the engine's
    model either way; the preset's avoidance is none, so the shared picture is not read)."""
    pos_a, m_a = _outdoor("disturbances=[comm_delay]", f"disturbances.comm_delay.tau={tau}",
                          "formation.tau_com=0.05")
    pos_b, m_b = _outdoor(f"formation.tau_com={tau}")
    assert np.array_equal(pos_a, pos_b)
    assert m_a == m_b
    if tau != 0.2:  # and it matters: the default tau_com gives another run
        pos_c, _ = _outdoor()
        assert not np.array_equal(pos_a, pos_c)


def test_a_channel_too_large_for_memory_is_refused(data):
    data["clock"]["guidance_period"] = 0.0001
    data["clock"]["physics_step"] = 0.0001
    data["disturbances"] = {"comm_delay": {"model": "fixed", "tau": 60.0}}
    data["swarm"]["n"] = 1000
    data["swarm"]["start"] = {"layout": "grid", "spacing": 2.0}
    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError) as exc:
        api.load(data)
    assert exc.value.lines == [
        "disturbances.comm_delay.tau: the channel would keep 600001 ticks of 1000 agents' messages "
        "(31.3 GiB, at most 1); shorten the delay or lengthen clock.guidance_period (got 60.0)"]


def test_outdoor_mission_maps_lose_the_declared_messages():
    """packet_loss reaches the swarm maps per link and tick: at p = 0 the run is the one without
    it (the draws come from the model's own stream), at p = 0.3 the realised rate is 0.3."""
    pos_a, m_a = _outdoor()
    pos_b, m_b = _outdoor("disturbances=[packet_loss]", "disturbances.packet_loss.p=0")
    assert np.array_equal(pos_a, pos_b) and m_a == m_b
    result = api.run(["scenario=outdoor_square", "output.summary=false", "disturbances=[packet_loss]",
                      "disturbances.packet_loss.p=0.3"])
    assert result.metrics["disturbances.comm.link_loss_rate"] == pytest.approx(0.3, abs=0.005)
    assert not np.array_equal(result.trajectory["pos"][: len(pos_a)], pos_a[: len(result.trajectory["pos"])])
