"""Template of a policy: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), fly it with
``swarmscene avoidance=policy avoidance.policy=my_policy`` (options: ``avoidance.policy_options.gain=2``),
and check it with ``swarmscene.testing.check_policy(MyPolicy)`` in your tests. A trained network
loads its weights in ``__init__`` (a path among its Params) and runs them in ``__call__``.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.plugin import PluginParams, Policy, hookimpl


class MyPolicy(Policy):
    """Fly straight at the formation's reference, at a speed proportional to the distance."""

    name = "my_policy"

    class Params(PluginParams):
        gain: float = Field(1.0, gt=0, description="k: commanded speed per metre of offset, 1/s")

    params: Params  # self.params: the validated options, typed as this class's own (for mypy, editors)

    def __call__(self, obs):
        """Actions (N, 3) in [-1, 1] from the observations (N, D): ``self.layout.split`` names the
        columns (own state, neighbours, nearest obstacle, reference); ``self.spec`` says whether an
        action is a velocity or an acceleration and its scale."""
        f = self.layout.split(np.asarray(obs, dtype=float))
        desired = self.params.gain * f["ref_offset"] * f["ref_mask"]  # m/s
        if self.spec.command == "velocity":
            action = desired / self.spec.max_speed
        else:
            action = (desired - f["own_vel"]) / (self.spec.guidance_period * self.spec.max_accel)
        return np.clip(action, -1.0, 1.0)


@hookimpl
def swarmscene_register_policies(register):
    register(MyPolicy)
