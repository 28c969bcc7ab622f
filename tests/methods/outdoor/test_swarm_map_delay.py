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
