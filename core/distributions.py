"""Random scenario parts declared as distributions, and the seeded streams they are drawn from.

A value that may be random is written either as a number or as a mapping with exactly one key
naming its distribution::

    at: 5.0                      # fixed
    at: {uniform: [2, 20]}       # U(low, high)
    at: {normal: [10, 2]}        # N(mean, std)
    at: {lognormal: [0, 0.5]}    # exp(N(mu, sigma)): positive, right-skewed (sizes)
    at: {exponential: 30}        # mean 30: a constant failure rate 1/30 per s (memoryless)
    at: {choice: [5, 10, 15]}    # one of the listed values, equally likely

Streams: every random part draws from its own generator, derived from the scenario's ``seed`` and a
fixed key (:func:`stream`), never from the run's generator. A scenario without random parts therefore
draws exactly what it drew before they existed, and adding a random event does not shift the start
positions or any other random part.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from pydantic import Field, TypeAdapter, model_serializer, model_validator

from .errors import SwarmsceneDeprecationWarning
from .fields import MAX_LENGTH, StrictModel, key_error

EVENTS_STREAM = 0x6576
"""Key of the event draws' streams (:func:`stream`); one sub-stream per event, by its index."""
MAP_STREAM = 0x6D61
"""Key of the map generators' stream (:func:`stream`)."""


def stream(seed: int, key: int, *index: int) -> np.random.Generator:
    """A generator independent of ``default_rng(seed)`` (the run's) and of every other key/index.

    ``SeedSequence(seed, spawn_key=(key, *index))`` is numpy's own way to derive independent
    streams from one seed (the same as ``SeedSequence(seed).spawn`` children), so the draws are
    reproducible from the seed alone and unrelated to the run's stream.
    """
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(key, *index)))


class Draw(StrictModel):
    """A distribution: exactly one of its keys (see :mod:`swarmscene.core.distributions`)."""

    uniform: tuple[float, float] | None = Field(None, description="[low, high], low <= high")
    normal: tuple[float, float] | None = Field(None, description="[mean, std], std >= 0")
    lognormal: tuple[float, float] | None = Field(
        None, description="[mu, sigma] of the underlying normal, sigma >= 0"
    )
    exponential: float | None = Field(None, gt=0, description="mean (1 / rate)")
    choice: list[float] | None = Field(None, min_length=1, description="values, equally likely")

    @model_validator(mode="after")
    def _one_distribution(self) -> Draw:
        given = self.families()
        if len(given) != 1:
            raise ValueError(
                f"give exactly one distribution, one of {', '.join(type(self).model_fields)}"
            )
        for family, bad, rule in (
            ("uniform", lambda p: p[0] > p[1], "[low, high] with low <= high"),
            ("normal", lambda p: p[1] < 0, "[mean, std] with std >= 0"),
            ("lognormal", lambda p: p[1] < 0, "[mu, sigma] with sigma >= 0"),
        ):
            value = getattr(self, family)
            if value is not None and bad(value):
                raise key_error(family, f"must be {rule}", list(value))
        return self

    @model_serializer(mode="wrap")
    def _only_the_given(self, handler: Any) -> dict[str, Any]:
        """Recorded as written: ``{uniform: [2, 20]}``, without the other keys' nulls."""
        return {k: v for k, v in handler(self).items() if v is not None}

    @property
    def kind(self) -> str:
        """Deprecated alias of :attr:`family` (until 0.9.0: ``kind`` names a plugin's kind only)."""
        warnings.warn("Draw.kind is deprecated: read Draw.family (kind is removed in 0.9.0)",
                      SwarmsceneDeprecationWarning, stacklevel=2)
        return self.family

    def kinds(self) -> list[str]:
        """Deprecated alias of :meth:`families` (until 0.9.0)."""
        warnings.warn("Draw.kinds() is deprecated: call Draw.families() (kinds is removed in 0.9.0)",
                      SwarmsceneDeprecationWarning, stacklevel=2)
        return self.families()

    def families(self) -> list[str]:
        """The distribution keys given (one, once validated)."""
        return [k for k in type(self).model_fields if getattr(self, k) is not None]

    @property
    def family(self) -> str:
        """The one distribution key given, its family (``uniform``, ``normal``, ...)."""
        return self.families()[0]

    def support(self) -> tuple[float, float]:
        """Smallest and largest value a draw can take."""
        family = self.family
        value = getattr(self, family)
        if family == "uniform":
            return float(value[0]), float(value[1])
        if family == "choice":
            return float(min(value)), float(max(value))
        if family == "normal" and value[1] == 0:
            return float(value[0]), float(value[0])
        return (0.0 if family in ("lognormal", "exponential") else -np.inf), np.inf

    def positive(self) -> bool:
        """Whether every draw is > 0 (sizes)."""
        if self.family in ("lognormal", "exponential"):
            return True
        return self.family != "normal" and self.support()[0] > 0

    def sample(self, rng: np.random.Generator, size: int | None = None) -> Any:
        """One value (``size`` None) or an array of ``size`` values drawn with ``rng``."""
        family = self.family
        value = getattr(self, family)
        if family == "uniform":
            return rng.uniform(value[0], value[1], size)
        if family == "normal":
            return rng.normal(value[0], value[1], size)
        if family == "lognormal":
            return rng.lognormal(value[0], value[1], size)
        if family == "exponential":
            return rng.exponential(value, size)
        picks = rng.integers(len(value), size=size)
        return np.asarray(value, dtype=float)[picks]


def parse_draw(value: Any, number: TypeAdapter) -> float | Draw:
    """A field that is a number or a :class:`Draw`: a mapping is validated as a Draw (its errors
    name their key below the field: ``events.0.at.uniform: ...``), anything else by ``number``."""
    if isinstance(value, (dict, Draw)):
        return Draw.model_validate(value)
    if isinstance(value, bool):  # pydantic's lax mode would read 1 or 0
        raise ValueError("must be a number, not true/false")
    return number.validate_python(value)


def number_adapter(low: float, high: float = MAX_LENGTH) -> TypeAdapter:
    """Validator of a fixed number in [low, high] (finite)."""
    from typing import Annotated

    return TypeAdapter(Annotated[float, Field(ge=low, le=high, allow_inf_nan=False)])
