"""The ``stuck`` event kind: the vehicle no longer responds and keeps its velocity (a fly-away).

p(t) = p(t_f) + v(t_f) (t - t_f): the "stuck-at" / lock-in-place fault of the fault-tolerant-control
taxonomy, applied to the velocity command.
"""

from swarmscene.plugin import EventKindPlugin, Motion, hookimpl


class Stuck(EventKindPlugin):
    """No longer responds: keeps the velocity it had at the event (a fly-away)."""

    name = "stuck"
    motion = Motion.COAST  # at the velocity apply() leaves: its own, unchanged


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`Stuck` to the registry, so that an event's ``name: stuck`` chooses it."""
    register(Stuck)
