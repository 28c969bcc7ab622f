"""Building blocks of the scenario schema shared by its sections (engine config, events, maps).

Kept apart from :mod:`swarmscene.core.config` so that the modules owning a section's schema
(:mod:`~swarmscene.core.events`, :mod:`~swarmscene.core.obstacles`) can define it beside the code
that uses it without importing the whole schema.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from .plugin import reject_bool_as_number


class StrictModel(BaseModel):
    """A section of the engine schema: unknown keys, NaN and infinity are errors; values frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_numbers(cls, value: Any, info: Any) -> Any:
        """``true``/``false`` where a number is expected is an error (pydantic would read 1/0)."""
        return reject_bool_as_number(cls, value, info)


MAX_LENGTH = 1e7
"""Largest coordinate magnitude and length, m (10,000 km): squared distances stay far from float
overflow in every k-d tree and geometry query."""
MAX_DURATION = 1e9
"""Longest simulated duration, s (~32 years; the tick count is bounded by MAX_TICKS as well)."""
Coordinate = Annotated[float, Field(ge=-MAX_LENGTH, le=MAX_LENGTH)]
Point2 = tuple[Coordinate, Coordinate]
Point3 = tuple[Coordinate, Coordinate, Coordinate]


def key_error(key: str, message: str, value: Any) -> Exception:
    """A pydantic error at ``key`` of the model being validated, for checks across its fields:
    raised from a model validator it is reported at that key (``events.0.velocity: ...``), where a
    plain ValueError would be reported at the model (``events.0: ...``)."""
    from pydantic_core import InitErrorDetails, ValidationError

    detail = InitErrorDetails(type="value_error", loc=(key,), input=value, ctx={"error": ValueError(message)})
    return ValidationError.from_exception_data("scenario", [detail])
