"""Template of a disturbance model: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), add ``disturbances/<name>.yaml`` holding
``<name>: {name: <name>}`` (the key is the model's name in errors and metrics), choose it with
``swarmscene disturbances=[<name>]``, and check it with
``swarmscene.testing.check_disturbance(MyDisturbance)`` in your tests.
Cite the paper or datasheet behind each number here.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from swarmscene.plugin import Disturbance, DisturbanceParams, hookimpl


class MyDisturbance(Disturbance):
    """A biased, noisy position estimate: p_hat = p + b + e, e ~ N(0, sigma^2) each tick."""

    name = "my_disturbance"
    # sense: each agent's estimate of itself; communicate: what the others receive of it;
    # wind: the air's velocity at each agent, each physics step (method air(world, t) -> (N, 3));
    # force: any other force per mass, each physics step (method force(world, t) -> (N, 3), m/s^2).
    # A wind model may add the classmethod air_batch(models, worlds, t), the air of B worlds at
    # once (docs/batched.md; plugins/disturbance/dryden.py is an example).
    # The built-ins (plugins/disturbance/*.py) are worked examples of each phase.
    phase = "sense"

    class Params(DisturbanceParams):
        bias: tuple[float, float, float] = Field((0.0, 0.0, 0.5), description="b: constant offset [x, y, z], m")
        std: float = Field(0.1, ge=0, le=100, description="sigma: standard deviation of the noise, m")

    params: Params  # self.params: the validated options, typed as this class's own (for mypy, editors)

    def __init__(self, params, ctx):
        super().__init__(params, ctx)
        self.largest = 0.0  # state on the instance: one model per run

    def sense(self, world, pos, vel):
        """The estimate from the truth (``world``) and the models before it (``pos``, ``vel``):
        return new arrays, never edit them in place."""
        noise = self.rng.normal(0.0, self.params.std, pos.shape)  # the model's own seeded stream
        out = pos + np.asarray(self.params.bias) + noise
        self.largest = max(self.largest, float(np.abs(noise).max(initial=0.0)))
        return out, vel

    def metrics(self):
        return {"largest_noise": self.largest}  # recorded as disturbances.<key>.largest_noise, m


@hookimpl
def swarmscene_register_disturbances(register):
    register(MyDisturbance)
