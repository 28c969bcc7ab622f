"""The contract of a disturbance model: its ``name``, its phase, its ``Params``, its random stream.

A scenario declares models under ``disturbances``, each under a key of its choice (the key names it
in errors and metrics; the model's ``name`` defaults to the key)::

    disturbances:
      dryden: {speed: 5.0}                   # name: dryden
      gps: {name: sensing_noise, pos_std: [2.1, 2.1, 4.2]}

(``kind``, the spelling of ``name`` until 0.6.0, is read until 0.9.0 with a warning: :mod:`..spelling`.)

Each model acts in one phase of the tick (:data:`PHASES`); the kernel calls the models of a phase
in the order of their keys (sorted), so a composition does not depend on how Hydra merged it.
"""

from __future__ import annotations

import warnings
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..errors import SwarmsceneDeprecationWarning
from ..fields import StrictModel

PHASES = ("sense", "communicate", "wind", "force")
"""sense: what each agent measures of itself; communicate: what the others receive of it;
wind: the air's force on every vehicle, each physics step; force: any other force on every
vehicle (downwash, ground effect, drag, a battery's limit), each physics step."""

STREAM = 0x18D15
"""Spawn key of the disturbances' random streams: model ``key`` draws from
``SeedSequence(seed, spawn_key=(STREAM, crc32(key)))``, never from the run's generator, so a
scenario without disturbances keeps its random stream and adding one model leaves the others'
draws unchanged."""


class DisturbanceParams(StrictModel):
    """Base of every disturbance model's options (unknown keys, NaN, booleans for numbers refused)."""


@dataclass(frozen=True)
class DisturbanceContext:
    """What a disturbance model may know when it is built.

    Attributes:
        key: its key under ``disturbances``.
        n: number of agents.
        guidance_period: T_s, s.
        physics_step: s.
        comm_range: m.
        rng: the model's own generator (see :data:`STREAM`).
        floor: the ground's height, m (``environment.floor``); None: the scenario has no ground.
    """

    key: str
    n: int
    guidance_period: float
    physics_step: float
    comm_range: float
    rng: np.random.Generator
    floor: float | None = None


def model_rng(seed: int, key: str) -> np.random.Generator:
    """The generator of model ``key`` in a run seeded ``seed`` (independent of the run's)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(STREAM, zlib.crc32(key.encode()))))


class _DeprecatedKind:
    """``Disturbance.kind``: the model's ``name``, read with a warning (until 0.9.0)."""

    def __get__(self, obj: Any, owner: type) -> str:
        warnings.warn(f"{owner.__name__}.kind is deprecated: read {owner.__name__}.name (a disturbance "
                      f"model's kind is read until 0.9.0)", SwarmsceneDeprecationWarning, stacklevel=2)
        return owner.name  # type: ignore[attr-defined]  # every registered model declares one


class Disturbance:
    """A disturbance model: subclasses set ``name``, ``phase``, ``Params`` and their phase's method
    (and ``params: Params`` under their ``Params``, which types ``self.params`` as that model).

    ``name`` is the registered name a scenario chooses it by (``disturbances.<key>.name``, the key
    itself when it is left out). ``kind``, its attribute name until 0.6.0, is deprecated (until
    0.9.0): reading it warns and gives ``name``; a model declaring ``kind`` rather than ``name`` is
    registered under it, with a warning.

    sense:        ``sense(world, pos, vel) -> (pos, vel)``: each agent's estimate of its own state,
                  from the truth (``world``) and the estimate of the models before it.
    communicate:  ``communicate(world, pos, vel) -> (pos, vel)``: the swarm's picture of every agent
                  (what the others received of it), from the agents' own estimates.
    wind:         ``air(world, t) -> (N, 3)``: the air's velocity at each agent at time ``t``, m/s,
                  for the physics step starting then (summed over the wind models).
    force:        ``force(world, t) -> (N, 3)``: a force per unit mass on each vehicle, m/s^2,
                  world frame, for the physics step starting at ``t`` (summed over the force
                  models; the dynamics integrates it, ``Dynamics.force_coupling``).
    A communicate model joins the broadcast channel by its methods (core/disturbances/channel.py):
    ``delays(world, sensing) -> (N,) ticks`` with ``max_ticks`` (and, so that validation bounds the
    channel's memory before the run, the classmethod :meth:`channel_ticks`), and/or
    ``lost(world, sensing) -> (N,) bool``; and the per-link layer with
    ``link_delay(hops) -> (N, N) ticks`` and/or ``link_lost(world) -> (N, N) bool``. One with none
    of them is a relay: ``communicate(world, pos, vel)`` after the channel.
    Every model may add metrics (``metrics() -> dict``, keys without prefix; the engine prefixes
    ``disturbances.<key>.``).
    """

    name: ClassVar[str]
    phase: ClassVar[str]
    Params: ClassVar[type[DisturbanceParams]] = DisturbanceParams
    delay_option: ClassVar[str | None] = None
    """The option that lengthens the model's delays (``tau`` of ``comm_delay``), named in the error
    when the channel would keep too many ticks of messages (None: the model's key is named)."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # ``kind`` was the attribute until 0.6.0: a model still declaring it has it as its name
        # (reads of ``kind`` then go through the deprecated alias below, like every model's).
        own = cls.__dict__
        if "kind" in own and not isinstance(own["kind"], _DeprecatedKind):
            declared = own["kind"]
            if "name" not in own:
                warnings.warn(f"{cls.__qualname__} declares kind = {declared!r}: declare name (a disturbance "
                              f"model's kind is read as its name until 0.9.0)", SwarmsceneDeprecationWarning,
                              stacklevel=2)
                cls.name = declared
            del cls.kind

    kind = _DeprecatedKind()
    """Deprecated name of ``name`` (read until 0.9.0)."""

    def __init__(self, params: DisturbanceParams, ctx: DisturbanceContext) -> None:
        self.params = params
        self.ctx = ctx
        self.rng = ctx.rng

    @classmethod
    def channel_ticks(cls, params: Any, n: int, guidance_period: float) -> int:
        """The longest delay, in guidance ticks, this model may put on a broadcast message, from its
        options alone (``n`` agents, tick ``guidance_period`` s): the channel keeps that many ticks
        of messages, and validation refuses a scenario whose channel would not fit in memory
        (0, the default: the model delays nothing, or what it delays is not bounded in advance)."""
        return 0

    @classmethod
    def air_batch(cls, models: Sequence[Any], worlds: Sequence[Any], t: float) -> Sequence[np.ndarray] | Any:
        """A wind model's ``air`` of B worlds at once (docs/batched.md): one (N, 3) array per world
        from its own instance in ``models``, each the bits that instance's ``air(world, t)`` would
        give and leaving the instance as that call would. The default returns ``NotImplemented``:
        the engine asks each world's ``air``. The contract check
        ``disturbance.air_batch_equals_worlds`` holds a batched form to the per-world one."""
        return NotImplemented

    def metrics(self) -> dict[str, Any]:
        """The model's own metrics, keys without prefix (none by default)."""
        return {}

    def raised(self, world: Any, t: float) -> list[Any]:
        """Events the model raises at the end of the tick ending at ``t`` (failures it causes, e.g.
        a battery run down): :class:`~swarmscene.core.events.Event` objects, applied by the kernel
        like scheduled ones (none by default)."""
        return []
