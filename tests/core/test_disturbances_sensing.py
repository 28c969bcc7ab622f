"""Sensing noise: the statistics of what the plugins receive, and monitors that judge the truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from swarmscene import api
from swarmscene.core.setpoint import Setpoints

N = 100


def probed(data: dict, noise: dict, ticks: int = 400, n: int = N, spacing: float = 3.0):
    """A grid of ``n`` single integrators holding their start; returns the run and, per tick, the
    positions/velocities the formation received and the true ones at that moment."""
    data["swarm"] = {"n": n, "leader": None, "start": {"layout": "grid", "spacing": spacing, "center": [0, 0, 5]}}
    data["environment"] = {"name": "open", "obstacles": []}
    data["clock"].update(duration=ticks * 0.1, guidance_period=0.1, physics_step=0.1)
    data["avoidance"] = {"name": "none"}
    data["dynamics"] = {"name": "single_integrator"}
    data["formation"] = {"name": "static_shape", "waypoints": [[0.0, 0.0, 5.0]]}
    data["termination"]["on_complete"] = False
    data["disturbances"] = {"noise": {"name": "sensing_noise", **noise}}
    sim = api.build(data)
    target = sim.world.pos.copy()
    seen, truth = [], []

    def setpoints(world, sensing):
        seen.append((world.pos.copy(), world.vel.copy()))
        truth.append((sim.world.pos.copy(), sim.world.vel.copy()))
        return Setpoints.hold(target)

    sim.formation.setpoints = setpoints
    result = sim.run()
    pos_err = np.array([s[0] - t[0] for s, t in zip(seen, truth, strict=True)])  # (ticks, N, 3)
    vel_err = np.array([s[1] - t[1] for s, t in zip(seen, truth, strict=True)])
    return sim, result, pos_err, vel_err, np.array([s[0] for s in seen])


def test_white_noise_has_the_declared_standard_deviations(data):
    _, _, pos_err, vel_err, _ = probed(data, {"pos_std": [0.3, 0.2, 0.1], "vel_std": [0.05, 0.1, 0.0]})
    # 40,000 samples per axis: the sample std is within ~0.4 % (1 sigma) of the true one
    np.testing.assert_allclose(pos_err.reshape(-1, 3).std(axis=0), [0.3, 0.2, 0.1], rtol=0.02)
    np.testing.assert_allclose(pos_err.reshape(-1, 3).mean(axis=0), 0.0, atol=0.005)
    np.testing.assert_allclose(vel_err.reshape(-1, 3).std(axis=0), [0.05, 0.1, 0.0], rtol=0.02, atol=1e-12)
    lag1 = np.mean(pos_err[1:, :, 0] * pos_err[:-1, :, 0]) / np.mean(pos_err[:, :, 0] ** 2)
    assert abs(lag1) < 0.02  # white: independent from tick to tick


def test_gauss_markov_error_has_the_declared_correlation(data):
    tau = 1.0
    _, _, pos_err, _, _ = probed(data, {"pos_std": [0.2, 0.2, 0.2], "vel_std": [0, 0, 0], "correlation_time": tau})
    a = np.exp(-0.1 / tau)
    e = pos_err[:, :, :2]
    lag1 = np.mean(e[1:] * e[:-1]) / np.mean(e * e)
    assert lag1 == pytest.approx(a, abs=0.01)
    # stationary from the start: std 0.2 (fewer independent samples: 200 agent-axes x 40 tau)
    assert e.std() == pytest.approx(0.2, rel=0.04)


def test_bias_is_constant_per_agent_with_the_declared_spread(data):
    _, _, pos_err, _, _ = probed(data, {"pos_std": [0.01, 0.01, 0.01], "vel_std": [0, 0, 0],
                                        "pos_bias_std": [0.5, 0.5, 0.0]}, ticks=50)
    per_agent = pos_err.mean(axis=0)  # (N, 3): the bias plus noise averaged over 50 ticks
    np.testing.assert_allclose(pos_err.std(axis=0)[:, :2], 0.01, rtol=0.35)  # constant in time
    # 200 draws: the spread's standard error is ~5 %
    assert per_agent[:, :2].std() == pytest.approx(0.5, rel=0.15)
    assert np.abs(per_agent[:, 2]).max() < 0.01


def test_dropout_keeps_the_last_estimate_at_the_declared_rate(data):
    _, result, pos_err, _, seen = probed(data, {"pos_std": [0.1, 0.1, 0.1], "dropout": 0.25})
    unchanged = np.all(seen[1:] == seen[:-1], axis=2)  # white noise never repeats a value
    assert unchanged.mean() == pytest.approx(0.25, abs=0.01)
    assert result.metrics["disturbances.noise.dropout_rate"] == pytest.approx(0.25, abs=0.01)


def test_monitors_judge_the_true_state(data):
    """Agents 1 m apart under 0.6 m noise: the plugins see pairs far closer than they are; the
    monitor's minimum separation is the one of the recorded (true) trajectory, exactly."""
    sim, result, pos_err, _, seen = probed(data, {"pos_std": [0.6, 0.6, 0.6]}, ticks=60, n=16, spacing=1.0)
    traj = result.trajectory["pos"]
    truth_min = min(pdist(frame).min() for frame in traj)
    seen_min = min(pdist(frame).min() for frame in seen)
    assert result.metrics["min_separation"] == truth_min
    assert seen_min < 0.5 * truth_min
    assert result.metrics["disturbances.sense.pos_error_rms"] == pytest.approx(0.6 * np.sqrt(3), rel=0.05)
    # the holding single integrator moves on its noisy estimate: the truth wanders, the record has it
    assert np.abs(traj[-1] - traj[0]).max() > 0.05
