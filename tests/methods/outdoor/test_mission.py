"""The thesis' mission workflow as a method (section 4.3.1-4.3.2, eq. 4.1-4.2): the swarm map's hops,
delays and expiry, the leader's catch-up rule, and the workflow's parameters beside the plugin's."""

from __future__ import annotations

import dataclasses

import networkx as nx
import numpy as np
import pytest

from swarmscene.core.setpoint import Setpoints
from swarmscene.core.state import WorldState
from swarmscene.methods.outdoor.mission import LeaderLogic, Task, WorkflowParameters
from swarmscene.methods.outdoor.swarm_map import SwarmMap, hop_matrix
from swarmscene.plugins.formation.outdoor_mission import OutdoorMission

T_MSG, TAU = 2.0, 0.2


# -- swarm map ---------------------------------------------------------------------------------


def test_hop_matrix_equals_networkx_hop_distances_over_the_comm_graph():
    rng = np.random.default_rng(3)
    pos = np.c_[rng.uniform(0, 60, (40, 2)), np.zeros(40)]
    members = rng.random(40) > 0.1
    hops = hop_matrix(pos, members, 12.0)
    graph = nx.Graph()
    graph.add_nodes_from(np.flatnonzero(members).tolist())
    idx = np.flatnonzero(members)
    for a in idx:
        for b in idx:
            if a < b and np.linalg.norm(pos[a] - pos[b]) <= 12.0:
                graph.add_edge(int(a), int(b))
    lengths = dict(nx.all_pairs_shortest_path_length(graph))
    for a in range(40):
        for b in range(40):
            expected = 0 if a == b else lengths.get(a, {}).get(b, np.inf)
            assert hops[a, b] == expected


def test_delay_is_hops_times_tau_com():
    # A chain 0-1-2-3, 10 m apart, range 12 m: agent 0 hears agent 3 three hops (0.6 s) late.
    n, T_s = 4, 0.1
    pos = np.c_[np.arange(n) * 10.0, np.zeros((n, 2))]
    smap = SwarmMap(n, T_s, TAU, T_MSG, self_hops=0)
    hops = hop_matrix(pos, np.ones(n, dtype=bool), 12.0)
    for k in range(15):
        stamp_pos = pos.copy()
        stamp_pos[:, 2] = k  # the message carries its tick in z
        smap.broadcast(k, np.ones(n, dtype=bool), np.full(n, Task.FLOW), stamp_pos,
                       np.zeros((n, 3)), np.zeros((n, 3)))
        smap.deliver(hops)
    np.testing.assert_allclose(smap.age(), hops * TAU, atol=1e-12)
    np.testing.assert_array_equal(smap.pos[..., 2], 14 - np.rint(hops * TAU / T_s))
    assert smap.present.all()


def test_entries_expire_after_T_msg():
    n, T_s = 3, 0.1
    smap = SwarmMap(n, T_s, TAU, T_MSG)
    hops = hop_matrix(np.zeros((n, 3)) + np.arange(n)[:, None], np.ones(n, dtype=bool), 50.0)
    sending = np.ones(n, dtype=bool)
    last_sent = 10
    for k in range(60):
        sending[2] = k <= last_sent  # agent 2 goes silent after tick 10
        smap.broadcast(k, sending, np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)))
        present = smap.deliver(hops)
        age_ticks = k - last_sent
        # the newest message of agent 2 (tick 10) is held until it is T_msg old, then removed
        if 2 <= age_ticks <= round(T_MSG / T_s):
            assert present[0, 2] and present[1, 2]
        elif age_ticks > round(T_MSG / T_s):
            assert not present[0, 2] and not present[1, 2]
        assert present[0, 1] or k < 2


def test_catch_up_eq_4_1_waits_T_del_then_ignores_the_lagging_follower():
    # Leader 0 on its path, followers 1-3 in FLOW; the maps are instantaneous here (0 hops).
    n, T_s, T_del, th = 4, 0.1, 5.0, 2.0
    params = WorkflowParameters(waypoints=((0.0, 100.0, 0.0),), T_del=T_del)
    lead = LeaderLogic(np.zeros(3), np.array([[0.0, 100.0, 0.0]]), params, th, n, 0, T_s)
    smap = SwarmMap(n, T_s, TAU, T_MSG, self_hops=0)
    offsets = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [-5.0, 0.0, 0.0], [0.0, 5.0, 0.0]])
    world = WorldState.at_rest(offsets, leader=0)
    task = np.array([Task.LEAD, Task.FLOW, Task.FLOW, Task.FLOW], dtype=np.int8)
    lag = np.zeros((n, 3))

    def tick(k):
        world.t = k * T_s
        smap.broadcast(k, np.ones(n, dtype=bool), task, world.pos + lag, world.vel, world.vel)
        present = smap.deliver(np.zeros((n, n)))
        lead.update(world, present, smap, task, Setpoints.hold(world.pos))

    for k in range(3):
        tick(k)
    assert lead.phase == "path" and not lead.waiting
    lag[3] = [0.0, -7.5, 0.0]  # follower 3 falls 7.5 m behind: the barycentre drifts 2.5 m
    tick(3)
    np.testing.assert_allclose(lead.delta, [0.0, -2.5 / 2, 0.0])  # eq. 4.1: half the drift
    assert not lead.waiting
    tick(4)
    np.testing.assert_allclose(lead.delta, [0.0, -2.5 * 3 / 4, 0.0])
    k = 5
    while not lead.waiting:
        tick(k)
        k += 1
    t_wait = world.t
    assert np.linalg.norm(lead.delta) >= th
    while not lead.ignored.any():
        tick(k)
        k += 1
    assert world.t == pytest.approx(t_wait + T_del)
    assert np.flatnonzero(lead.ignored).tolist() == [3]  # only the lagging one
    tick(k)
    assert not lead.waiting  # W = {1, 2}: caught up


def test_workflow_parameters_are_the_plugin_options_with_the_same_defaults():
    # the adapter passes every option through (WorkflowParameters(**params.model_dump())): a new
    # option on one side only, or a default that drifts, would fail here rather than at run time
    fields = {f.name: f.default for f in dataclasses.fields(WorkflowParameters)}
    options = OutdoorMission.Params()
    assert set(fields) == set(OutdoorMission.Params.model_fields)
    for name, default in fields.items():
        value = getattr(options, name)
        assert (tuple(map(tuple, value)) if name == "waypoints" else value) == default, name
