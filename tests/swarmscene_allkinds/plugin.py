"""One of each kind: formation, avoidance, dynamics, observer, disturbance model, event kind, map
generator, policy (each small, each passing its contract check)."""

from __future__ import annotations

import numpy as np
from pydantic import Field
from shapely.geometry import box

from swarmscene.plugin import (
    Avoidance,
    Disturbance,
    DisturbanceParams,
    Dynamics,
    EventKindPlugin,
    EventParams,
    Formation,
    MapGenerator,
    Mode,
    Motion,
    PluginParams,
    Policy,
    Setpoints,
    StrictModel,
    hookimpl,
)


class Climb(Formation):
    """Every agent holds its start, ``height`` higher."""

    name = "ak_climb"

    class Params(PluginParams):
        height: float = Field(1.0, ge=0, le=100, description="climb above the start, m")

    def __init__(self, params, ctx):
        super().__init__(params, ctx)
        self.goal = ctx.initial.pos + [0.0, 0.0, params.height]

    def setpoints(self, world, sensing):
        sp = Setpoints.hold(world.pos)
        sp.mode[:] = Mode.POSITION
        sp.pos[:] = self.goal
        return sp


class Damped(Avoidance):
    """Setpoint velocities scaled by ``factor`` for healthy agents."""

    name = "ak_damped"

    class Params(PluginParams):
        factor: float = Field(0.8, gt=0, le=1, description="fraction of the velocity kept")

    def adjust(self, world, sensing, sp):
        out = sp.copy()
        out.vel[world.healthy] *= self.params.factor
        return out


class Point(Dynamics):
    """A kinematic point under a proportional controller with velocity feed-forward."""

    name = "ak_point"
    wind_coupling = "carried"

    class Params(PluginParams):
        gain: float = Field(1.0, gt=0, le=100, description="position gain, 1/s")

    def initialize(self, world):
        self.u = np.zeros_like(world.pos)

    def control(self, world, sp):
        self.u = sp.vel + self.params.gain * (sp.pos - world.pos)
        velocity = sp.mode == Mode.VELOCITY
        self.u[velocity] = sp.vel[velocity]
        hold = sp.mode == Mode.HOLD
        self.u[hold] = self.params.gain * (sp.pos[hold] - world.pos[hold])

    def step(self, world, dt):
        world.pos += self.u * dt


class Altitude:
    """Records the highest altitude any agent reached."""

    def __init__(self, sim):
        self.top = float(sim.world.pos[:, 2].max())

    @hookimpl
    def swarmscene_step_end(self, sim):
        self.top = max(self.top, float(sim.world.pos[:, 2].max()))

    @hookimpl
    def swarmscene_run_end(self, sim, metrics):
        metrics["ak_altitude.top"] = self.top


class Updraft(Disturbance):
    """A steady updraft of ``speed`` m/s at every agent."""

    name = "ak_updraft"
    phase = "wind"

    class Params(DisturbanceParams):
        speed: float = Field(0.5, ge=0, le=50, description="vertical air speed, m/s")

    def air(self, world, t):
        return np.tile([0.0, 0.0, self.params.speed], (world.n, 1))

    def metrics(self):
        return {"speed": self.params.speed}


class Freeze(EventKindPlugin):
    """The vehicle fails and coasts at ``keep`` of its velocity."""

    name = "ak_freeze"
    motion = Motion.COAST

    class Params(EventParams):
        keep: float = Field(0.5, ge=0, le=1, description="the fraction of its velocity it keeps")

    @classmethod
    def apply(cls, event, world, idx):
        super().apply(event, world, idx)
        world.vel[idx] *= event.params.keep


class Posts(MapGenerator):
    """A row of ``count`` square posts 5 m apart along +x, 20 m north of the origin."""

    name = "ak_posts"

    class Params(StrictModel):
        count: int = Field(3, ge=1, le=100, description="how many posts")

    @classmethod
    def build(cls, params):
        return [box(5.0 * k, 20.0, 5.0 * k + 1.0, 21.0) for k in range(params.count)]


class Up(Policy):
    """Every agent asks to climb at ``rate`` of the top speed."""

    name = "ak_up"

    class Params(PluginParams):
        rate: float = Field(0.5, ge=0, le=1, description="fraction of the top speed, upwards")

    def __call__(self, obs):
        return np.tile([0.0, 0.0, self.params.rate], (len(obs), 1))


@hookimpl
def swarmscene_register_formations(register):
    register(Climb)


@hookimpl
def swarmscene_register_avoidances(register):
    register(Damped)


@hookimpl
def swarmscene_register_dynamics(register):
    register(Point)


@hookimpl
def swarmscene_register_observers(register):
    register(Altitude)


@hookimpl
def swarmscene_register_disturbances(register):
    register(Updraft)


@hookimpl
def swarmscene_register_events(register):
    register(Freeze)


@hookimpl
def swarmscene_register_generators(register):
    register(Posts)


@hookimpl
def swarmscene_register_policies(register):
    register(Up)
