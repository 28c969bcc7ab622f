"""The environment section of the scenario schema: the obstacle map's footprints.

Validated here, built into shapely geometries by :func:`swarmscene.core.geometry.build_obstacles`,
queried during a run through :class:`swarmscene.core.environment.Environment`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from .fields import MAX_LENGTH, Point2, StrictModel
from .plugin import reject_bool_as_number


class _Shape(BaseModel):
    """Base of the obstacle footprints: their ``type`` tags a union, which admits no ``*`` validator."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("points", "center", "radius", "thickness", mode="before", check_fields=False)
    @classmethod
    def _no_bool_for_numbers(cls, value: Any, info: Any) -> Any:
        return reject_bool_as_number(cls, value, info)


class PolygonObstacle(_Shape):
    """A polygonal footprint; ``points`` in order, at least 3, not self-intersecting."""

    type: Literal["polygon"]
    points: list[Point2] = Field(min_length=3, description="vertices [x, y], m")


class CircleObstacle(_Shape):
    """A disc footprint (pillar, no-fly cylinder)."""

    type: Literal["circle"]
    center: Point2 = Field(description="[x, y], m")
    radius: float = Field(gt=0, le=MAX_LENGTH, description="m")


class WallObstacle(_Shape):
    """A thick wall: the polyline ``points`` buffered by ``thickness / 2`` with flat caps."""

    type: Literal["wall"]
    points: list[Point2] = Field(min_length=2, description="polyline [x, y], m")
    thickness: float = Field(gt=0, le=MAX_LENGTH, description="m")


Obstacle = Annotated[PolygonObstacle | CircleObstacle | WallObstacle, Field(discriminator="type")]


class EnvironmentConfig(StrictModel):
    """The obstacle map (footprints in the x-y plane, extruded over all altitudes)."""

    name: str = Field("open", description="label of the map")
    obstacles: list[Obstacle] = Field(default_factory=list, description="obstacle footprints")
