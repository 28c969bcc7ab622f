"""Actions turned into setpoints (methods/policy/actions.py)."""

from __future__ import annotations

import numpy as np

from swarmscene.core.setpoint import Mode
from swarmscene.core.state import WorldState
from swarmscene.methods.policy.actions import ActionSpec, action_setpoints


def test_actions_are_clipped_and_a_nan_commands_nothing_as_nan_to_num_then_clip():
    """Every special value gives the bits of ``clip(nan_to_num(a), -1, 1)``: NaN 0, +-inf +-1,
    -0.0 kept; inactive and failed agents hold."""
    rng = np.random.default_rng(4)
    special = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1.0 + 1e-16, -3.0, 5e-324, 0.999999])
    world = WorldState.at_rest(rng.normal(size=(12, 3)))
    world.vel[:] = rng.normal(size=(12, 3))
    world.healthy[3] = False
    active = np.ones(12, dtype=bool)
    active[5] = False
    drawn = 0
    for command in ("velocity", "acceleration"):
        spec = ActionSpec(command, max_speed=2.0, max_accel=3.0, guidance_period=0.1)
        for _ in range(20):
            action = rng.choice(special, size=(12, 3))
            sp = action_setpoints(world, action, active, spec)
            a = np.clip(np.nan_to_num(action), -1.0, 1.0)
            go = active & world.healthy
            scale = spec.max_speed if command == "velocity" else spec.max_accel
            want = a[go] * scale if command == "velocity" else world.vel[go] + spec.guidance_period * (a[go] * scale)
            assert sp.vel[go].tobytes() == want.tobytes()
            want_acc = np.zeros_like(sp.acc) if command == "velocity" else a * scale
            assert sp.acc[go].tobytes() == want_acc[go].tobytes() and not sp.acc[~go].any()
            assert (sp.mode == np.where(go, int(Mode.VELOCITY), int(Mode.HOLD))).all()
            assert not sp.vel[~go].any() and (sp.pos == world.pos).all()
            drawn += int(np.isnan(action[go]).any() and np.isinf(action[go]).any())
    assert drawn > 30  # NaN and infinities among the actions that fly
