"""The building map: a floor with a start hall and an end hall on its west side and a ring
corridor around a block of rooms in two rows, each room with a door on the corridor, open or
closed (thesis Appendix A: four rooms, a 28 m x 22 m floor).

``params`` is any object with ``rooms`` (even), ``doors_open``, ``door_width``, ``room_size``
([east, north]), ``corridor_width``, ``hall`` and ``wall_thickness`` (m): the ``building``
generator's validated ``Params``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from shapely.geometry import Polygon
from shapely.ops import unary_union

from .walls import snapped_box, wall_polygons

PARTITION = 0.2
"""Thickness of the walls of the building's block of rooms, m (thesis Appendix A plan)."""
SEPARATION = 2.0
"""Depth of the wall block between the building's start and end halls, m."""
DOOR_OVERLAP = 0.1
"""How far a door opening reaches past each face of the wall it cuts, m (a clean cut)."""


def building_free_space(params: Any) -> Any:
    """The floor minus the block of rooms (rooms hollow, doors cut when open) and the wall block
    between the halls. Layout, x east: halls [0, hall], block from x = hall, ring corridor around
    it; y north: the block between corridors of ``corridor_width``, the halls split at mid-height."""
    per_row = params.rooms // 2
    rx, ry = params.room_size
    p, c = PARTITION, params.corridor_width
    block_w, block_h = per_row * rx + (per_row + 1) * p, 2 * ry + 3 * p
    width, height = params.hall + block_w + c, block_h + 2 * c
    x0 = params.hall + p + np.arange(per_row) * (rx + p)  # each column's west wall face
    rows = [(c + 2 * p + ry, c + 2 * p + 2 * ry), (c + p, c + p + ry)]  # north row, south row
    rooms = [snapped_box(x, y0, x + rx, y1) for y0, y1 in rows for x in x0]
    mid = x0 + rx / 2
    door_rows = [(rows[0][1] - DOOR_OVERLAP, c + block_h + DOOR_OVERLAP),
                 (c - DOOR_OVERLAP, rows[1][0] + DOOR_OVERLAP)]
    doors = [snapped_box(m - params.door_width / 2, y0, m + params.door_width / 2, y1)
             for y0, y1 in door_rows for m in mid]
    block = snapped_box(params.hall, c, params.hall + block_w, c + block_h)
    solid = block.difference(unary_union(rooms + (doors if params.doors_open else [])))
    separation = snapped_box(0.0, (height - SEPARATION) / 2, params.hall, (height + SEPARATION) / 2)
    return snapped_box(0.0, 0.0, width, height).difference(unary_union([solid, separation])).normalize()


def building(params: Any) -> list[Polygon]:
    """The building map's walls."""
    return wall_polygons(building_free_space(params), params.wall_thickness)
