"""The corridor map: a corridor of width w between two square rooms, straight or bent once at its
middle (thesis section 5.4, Fig. 5.11: straight; Fig. 5.12: a 90 degree bend, the L corridor).

``params`` is any object with ``width``, ``length``, ``bend`` (degrees), ``room`` and
``wall_thickness`` (m): the ``corridor`` generator's validated ``Params``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from .walls import snap, wall_polygons


def corridor_axis(params: Any) -> np.ndarray:
    """(k, 2) corridor axis from the origin east: straight, or bent by ``bend`` at its middle."""
    if params.bend == 0:
        return snap([[0.0, 0.0], [params.length, 0.0]])
    half, turn = params.length / 2, math.radians(params.bend)
    return snap([[0.0, 0.0], [half, 0.0], [half + half * math.cos(turn), half * math.sin(turn)]])


def _room(anchor: np.ndarray, heading: np.ndarray, side: float, behind: bool) -> Polygon:
    """A square of ``side`` whose mid-side sits at ``anchor``, before or after it along ``heading``."""
    t = heading / np.linalg.norm(heading)
    n = np.array([-t[1], t[0]])
    far = anchor + (-side if behind else side) * t
    pts = [anchor + side / 2 * n, far + side / 2 * n, far - side / 2 * n, anchor - side / 2 * n]
    return Polygon(snap(pts)).normalize()


def corridor_free_space(params: Any) -> Any:
    """Entrance room, corridor of width w along :func:`corridor_axis`, exit room (one polygon)."""
    axis = corridor_axis(params)
    corridor = LineString(axis).buffer(params.width / 2, cap_style="flat", join_style="mitre")
    entrance = _room(axis[0], axis[1] - axis[0], params.room, behind=True)
    exit_room = _room(axis[-1], axis[-1] - axis[-2], params.room, behind=False)
    return unary_union([entrance, corridor, exit_room]).normalize()


def corridor(params: Any) -> list[Polygon]:
    """The corridor map's walls."""
    return wall_polygons(corridor_free_space(params), params.wall_thickness)
