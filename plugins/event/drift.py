"""The ``drift`` event kind: the vehicle no longer responds and moves at a constant ``velocity``.

p(t) = p(t_f) + v_d (t - t_f), v_d the event's ``velocity``.

Source: the drift fault of the sensor-fault taxonomy, an additive error growing linearly in time,
y(t) = x(t) + r (t - t_f) (Balaban et al., IEEE Sensors Journal 9(12), 2009; Sharma et al., ACM
TOSN 6(3), 2010): a position estimate drifting at rate r makes a vehicle that holds its estimate
move physically at v_d = -r.
"""

from pydantic import Field

from swarmscene.plugin import EventKindPlugin, EventParams, Motion, Point3, hookimpl


class DriftParams(EventParams):
    """``name: drift``: its own field beside ``at``, ``agents``, ``name``."""

    velocity: Point3 = Field(description="its drift velocity [vx, vy, vz], m/s")


class Drift(EventKindPlugin):
    """No longer responds: moves at the event's constant ``velocity`` (a drifting estimate)."""

    name = "drift"
    motion = Motion.COAST
    Params = DriftParams

    @classmethod
    def apply(cls, event, world, idx):
        """Drift: the agent fails and coasts at the event's ``velocity`` v_d from now on."""
        super().apply(event, world, idx)
        world.vel[idx] = event.params.velocity


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`Drift` to the registry, so that an event's ``name: drift`` chooses it."""
    register(Drift)
