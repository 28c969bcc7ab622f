"""``seek_reference``: a scripted policy flying each agent to the formation's reference, pushed off
close neighbours and obstacles (numerics: :func:`swarmscene.methods.policy.policies.seek_reference_actions`).

A demonstration of the policy mechanism, not a safe method (docs/rl.md).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.methods.policy.policies import seek_reference_actions
from swarmscene.plugin import PluginParams, Policy, hookimpl


class SeekReference(Policy):
    """Fly to the formation's reference, pushed off close neighbours and obstacles."""

    name = "seek_reference"

    class Params(PluginParams):
        gain: float = Field(1.0, ge=0, description="k_p: pull onto the reference position, 1/s")
        repulsion: float = Field(2.0, ge=0, description="k_r: push off neighbours and obstacles, m/s")
        radius: float = Field(1.0, gt=0, description="r: distance under which it pushes off, m")

    params: Params

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The actions that fly each agent at its formation reference, gain k, pushed off neighbours
        and obstacles closer than ``radius``."""
        p = self.params
        return seek_reference_actions(self.layout, self.spec, obs, p.gain, p.repulsion, p.radius)


@hookimpl
def swarmscene_register_policies(register):
    """Add :class:`SeekReference` to the registry, so that ``avoidance.policy: seek_reference`` chooses it."""
    register(SeekReference)
