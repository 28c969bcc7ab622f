"""The environment section of the scenario schema: the obstacle map's footprints, listed or generated.

Validated here (a generator's parameters by its own model in :mod:`swarmscene.core.generators`),
built into shapely geometries by :func:`swarmscene.core.geometry.build_obstacles`,
queried during a run through :class:`swarmscene.core.environment.Environment`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel, ConfigDict, Field, create_model, field_validator, model_serializer, model_validator,
)

from .fields import MAX_LENGTH, Point2, StrictModel, key_error
from .generators import GENERATORS, GeneratorName, generate
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


class _EnvironmentBase(StrictModel):
    """The obstacle map (footprints in the x-y plane, extruded over all altitudes): listed
    ``obstacles``, and those of a map ``generator`` built from its parameters (which sit beside it:
    ``environment.width``), see :mod:`swarmscene.core.generators`."""

    name: str = Field("open", description="label of the map")
    generator: GeneratorName | None = Field(
        None,
        description="map generator: corridor | building | obstacle_field (null: only the listed obstacles)",
    )
    obstacles: list[Obstacle] = Field(
        default_factory=list, description="obstacle footprints (added to the generator's)"
    )

    @model_validator(mode="wrap")
    @classmethod
    def _generator_parameters(cls, data: Any, handler: Any) -> Any:
        """The chosen generator's parameters are validated by its own model (defaults filled, so
        the run's config records all of them); a parameter of another generator is an error."""
        generator = data.get("generator") if isinstance(data, dict) else None
        if generator is not None and generator not in GENERATORS:
            return handler(data)  # reported as an unknown generator, its parameters unchecked
        if not isinstance(data, dict):
            return handler(data)
        params_model = GENERATORS[generator][0] if generator in GENERATORS else None
        given = {k: v for k, v in data.items() if k in GENERATOR_KEYS}
        own = params_model.model_fields if params_model is not None else {}
        for key, value in given.items():
            if key not in own:
                raise key_error(key, _not_a_parameter(key, generator), value)
        if params_model is not None:
            data = {**data, **params_model.model_validate(given).model_dump(mode="json")}
        return handler(data)

    @model_serializer(mode="wrap")
    def _recorded(self, handler: Any) -> dict[str, Any]:
        """As a user writes it: the generator's parameters only (no other generator's nulls), and
        no ``generator: null`` for a listed map."""
        own = GENERATORS[self.generator][0].model_fields if self.generator else {}
        return {k: v for k, v in handler(self).items()
                if (k not in GENERATOR_KEYS and (k != "generator" or v is not None)) or k in own}

    def generated(self) -> tuple[list, list[str]]:
        """The generator's obstacle polygons and its error lines (none without a generator)."""
        if self.generator is None:
            return [], []
        polygons, errors = generate(self.generator, self.generator_params().model_dump_json())
        return list(polygons), list(errors)  # new lists: the cached ones are shared

    def generator_params(self) -> StrictModel | None:
        """The chosen generator's validated parameters (None without a generator)."""
        if self.generator is None:
            return None
        model = GENERATORS[self.generator][0]
        return model.model_validate({k: getattr(self, k) for k in model.model_fields})


def _not_a_parameter(key: str, generator: str | None) -> str:
    users = [name for name, (model, _) in GENERATORS.items() if key in model.model_fields]
    if generator is None:
        return f"a parameter of environment.generator {' or '.join(users)}, which is not chosen"
    return (f"not a parameter of generator {generator} (its parameters: "
            f"{', '.join(GENERATORS[generator][0].model_fields)})")


def _generator_fields() -> dict[str, Any]:
    """The generators' parameters as optional fields of the environment section (one flat
    namespace, so ``environment.width=0.5`` overrides a corridor's width); a name shared by two
    generators means the same thing in both. Their own models hold the defaults and constraints."""
    owners: dict[str, list[str]] = {}
    for name, (model, _) in GENERATORS.items():
        for key in model.model_fields:
            owners.setdefault(key, []).append(name)
    fields: dict[str, Any] = {}
    for key, names in owners.items():
        info = GENERATORS[names[0]][0].model_fields[key]
        default = info.get_default(call_default_factory=True)
        default = "required" if info.is_required() else f"default {default!r}"
        description = f"{', '.join(names)}: {info.description} ({default})"
        fields[key] = (info.annotation | None, Field(None, description=description))
    return fields


GENERATOR_KEYS = frozenset(key for model, _ in GENERATORS.values() for key in model.model_fields)
"""Every generator parameter's name (the environment section's optional keys)."""

EnvironmentConfig = create_model(
    "EnvironmentConfig", __base__=_EnvironmentBase, __module__=__name__,
    __doc__=_EnvironmentBase.__doc__, **_generator_fields(),
)
