"""Policy: a trained or scripted policy flies the agents, from what each one senses.

Each guidance tick, every agent's observation row (own state, the k nearest neighbours within the
sensing range, the nearest obstacle, the formation's reference: ``methods/policy/observation.py``)
goes to a policy that returns a normalised action per agent, turned into a velocity or
acceleration setpoint (``methods/policy/actions.py``). The formation's setpoints are the task (the
reference in the observation); this plugin replaces them, so the policy must keep the swarm safe
itself, and the safety monitor judges it like any other method.

``policy`` names where the actions come from: a registered policy (hook
``swarmscene_register_policies``: the built-in scripted ``seek_reference``, or a package's), or null
when :mod:`swarmscene.env` drives the agents (the environment hands each tick's actions to
:meth:`PolicyAvoidance.command`). A scenario file names a policy, never an import path; the name
and ``policy_options`` are checked when the scenario is validated (the policy's own ``Params``).

Choices: the reference observed is the formation's setpoint of the previous tick (none at t = 0),
which is what an environment can show its agents before they act; the plugin does the same when it
flies, so a policy meets exactly the inputs it was trained on.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import numpy as np
from pydantic import Field, PrivateAttr, ValidationError, ValidationInfo, model_validator

from swarmscene.methods.policy.actions import ActionCommand, ActionSpec, action_setpoints, action_setpoints_batch
from swarmscene.methods.policy.observation import ObservationLayout, observe, observe_batch
from swarmscene.methods.policy.policies import make_policy
from swarmscene.plugin import (
    Avoidance,
    BuildContext,
    PluginParams,
    Policy,
    Setpoints,
    WorldState,
    choose,
    format_validation_error,
    hookimpl,
)


class PolicyAvoidance(Avoidance):
    """Setpoints from a policy's actions over each agent's observation."""

    name = "policy"

    class Params(PluginParams):
        policy: str | None = Field(
            None, description="registered policy that flies the agents (built-in: seek_reference; "
            "packages add theirs through the hook swarmscene_register_policies); null: the "
            "actions come from swarmscene.env")
        policy_options: dict[str, Any] = Field(
            default_factory=dict, description="keyword options of the chosen policy (e.g. the path "
            "of a trained model), validated by the policy's Params; seek_reference takes gain, "
            "repulsion, radius")
        action: ActionCommand = Field(
            "velocity", description="what an action commands: velocity (a * max_speed) or "
            "acceleration (a * max_accel, through the dynamics' velocity loop)")
        max_speed: float = Field(2.0, gt=0, description="m/s commanded by a velocity action of 1")
        max_accel: float = Field(2.0, gt=0, description="m/s^2 commanded by an acceleration action of 1")
        neighbours: int = Field(4, ge=0, le=64, description="k: nearest neighbours observed")
        sensing_range: float | None = Field(
            None, gt=0, le=1e6, description="R: neighbours observed within this distance, m (null: comm.range)")
        obstacle_range: float = Field(
            5.0, gt=0, le=1e6, description="R_o: the nearest obstacle is observed within this distance, m "
            "(at most 1000 km)")

        _policy: Any = PrivateAttr(None)

        @model_validator(mode="after")
        def _registered_policy(self, info: ValidationInfo) -> PolicyAvoidance.Params:
            """The policy named is registered and its options pass its Params (checked against the
            registry validating the scenario; without one, when the plugin is built)."""
            if self.policy is None:
                return self
            try:
                cls = choose(info, "policy", self.policy)
            except ValueError as exc:
                raise ValueError(f"policy: {exc}") from None
            if cls is not None:
                _check_options(cls, self.policy_options)
                self._policy = cls
            return self

        @property
        def policy_class(self) -> type[Policy] | None:
            """The registered class ``policy`` names (None: not resolved by a registry)."""
            return self._policy

    params: Params

    def __init__(self, params: PolicyAvoidance.Params, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        self.layout = ObservationLayout(params.neighbours)
        self.spec = ActionSpec(params.action, params.max_speed, params.max_accel, ctx.guidance_period)
        self.sensing_range = params.sensing_range or ctx.comm_range
        policy_class = params.policy_class
        if params.policy is not None and policy_class is None:
            raise ValueError(f"policy: {params.policy!r} was not resolved by a registry: build the "
                             "scenario through swarmscene.api (which validates it)")
        self.policy = (
            None if params.policy is None or policy_class is None  # (a policy without its class: raised)
            else make_policy(policy_class, self.layout, self.spec, params.policy_options)
        )
        self.reference: Setpoints | None = None
        """The formation's setpoints of the last tick (observed as the reference)."""
        self._action: np.ndarray | None = None
        self._active = np.ones(ctx.n, dtype=bool)

    def observe(self, sensing) -> np.ndarray:
        """Every agent's observation row now, shape (N, D) float32."""
        return observe(sensing, self.reference, self.layout, self.sensing_range, self.params.obstacle_range)

    @classmethod
    def observe_batch(cls, avoidances: Sequence[PolicyAvoidance], sensings: Sequence[Any]) -> np.ndarray:
        """:meth:`observe` of B worlds of N agents, stacked (B, N, D) float32, world b's rows the bits of
        ``avoidances[b].observe(sensings[b])`` (:func:`~swarmscene.methods.policy.observation.observe_batch`).
        Instances with different ranges are observed one by one; all must share N and the layout
        (the row length D), or the stacking raises a ``ValueError``."""
        first = avoidances[0]
        ranges = (first.layout, first.sensing_range, first.params.obstacle_range)
        if any((a.layout, a.sensing_range, a.params.obstacle_range) != ranges for a in avoidances):
            return np.stack([a.observe(s) for a, s in zip(avoidances, sensings, strict=True)])
        return observe_batch(sensings, [a.reference for a in avoidances], *ranges)

    def command(self, action: np.ndarray, active: np.ndarray) -> None:
        """Set the actions (N, 3) of the next tick; agents not ``active`` (N,) bool hold."""
        self._action = np.asarray(action, dtype=float)
        self._active = np.asarray(active, dtype=bool)

    def adjust(self, world: WorldState, sensing, sp: Setpoints) -> Setpoints:
        """Fly this tick's actions: the named policy's, or those an environment commanded."""
        if self.policy is not None:
            self.command(self.policy(self.observe(sensing)), np.ones(world.n, dtype=bool))
        elif self._action is None:
            raise RuntimeError(
                "avoidance 'policy' without avoidance.policy takes its actions from swarmscene.env; "
                "name a registered policy to fly it on its own")
        # set by command() above or by the environment (the branch before raised otherwise)
        out = action_setpoints(world, cast(np.ndarray, self._action), self._active, self.spec)
        self.reference = sp
        if self.policy is None:
            self._action = None  # an environment must command every tick
        return out

    @classmethod
    def adjust_batch(cls, avoidances, worlds, sensings, setpoints):
        """``adjust`` of B worlds an environment drives, their commanded actions turned into
        setpoints in one elementwise pass (:func:`~swarmscene.methods.policy.actions.action_setpoints_batch`):
        each world gets its own ``adjust``'s bits, and each instance keeps what its ``adjust``
        keeps (the reference observed next, no action left). Declined (``NotImplemented``, before
        any instance is touched) when a policy is named (it observes and acts world by world), a
        world was commanded nothing (its own ``adjust`` raises) or another shape than its agents,
        or the instances scale their actions differently."""
        first = avoidances[0]
        n = len(worlds[0].pos)
        if any(a.policy is not None or a._action is None or a._action.shape != (n, 3) or a._active.shape != (n,)
               or a.spec != first.spec for a in avoidances) or any(len(w.pos) != n for w in worlds):
            return NotImplemented
        out = action_setpoints_batch(worlds, [a._action for a in avoidances], [a._active for a in avoidances],
                                     first.spec)
        for a, sp in zip(avoidances, setpoints, strict=True):
            a.reference = sp
            a._action = None  # an environment must command every tick
        return out


def _check_options(cls: type[Policy], options: dict[str, Any]) -> None:
    """``policy_options`` against the policy's Params: the first problem as one line naming it."""
    try:
        cls.Params.model_validate(options)
    except ValidationError as exc:
        raise ValueError(format_validation_error(exc, cls.Params, options, prefix="policy_options")[0]) from None


@hookimpl
def swarmscene_register_avoidances(register) -> None:
    """Register :class:`PolicyAvoidance` (``avoidance=policy``)."""
    register(PolicyAvoidance)
