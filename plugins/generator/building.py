"""The ``building`` map generator: a floor with start and end halls and a ring corridor around a
block of rooms, each with a door open or closed (thesis Appendix A: ``rooms: 4``). Its geometry is
:mod:`swarmscene.methods.maps.building`."""

from typing import Any

from pydantic import Field, field_validator, model_validator

from swarmscene.methods.maps import building
from swarmscene.plugin import MAX_LENGTH, MapGenerator, StrictModel, hookimpl, key_error


class BuildingParams(StrictModel):
    """``generator: building``: thesis Appendix A (four rooms: a 28 m x 22 m floor)."""

    # first, as the corridor's: a run's config.yaml has recorded the parameters in this order
    wall_thickness: float = Field(0.1, gt=0, le=MAX_LENGTH, description="wall rectangles' thickness, m")
    rooms: int = Field(4, ge=2, le=1000, description="rooms in the central block, two rows (even)")
    doors_open: bool = Field(False, description="each room's door onto the ring corridor is open")
    door_width: float = Field(0.9, gt=0, le=MAX_LENGTH, description="m")
    room_size: tuple[float, float] = Field(
        (7.2, 7.7), description="[along the rows (east), across (north)] of each room, m"
    )
    corridor_width: float = Field(3.0, gt=0, le=MAX_LENGTH, description="ring corridor width, m")
    hall: float = Field(
        10.0, gt=0, le=MAX_LENGTH, description="east-west depth of the start and end halls, m"
    )

    @field_validator("rooms")
    @classmethod
    def _even(cls, value: int) -> int:
        if value % 2:
            raise ValueError("must be even (two rows of rooms)")
        return value

    @field_validator("room_size")
    @classmethod
    def _positive(cls, value: tuple[float, float]) -> tuple[float, float]:
        if min(value) <= 0 or max(value) > MAX_LENGTH:
            raise ValueError(f"must be two lengths in (0, {MAX_LENGTH:g}] m")
        return value

    @model_validator(mode="after")
    def _door_fits(self) -> "BuildingParams":
        if self.door_width >= self.room_size[0]:
            width = self.room_size[0]
            raise key_error("door_width", f"must be < the room's width {width} m", self.door_width)
        return self


class Building(MapGenerator):
    """A floor with start and end halls and a ring corridor around rooms (thesis Appendix A)."""

    name = "building"
    Params = BuildingParams

    @classmethod
    def build(cls, params: Any) -> list:
        """The building's wall polygons (:func:`swarmscene.methods.maps.building`)."""
        return building(params)


@hookimpl
def swarmscene_register_generators(register):
    """Add :class:`Building` to the registry, so that ``environment.generator: building`` chooses it."""
    register(Building)
