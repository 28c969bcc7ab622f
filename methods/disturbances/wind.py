"""What the wind models (``constant_wind``, ``gust``, ``dryden``) share: their options and directions.

A wind model returns the air's velocity at each agent; the kernel sums the models' and applies the
sum as a force on the dynamics (:mod:`swarmscene.core.disturbances`, "wind phase"), with the
moment arm of the largest (``moment_arm``, which the engine reads from every wind model's options).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from swarmscene.core.disturbances.base import DisturbanceParams

MAX_WIND = 100.0
"""m/s: the largest wind speed a model accepts (a category-5 hurricane is ~70 m/s)."""


class WindParams(DisturbanceParams):
    """Options shared by the wind models."""

    heading: float = Field(
        0.0, ge=-360.0, le=360.0,
        description="direction the wind blows toward, degrees counter-clockwise from +x (east)")
    moment_arm: float = Field(
        0.0, ge=-1.0, le=1.0,
        description="height of the centre of pressure above the centre of gravity, m: models with "
        "attitude (quadrotor) take the moment r x F of the wind's force there (0: force only)")


def direction(heading_deg: float, elevation_deg: float = 0.0) -> np.ndarray:
    """The unit vector (3,) toward ``heading_deg`` (counter-clockwise from +x) and ``elevation_deg``
    above the horizontal."""
    h, e = math.radians(heading_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(h), math.cos(e) * math.sin(h), math.sin(e)])
