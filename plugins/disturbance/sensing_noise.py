"""The ``sensing_noise`` disturbance model: each agent's estimate of its own position and velocity.

    p_hat = p + b + e_p,   v_hat = v + e_v                    (per agent, per guidance tick)

b is a constant bias drawn per agent at the start (N(0, pos_bias_std^2) per axis); e_p a
first-order Gauss-Markov error of standard deviation ``pos_std`` and correlation time
``correlation_time`` (0: white), e_p(k+1) = a e_p(k) + sqrt(1 - a^2) pos_std xi, a = exp(-T_s / tau)
(:mod:`swarmscene.methods.disturbances.noise`); e_v white with ``vel_std``. With probability
``dropout`` an agent's measurement is lost at a tick and its estimate keeps the last one (the
velocity estimate included).

What the plugins read as ``world.pos`` / ``world.vel`` is this estimate (through the communicate
phase for the others' rows); the monitors, the events' hold and the plant read the truth.

Presets (``scenarios/disturbances``): ``gps`` (u-blox NEO-M8 data sheet, UBX-15031086: 2.5 m CEP
horizontal -> sigma = 2.5 / 1.1774 = 2.12 m per horizontal axis; vertical taken as twice that (a
typical VDOP / HDOP ratio, an assumption); 0.05 m/s velocity accuracy; the error's correlation time
taken as 60 s, an assumption: GNSS position error drifts over minutes rather than jumping each
fix) and ``mocap`` (Merriaux et al. 2017, "A study of Vicon system positioning performance",
Sensors 17(7) 1591: errors below 2 mm in a 30 m^3 volume -> sigma = 1 mm white; velocity from
differentiated positions at 100 Hz, sigma ~ sqrt(2) 1 mm / 10 ms = 0.14 m/s, 0.1 m/s taken).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.methods.disturbances import noise
from swarmscene.plugin import (
    MAX_DURATION,
    Disturbance,
    DisturbanceContext,
    DisturbanceParams,
    WorldState,
    hookimpl,
    key_error,
)


class SensingNoiseParams(DisturbanceParams):
    """``name: sensing_noise``: the errors' standard deviations, correlation time and dropouts."""

    pos_std: tuple[float, float, float] = Field(
        (0.05, 0.05, 0.05), description="standard deviation of the position error per axis "
        "(x, y, z), m")
    vel_std: tuple[float, float, float] = Field(
        (0.02, 0.02, 0.02), description="standard deviation of the velocity error per axis, m/s")
    pos_bias_std: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="standard deviation of each agent's constant position bias "
        "per axis, m (drawn once at the start)")
    correlation_time: float = Field(
        0.0, ge=0.0, le=MAX_DURATION, description="correlation time tau of the position error, s "
        "(0: white, a new error each tick)")
    dropout: float = Field(
        0.0, ge=0.0, le=1.0, description="probability that an agent's measurement is lost at a "
        "tick (its estimate then keeps the last one)")

    def model_post_init(self, _: Any) -> None:
        """Each component of the three per-axis standard deviations lies in [0, 1000] m (or m/s)."""
        for key in ("pos_std", "vel_std", "pos_bias_std"):
            values = getattr(self, key)
            if not all(0.0 <= v <= 1e3 for v in values):
                raise key_error(key, "each must be in [0, 1000]", list(values))


class SensingNoise(Disturbance):
    """Truth + bias + Gauss-Markov position error, white velocity error, dropouts."""

    name = "sensing_noise"
    phase = "sense"
    Params = SensingNoiseParams

    params: SensingNoiseParams

    def __init__(self, params: SensingNoiseParams, ctx: DisturbanceContext) -> None:
        super().__init__(params, ctx)
        n = ctx.n
        self.pos_std = np.array(params.pos_std)
        self.vel_std = np.array(params.vel_std)
        self.bias = self.rng.standard_normal((n, 3)) * np.array(params.pos_bias_std)
        self.a = noise.correlation(ctx.guidance_period, params.correlation_time)
        self.error = self.rng.standard_normal((n, 3)) * self.pos_std  # stationary start
        self.last: tuple[np.ndarray, np.ndarray] | None = None
        self.lost = 0
        self.samples = 0

    def sense(self, world: WorldState, pos: np.ndarray, vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The estimate: bias + first-order Gauss-Markov position error, white velocity noise; a lost
        measurement (``dropout``) keeps the agent's previous estimate."""
        n = world.n
        rng = self.rng
        self.error = noise.gauss_markov_step(self.error, self.a, self.pos_std, rng)
        pos = pos + self.bias + self.error
        vel = vel + self.vel_std * rng.standard_normal((n, 3))
        if self.params.dropout > 0.0:
            lost = rng.random(n) < self.params.dropout
            if self.last is not None:
                pos = np.where(lost[:, None], self.last[0], pos)
                vel = np.where(lost[:, None], self.last[1], vel)
            self.lost += int(lost.sum())
            self.last = (pos, vel)
        self.samples += n
        return pos, vel

    def metrics(self) -> dict[str, Any]:
        """The fraction of measurements lost to ``dropout`` over the run."""
        return {"dropout_rate": self.lost / self.samples if self.samples else 0.0}


@hookimpl
def swarmscene_register_disturbances(register):
    """Add :class:`SensingNoise` to the registry, so that ``disturbances.<key>.name: sensing_noise`` chooses it."""
    register(SensingNoise)
