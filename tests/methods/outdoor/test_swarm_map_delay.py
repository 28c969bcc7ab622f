"""The swarm map's link delays come from the engine's delay model (thesis section 4.2)."""

import numpy as np

from swarmscene.methods.outdoor.swarm_map import SwarmMap


def test_default_delay_is_the_thesis_hop_ceiling_with_self_hops():
    hops = np.array([[0.0, 1.0, 3.0], [1.0, 0.0, np.inf], [3.0, np.inf, 0.0]])
    m = SwarmMap(3, 0.1, 0.25, 2.0, self_hops=1)
    # ceil(h 0.25 / 0.1): 1 hop -> 3 ticks, 3 hops -> 8; own message 1 hop; unreachable -1
    np.testing.assert_array_equal(m.delay_ticks(hops), [[3, 3, 8], [3, 3, -1], [8, -1, 3]])
    m0 = SwarmMap(3, 0.1, 0.2, 2.0, self_hops=0)
    np.testing.assert_array_equal(np.diag(m0.delay_ticks(hops)), [0, 0, 0])


def test_a_given_link_delay_model_replaces_tau_com():
    seen = []

    def model(hops):
        seen.append(hops.copy())
        return np.where(np.isfinite(hops), 7, -1)

    m = SwarmMap(2, 0.1, 0.2, 2.0, self_hops=2, link_delay=model)
    np.testing.assert_array_equal(m.delay_ticks(np.array([[0.0, np.inf], [np.inf, 0.0]])), [[7, -1], [-1, 7]])
    np.testing.assert_array_equal(seen[0], [[2.0, np.inf], [np.inf, 2.0]])  # own message: self_hops


def test_a_lost_message_leaves_the_entry_as_it_was():
    """deliver(hops, lost): the (receiver, sender) messages lost this tick do not update the map."""
    m = SwarmMap(2, 0.1, 0.1, 2.0, self_hops=0)
    hops = np.array([[0.0, 1.0], [1.0, 0.0]])
    pos = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    zero = np.zeros((2, 3))
    m.broadcast(0, np.ones(2, bool), np.zeros(2, np.int8), pos, zero, zero)
    m.deliver(hops)
    m.broadcast(1, np.ones(2, bool), np.zeros(2, np.int8), pos + 1.0, zero, zero)
    m.deliver(hops)  # the one-hop messages of tick 0 arrive at tick 1: 0 holds 1 at x = 5
    m.broadcast(2, np.ones(2, bool), np.zeros(2, np.int8), pos + 2.0, zero, zero)
    lost = np.array([[False, True], [False, False]])  # 1's message to 0 is lost
    m.deliver(hops, lost)
    assert m.positions(0, 1)[0] == 5.0  # still tick 0's message
    assert m.positions(1, 0)[0] == 1.0  # 0's message of tick 1 arrived at 1
    assert m.positions(0, 0)[0] == 2.0  # own message, no hop
