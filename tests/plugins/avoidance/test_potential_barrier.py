"""potential_barrier: thesis eq. 5.30-5.36 as an avoidance plugin (w_obs + w_col, saturation at u_sat)."""

from __future__ import annotations

import numpy as np
import pytest

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.registry import make_plugin_manager
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.simulation import Simulation
from swarmscene.methods.indoor.control import psi_col, psi_obs

MODULES = (
    "swarmscene.plugins.formation.indoor_swarm",
    "swarmscene.plugins.avoidance.potential_barrier",
)
T_S, U_SAT = 0.01, 0.02


def build(positions: list[list[float]], extra: list[str] = ()) -> Simulation:
    pm, registry = make_plugin_manager(tuple(dict.fromkeys((*BUILTIN_PLUGINS, *MODULES))), False)
    pos = "[" + ",".join(f"[{x},{y},{z}]" for x, y, z in positions) + "]"
    overrides = ["scenario=indoor_corridor", f"swarm.n={len(positions)}", "swarm.start.layout=explicit",
                 f"+swarm.start.positions={pos}", "clock.duration=0.01", *extra]
    return Simulation(api.load(overrides, registry), pm, registry.observers)


def test_terms_are_w_obs_plus_w_col():
    # Agent 1 is 0.2 m below the corridor's upper wall (y = 0.4) and 0.5 m from agent 2.
    sim = build([[-3.0, 0.0, 1.0], [3.0, 0.2, 1.0], [3.0, -0.3, 1.0]])
    w = sim.avoidance.terms(sim.sensing)
    np.testing.assert_allclose(w[1], [0.0, psi_obs(0.2) - psi_col(0.5)], atol=1e-12)
    np.testing.assert_allclose(w[2], [0.0, psi_col(0.5) - psi_obs(0.1)], atol=1e-12)
    assert w[1, 1] < 0 and w[2, 1] > 0  # pushed away from the walls and from each other


def test_followers_saturate_at_u_sat_leader_exempt():
    sim = build([[-3.0, 0.0, 1.0], [3.0, 0.2, 1.0], [3.0, -0.3, 1.0], [-1.0, 2.0, 1.0]])
    sp = Setpoints.hold(sim.world.pos)
    sp.mode[:] = Mode.VELOCITY
    sp.vel[:] = [0.5, 0.0, 0.0]
    sp.vel[0] = [50.0, 0.0, 0.0]  # the leader's command is its own business
    out = sim.avoidance.adjust(sim.world, sim.sensing, sp)
    np.testing.assert_allclose(out.vel[0], [50.0, 0.0, 0.0])
    np.testing.assert_allclose(np.linalg.norm(out.vel[1:3, :2], axis=1), U_SAT / T_S)  # saturated
    np.testing.assert_allclose(out.vel[3], [0.5, 0.0, 0.0])  # nothing near agent 3
    np.testing.assert_array_equal(sp.vel[1], [0.5, 0.0, 0.0])  # the input is not modified


def test_leader_included_when_not_exempt():
    sim = build([[3.0, 0.2, 1.0], [-3.0, 0.0, 1.0]], ["avoidance.exempt_leader=false"])
    sp = Setpoints.hold(sim.world.pos)
    sp.mode[:] = Mode.VELOCITY
    out = sim.avoidance.adjust(sim.world, sim.sensing, sp)
    assert out.vel[0, 1] == pytest.approx(-U_SAT / T_S)  # psi_obs(0.2) saturates at u_sat


def test_position_modes_get_feed_forward_and_shifted_reference():
    sim = build([[-3.0, 0.0, 1.0], [3.0, 0.35, 1.0]])
    sp = Setpoints.hold(sim.world.pos)
    sp.mode[:] = Mode.TRACK
    out = sim.avoidance.adjust(sim.world, sim.sensing, sp)
    w = -psi_obs(0.05)  # 0.05 m from the wall: held at K_obs = 200 m per step below d_o
    assert w == pytest.approx(200.0)
    np.testing.assert_allclose(out.pos[1, :2], [3.0, 0.35 - w])
    np.testing.assert_allclose(out.vel[1, :2], [0.0, -w / T_S])


def test_collision_term_needs_line_of_sight_like_the_thesis():
    """w_col sums over N_i(G_sigma) (eq. 5.35), and G_sigma is in G_s, whose edges need the joining
    segment d_l clear of obstacles (eq. 5.8): two agents 0.31 m apart on either side of the
    corridor's entrance corner (0, 0.4) do not sense each other, so they do not repel; past the
    corner, at the same distance, they do."""
    from swarmscene.methods.indoor.control import w_obs
    from swarmscene.methods.indoor.shared import shared_snapshot

    hidden = build([[-3.0, 0.0, 1.0], [-0.12, 0.52, 1.0], [0.1, 0.3, 1.0]])
    snap = shared_snapshot(hidden.sensing, hidden.avoidance.gains)
    assert len(snap.g_n) == 0  # the segment passes 0.014 m from the corner, below d_l = 0.05 m
    w = hidden.avoidance.terms(hidden.sensing)
    np.testing.assert_allclose(w, w_obs(snap.r, snap.o, hidden.avoidance.gains), atol=1e-15)
    seen = build([[-3.0, 0.0, 1.0], [0.5, 0.0, 1.0], [0.72, -0.22, 1.0]])
    snap = shared_snapshot(seen.sensing, seen.avoidance.gains)
    assert snap.g_sigma.edge_set() == {(1, 2)}
    w_pair = seen.avoidance.terms(seen.sensing) - w_obs(snap.r, snap.o, seen.avoidance.gains)
    unit = np.array([0.22, -0.22]) / np.hypot(0.22, 0.22)
    np.testing.assert_allclose(w_pair[1], psi_col(np.hypot(0.22, 0.22)) * unit, atol=1e-12)
    assert w_pair[1] @ unit < 0  # agent 1 is pushed away from agent 2
