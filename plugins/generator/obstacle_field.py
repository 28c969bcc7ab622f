"""The ``obstacle_field`` map generator: round obstacles (pillars, trees) with random sizes at
random places until they cover a given fraction of a rectangle, never inside the declared free
regions (start, goal), seeded. Its sampling is :mod:`swarmscene.methods.maps.field`."""

from typing import Any

from pydantic import Field, field_validator

from swarmscene.methods.maps import obstacle_field
from swarmscene.plugin import MAX_LENGTH, Draw, MapGenerator, Point2, StrictModel, hookimpl, number_adapter, parse_draw


class FreeRegion(StrictModel):
    """A disc that no generated obstacle enters (a start or a goal area)."""

    center: Point2 = Field(description="[x, y], m")
    radius: float = Field(gt=0, le=MAX_LENGTH, description="m")


_RADIUS = number_adapter(0.0, MAX_LENGTH)


class ObstacleFieldParams(StrictModel):
    """``generator: obstacle_field``: random round obstacles (pillars, trees) of a given density."""

    bounds: tuple[float, float, float, float] = Field(
        (0.0, -10.0, 40.0, 10.0), description="[x_min, y_min, x_max, y_max] of the obstacles' centres, m"
    )
    density: float = Field(
        gt=0, le=0.5, description="fraction of the bounds' area the obstacles cover (a disc counts whole)"
    )
    radius: Draw | float = Field(
        description="obstacle radius, m: a number or a distribution with positive values "
        "({uniform: [a, b]} with a > 0, {lognormal: [mu, sigma]}, {exponential: mean}, {choice: [...]})"
    )
    gap: float = Field(0.0, ge=0, le=MAX_LENGTH, description="least distance between two obstacles, m")
    free_regions: list[FreeRegion] = Field(
        default_factory=list, description="discs kept free of obstacles (start and goal areas)"
    )
    seed: int = Field(0, ge=0, description="seed of the map's own stream (not the run's generator)")

    @field_validator("radius", mode="wrap")
    @classmethod
    def _number_or_distribution(cls, value: Any, handler: Any) -> Any:
        radius = parse_draw(value, _RADIUS)
        if not (radius.positive() if isinstance(radius, Draw) else radius > 0):
            raise ValueError("must be a positive number or a distribution of positive values "
                             "(uniform with low > 0, lognormal, exponential, choice of positives)")
        return radius

    @field_validator("bounds")
    @classmethod
    def _ordered(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        if not (value[0] < value[2] and value[1] < value[3]) or max(map(abs, value)) > MAX_LENGTH:
            raise ValueError("must be [x_min, y_min, x_max, y_max] with x_min < x_max, y_min < y_max")
        return value


class ObstacleField(MapGenerator):
    """Round obstacles of random sizes covering a fraction of a rectangle, seeded."""

    name = "obstacle_field"
    Params = ObstacleFieldParams

    @classmethod
    def build(cls, params: Any) -> list:
        """The field's round obstacles (:func:`swarmscene.methods.maps.obstacle_field`), drawn from its
        ``seed``."""
        return obstacle_field(params)


@hookimpl
def swarmscene_register_generators(register):
    """Add :class:`ObstacleField` to the registry, so that ``environment.generator: obstacle_field`` chooses it."""
    register(ObstacleField)
