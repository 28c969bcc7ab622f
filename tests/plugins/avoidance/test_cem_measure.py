"""The ``cem`` plugin's per-tick safety measurements, compiled (kernels.measure_tick), against the
NumPy way they were taken before (tests/oracles/cem.py, numpy_measure).

Three failures one later (so a re-activation), a healthy agent failing mid-run (it leaves the live
set), bounded tracking error (actual differs from commanded): every quantity equal, tick by tick.
"""

from __future__ import annotations

import numpy as np
import pytest
from oracles.cem import numpy_measure

from swarmscene.core.plugin import BuildContext
from swarmscene.core.setpoint import Mode, Setpoints
from swarmscene.core.state import WorldState
from swarmscene.plugins.avoidance.cem import CEM
from swarmscene.plugins.event.hover import Hover

DT = 0.01


@pytest.mark.parametrize("rule", ["printed", "gated"])
def test_compiled_measurements_equal_the_numpy_ones_tick_by_tick(rule):
    xy = np.array([[x, y] for x in (6.0, 0.0, -6.0) for y in (-9.0, -3.0, 3.0, 9.0)])
    world = WorldState.at_rest(np.column_stack([xy, np.full(len(xy), 2.0)]))
    ctx = BuildContext(n=world.n, guidance_period=DT, physics_step=DT, duration=10.0, separation_limit=0.56,
                       clearance_limit=0.0, comm_range=50.0, environment=None, rng=np.random.default_rng(3),
                       initial=world)
    plugin = CEM(CEM.Params(saddle_noise=rule), ctx)
    sim = type("Sim", (), {"world": world})()
    events = {20: (0, 3), 150: (6,), 260: (9,)}  # two, a later third, then a healthy agent fails too
    noise = np.random.default_rng(4)
    checked = 0
    for k in range(600):
        for agent in events.get(k, ()):
            ev = Hover.event(k * DT, (agent,))
            ev.apply(world)
            plugin.swarmscene_event(sim=sim, event=ev)
        sp = Setpoints.hold(world.pos)
        sp.mode[world.healthy] = Mode.TRACK
        sp.vel[world.healthy, 0] = 1.0
        sp.pos[world.healthy, 0] += DT
        out = plugin.adjust(world, None, sp)
        live = world.healthy.copy()
        world.pos[live] = out.pos[live] + np.column_stack([noise.uniform(-0.2, 0.2, (live.sum(), 2)),
                                                           np.zeros(live.sum())])
        world.vel[live] = out.vel[live] * noise.uniform(0.9, 1.1, (live.sum(), 1))
        if k == 300:  # an agent under CEM fails between the command and the measurement
            Hover.event(k * DT, (10,)).apply(world)
        if not plugin.mode._commanded:
            plugin.swarmscene_step_end(sim=sim)
            continue
        drift = plugin.mode.record.psi_drift.copy()  # the kernel raises it in place
        ref = numpy_measure(plugin.mode.nav, plugin.mode.healthy_idx, world.healthy, world.pos, world.vel,
                            np.array(list(plugin.mode.failed.values())))
        got = np.empty(plugin.mode._k.N_MEAS)
        live_n = plugin.mode.nav.measure_tick(world.healthy, world.pos, world.vel, plugin.mode._failed_xy, drift, got)
        expected_drift = plugin.mode.record.psi_drift.copy()
        np.maximum.at(expected_drift, plugin.mode.healthy_idx, ref["drift"])
        np.testing.assert_array_equal(drift, expected_drift)
        k_ = plugin.mode._k
        assert got[k_.M_MARGIN] == ref["margin"] and got[k_.M_SPEED] == ref["speed"]
        assert got[k_.M_CLEAR] == ref["clear"]
        assert (got[k_.M_PAIR], got[k_.M_PAIR_CMD]) == (ref["pair"], ref["pair_cmd"])
        assert live_n == int(world.healthy[plugin.mode.healthy_idx].sum())
        if live_n:
            assert (got[k_.M_SPEED_ACT], got[k_.M_TRACK_ERR]) == (ref["speed_act"], ref["track_err"])
        plugin.swarmscene_step_end(sim=sim)
        checked += 1
    assert checked > 500 and plugin.metrics()["cem.activations"] == 4
