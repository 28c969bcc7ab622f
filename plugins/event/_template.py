"""Template of an event kind: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in), write events of it in a scenario
(``events: [{at: 2.0, agents: [1], name: my_event, keep: 0.5}]``), and check it with
``swarmscene.testing.check_event_kind(MyEventKind)`` in your tests.
"""

from __future__ import annotations

from pydantic import Field

from swarmscene.plugin import EventKindPlugin, EventParams, Motion, hookimpl


class MyEventKind(EventKindPlugin):
    """Thrust fades: the vehicle fails and coasts on at a fraction ``keep`` of its velocity."""

    name = "my_event"
    failure = True  # healthy drops (False: only the radio is lost, comm_ok drops)
    motion = Motion.COAST  # after the dynamics: HOLD (stays), COAST (constant velocity), DYNAMICS
    stays_where_failed = False  # True: it stays about where it failed (an avoidance may take it as fixed)
    rotor_fault = False  # True: Params have rotor and fraction, which a dynamics model with rotors applies

    class Params(EventParams):  # the event's own keys beside at, agents, name
        keep: float = Field(0.5, ge=0, le=1, description="the fraction of its velocity it keeps")

    @classmethod
    def apply(cls, event, world, idx):
        """Flags and velocities of the agents ``idx`` (never positions: the kernel moves them)."""
        super().apply(event, world, idx)  # healthy[idx] = False
        world.vel[idx] *= event.params.keep  # the velocity it coasts at from now on


@hookimpl
def swarmscene_register_events(register):
    register(MyEventKind)
