"""The ``motor_failure`` event kind: one rotor (``rotor``) keeps ``fraction`` of its thrust.

The engine only marks the vehicle failed; a dynamics model with rotors applies the loss through the
``swarmscene_event`` hook (the kind declares ``rotor_fault``: its events carry ``rotor`` and
``fraction``), and the vehicle then moves as its physics says (it is not held). A vehicle that lost
a rotor falls or spins down about the point where it failed (``stays_where_failed``).
"""

from pydantic import Field

from swarmscene.plugin import EventKindPlugin, EventParams, hookimpl


class MotorFailureParams(EventParams):
    """``name: motor_failure``: its own fields beside ``at``, ``agents``, ``name``."""

    rotor: int = Field(ge=0, description="the index of the failed rotor")
    fraction: float = Field(0.0, ge=0, le=1, description="thrust the rotor keeps, 0..1 (0: dead)")


class MotorFailure(EventKindPlugin):
    """One rotor keeps ``fraction`` of its thrust; the dynamics model applies it (not held)."""

    name = "motor_failure"
    Params = MotorFailureParams
    rotor_fault = True
    stays_where_failed = True


@hookimpl
def swarmscene_register_events(register):
    """Add :class:`MotorFailure` to the registry, so that an event's ``name: motor_failure`` chooses it."""
    register(MotorFailure)
