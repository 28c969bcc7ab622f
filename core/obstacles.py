"""The environment section of the scenario schema: the obstacle map's footprints, listed or generated.

Validated here (a generator's parameters by its own ``Params``: the registry's map generators, the
built-ins of ``plugins/generator/`` and a third-party package's alike; the interface is
:class:`swarmscene.core.generators.MapGenerator`),
built into shapely geometries by :func:`swarmscene.core.geometry.build_obstacles`,
queried during a run through :class:`swarmscene.core.environment.Environment`.
"""

from __future__ import annotations

import functools
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    SerializationInfo,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from .fields import MAX_LENGTH, Point2, StrictModel, key_error
from .generators import MapGenerator
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
    """The obstacle map (footprints in the x-y plane, extruded over all altitudes): listed
    ``obstacles``, and those of a map ``generator`` built from its parameters (which sit beside it:
    ``environment.width``), see ``plugins/generator/``."""

    name: str = Field("open", description="label of the map")
    generator: str | None = Field(
        None,
        description="map generator, a registered name: corridor | building | obstacle_field | a "
        "plugin's (null: only the listed obstacles)",
    )
    obstacles: list[Obstacle] = Field(
        default_factory=list, description="obstacle footprints (added to the generator's)"
    )
    floor: float | None = Field(
        None, ge=-MAX_LENGTH, le=MAX_LENGTH,
        description="height of the ground, m (null: no ground, vehicles may fly at any z and a falling "
        "one falls forever); a vehicle meeting it lands, or crashes above touchdown_speed "
        "(core/floor.py)",
    )
    touchdown_speed: float = Field(
        0.5, gt=0, le=MAX_LENGTH, description="fastest a vehicle may meet the floor and land, m/s "
        "(faster: a crash, a failure)",
    )

    _generator: Any = PrivateAttr(None)
    _params: Any = PrivateAttr(None)

    @model_validator(mode="wrap")
    @classmethod
    def _generator_parameters(cls, data: Any, handler: Any, info: ValidationInfo) -> Any:
        """The chosen generator's parameters are validated by its own ``Params`` (defaults filled,
        so the run's config records all of them); a parameter of another generator is an error.

        The generators are the registry's (``context={"registry": ...}``, as :mod:`.validation`
        passes it); a generator named without one is refused in one line, naming the way
        (:func:`.registry.installed_registry` is the installed plugins' registry).
        Their parameters are held beside the section's fields (:meth:`generator_params`), not as
        fields: the schema names no generator."""
        if not isinstance(data, dict):
            return handler(data)
        generators = _generators(info.context)
        name = data.get("generator")
        chosen = generators.get(name) if isinstance(name, str) else None
        if name is not None and chosen is None:
            if not isinstance(info.context, dict) or info.context.get("registry") is None:
                raise key_error("generator", "a map generator is chosen from a plugin registry: validate with "
                                "context={'registry': ...} (swarmscene.api.load does)", name)
            raise key_error("generator", _unknown(name, generators), name)
        own = chosen.Params.model_fields if chosen is not None else {}
        given = {k: v for k, v in data.items() if k in own and k not in _ENVIRONMENT_KEYS}
        for key, value in data.items():
            if key not in own and key not in _ENVIRONMENT_KEYS and _users(key, generators):
                raise key_error(key, _not_a_parameter(key, name, generators), value)
        params = _validated(chosen, given) if chosen is not None else None
        model = handler({k: v for k, v in data.items() if k not in given})
        if isinstance(model, EnvironmentConfig):
            model._generator, model._params = chosen, params
        return model

    @model_serializer(mode="wrap")
    def _recorded(self, handler: Any, info: SerializationInfo) -> dict[str, Any]:
        """As a user writes it: no ``generator: null`` for a listed map; the generator's parameters
        after the section's fields, defaults filled; no ``floor: null`` (nor its default touchdown
        speed) for a map without a ground."""
        data = {k: v for k, v in handler(self).items() if k != "generator" or v is not None}
        if self._params is not None:
            mode = "json" if info.mode_is_json() else "python"
            data.update({k: v for k, v in self._params.model_dump(mode=mode).items() if k not in data})
        if self.floor is None:  # no ground: the record (and config hash) of a run before the floor
            data.pop("floor", None)
            if self.touchdown_speed == type(self).model_fields["touchdown_speed"].default:
                data.pop("touchdown_speed", None)
        return data

    def generated(self) -> tuple[list, list[str]]:
        """The generator's obstacle polygons and its error lines (none without a generator)."""
        if self.generator is None:
            return [], []
        polygons, errors = _build(self._generator, self._params.model_dump_json())
        return list(polygons), list(errors)  # new lists: the cached ones are shared

    def generator_params(self) -> BaseModel | None:
        """The chosen generator's validated parameters (None without a generator)."""
        return self._params

    @property
    def generator_class(self) -> type[MapGenerator] | None:
        """The chosen generator's class (a registered :class:`MapGenerator`; None without one)."""
        return self._generator


def _generators(context: Any) -> dict[str, type[MapGenerator]]:
    """The map generators known to a validation: its registry's (``context={"registry": ...}``, as
    :mod:`.validation` passes it), none without one (the engine holds no list of built-ins)."""
    registry = context.get("registry") if isinstance(context, dict) else None
    return {} if registry is None else registry.classes["generator"]


def _unknown(name: Any, generators: dict[str, type[MapGenerator]]) -> str:
    """The registry's line for an unknown name (:func:`~.registry.validate_choice`'s words)."""
    return f"unknown map generator {name!r} (valid: {', '.join(sorted(generators))})"


def _users(key: str, generators: dict[str, type[MapGenerator]]) -> list[str]:
    """The generators that take parameter ``key``."""
    return [name for name, cls in generators.items() if key in cls.Params.model_fields]


def _not_a_parameter(key: str, generator: str | None, generators: dict[str, type[MapGenerator]]) -> str:
    if generator is None:
        return (f"a parameter of environment.generator {' or '.join(_users(key, generators))}, "
                "which is not chosen")
    return (f"not a parameter of generator {generator} (its parameters: "
            f"{', '.join(generators[generator].Params.model_fields)})")


@functools.lru_cache(maxsize=8)
def _build(generator: type[MapGenerator], params_json: str) -> tuple[tuple[Any, ...], tuple[str, ...]]:
    """The obstacle polygons of ``generator`` with its parameters (as JSON) and its error lines.

    Cached by value: validation asks twice (to check the map, then the start positions), and a
    sweep's jobs in one process share a map; shapely geometries are immutable and the result is
    tuples, so no caller can change what the next one gets. Keyed by the class, not its name, so
    two registries with different generators of one name never share a map.
    """
    try:
        return tuple(generator.build(generator.Params.model_validate_json(params_json))), ()
    except ValueError as exc:  # one line naming its key (e.g. environment.density)
        return (), (str(exc),)


_ENVIRONMENT_KEYS = frozenset(EnvironmentConfig.model_fields)


def _validated(generator: type[MapGenerator], given: dict[str, Any]) -> BaseModel:
    """``generator.Params`` validated from ``given``; a check across its fields (a model validator
    raising ``ValueError("door_width: must be < ...")``, as docs/plugins.md asks) is reported at
    the field it names, ``environment.door_width: must be < ... (got 9.0)``, not at the whole
    environment with the dict of parameters as its value."""
    from pydantic_core import InitErrorDetails

    try:
        return generator.Params.model_validate(given)
    except ValidationError as exc:
        fields = generator.Params.model_fields
        details: list[InitErrorDetails] = []
        for err in exc.errors(include_url=False):
            message = str((err.get("ctx") or {}).get("error", err["msg"])).removeprefix("Value error, ")
            field, _, rest = message.partition(": ")
            if err["type"] == "value_error" and not err["loc"] and field in fields and rest:
                details.append(InitErrorDetails(type="value_error", loc=(field,), input=given.get(field),
                                                ctx={"error": ValueError(rest)}))
            else:
                details.append(InitErrorDetails(type=err["type"], loc=tuple(err["loc"]), input=err["input"],
                                                **({"ctx": err["ctx"]} if "ctx" in err else {})))  # type: ignore[typeddict-item]
        try:
            renamed = ValidationError.from_exception_data(exc.title, details)
        except Exception:  # an error type pydantic cannot rebuild (a custom one): keep the original
            raise exc from None
        raise renamed from None
