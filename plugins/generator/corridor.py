"""The ``corridor`` map generator: a corridor of width w between two square rooms, straight or
bent once at its middle (thesis section 5.4, Fig. 5.11: straight; Fig. 5.12: ``bend: 90``, the L
corridor). Its geometry is :mod:`swarmscene.methods.maps.corridor`."""

from typing import Any

from pydantic import Field

from swarmscene.methods.maps import corridor
from swarmscene.plugin import MAX_LENGTH, MapGenerator, StrictModel, hookimpl


class CorridorParams(StrictModel):
    """``generator: corridor``: thesis section 5.4 (10 m corridors; 6 m rooms are this engine's choice)."""

    width: float = Field(gt=0, le=MAX_LENGTH, description="corridor width w, m")
    length: float = Field(10.0, gt=0, le=MAX_LENGTH, description="corridor length along its axis, m")
    bend: float = Field(
        0.0, gt=-180, lt=180,
        description="turn at the corridor's middle, degrees, positive to the left (90: the L corridor)",
    )
    room: float = Field(6.0, gt=0, le=MAX_LENGTH, description="side of the square room at each end, m")
    wall_thickness: float = Field(0.1, gt=0, le=MAX_LENGTH, description="wall rectangles' thickness, m")


class Corridor(MapGenerator):
    """A corridor of width w between two square rooms, straight or bent once (thesis 5.4)."""

    name = "corridor"
    Params = CorridorParams

    @classmethod
    def build(cls, params: Any) -> list:
        """The corridor's wall polygons (:func:`swarmscene.methods.maps.corridor`)."""
        return corridor(params)


@hookimpl
def swarmscene_register_generators(register):
    """Add :class:`Corridor` to the registry, so that ``environment.generator: corridor`` chooses it."""
    register(Corridor)
