"""Walls from a free space, as the thesis' maps build them (thesis section 5.4, Appendix A).

The free space is a union of rectangles; each straight piece of its boundary becomes a
``thickness`` rectangle on the outer side, so the free space keeps its exact width and every
clearance equals the distance to a wall face. Vertices are rounded to :data:`DECIMALS` places, so
a generated map equals its listed-obstacle form exactly.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon, box

DECIMALS = 9
"""Decimal places of generated coordinates (1 nm): float sums such as 10.0 + 0.2 land on the
nearest double of the decimal value, as a map written by hand does."""


def snap(value: Any) -> Any:
    """Coordinates rounded to :data:`DECIMALS` places (Python's correctly rounded ``round``)."""
    array = np.asarray(value, dtype=float)
    return np.vectorize(lambda x: round(float(x), DECIMALS) + 0.0, otypes=[float])(array)


def snapped_box(x0: float, y0: float, x1: float, y1: float) -> Polygon:
    """The rectangle [x0, x1] x [y0, y1], its corners rounded by :func:`snap` like every generated
    coordinate, so that boxes built from the same numbers share exact edges."""
    return box(*snap([x0, y0, x1, y1]))


def wall_polygons(free_space: Any, thickness: float) -> list[Polygon]:
    """Each straight piece of the boundary of ``free_space`` as a ``thickness`` rectangle on its
    outer side: the rectangle [a, b, b + t n_out, a + t n_out], in the boundary's order."""
    parts = shapely.get_parts(free_space)
    rings = [ring for part in parts for ring in (part.exterior, *part.interiors)]
    coords = [np.asarray(ring.coords) for ring in rings]
    segments = np.concatenate([np.stack([c[:-1], c[1:]], axis=1) for c in coords])
    a, b = segments[:, 0], segments[:, 1]
    tangent = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    probe = (a + b) / 2 + 1e-6 * normal
    inward = shapely.contains_xy(free_space, probe[:, 0], probe[:, 1])
    out = np.where(inward[:, None], -normal, normal) * thickness
    quads = snap(np.stack([a, b, b + out, a + out, a], axis=1))
    return list(shapely.polygons(quads))
