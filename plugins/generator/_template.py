"""Template of a map generator: copy this file, rename the class and ``name``, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package (or
in swarmscene/builtins.py for a built-in) and check it with
``swarmscene.testing.check_generator(MyGenerator)`` in your tests. Its parameters sit beside
``environment.generator`` (``environment.pillars=8``), so a map is swept like any option.
"""

from __future__ import annotations

from pydantic import Field
from shapely.geometry import box

from swarmscene.plugin import MapGenerator, StrictModel, hookimpl


class MyGenerator(MapGenerator):
    """A row of square pillars along +x, ``pitch`` apart."""

    name = "my_generator"

    class Params(StrictModel):
        pillars: int = Field(4, ge=1, le=1000, description="how many pillars")
        pitch: float = Field(4.0, gt=0, le=1e4, description="distance between pillar centres, m")
        side: float = Field(1.0, gt=0, le=1e4, description="side of each square pillar, m")

    @classmethod
    def build(cls, params):
        """The obstacle footprints (shapely polygons, m); a ValueError("environment.<key>: ...")
        names the parameter a map cannot be built from."""
        h = params.side / 2
        return [box(k * params.pitch - h, -h, k * params.pitch + h, h) for k in range(params.pillars)]


@hookimpl
def swarmscene_register_generators(register):
    register(MyGenerator)
