"""The random obstacle field: round obstacles of random sizes at random places until they cover a
given fraction of a rectangle, never inside the declared free regions (start, goal), seeded.

``params`` is any object with ``bounds`` ([x_min, y_min, x_max, y_max] m), ``density``,
``radius`` (a number or a :class:`~swarmscene.core.distributions.Draw`), ``gap`` (m),
``free_regions`` (each with ``center`` and ``radius``) and ``seed``: the ``obstacle_field``
generator's validated ``Params``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from shapely.geometry import Point, Polygon

from swarmscene.core.distributions import MAP_STREAM, Draw, stream

MAX_FIELD_CANDIDATES = 200_000
"""Random obstacles tried by ``obstacle_field`` before a density is refused as out of reach."""
FIELD_BATCH = 1024
"""Candidate obstacles drawn at once by ``obstacle_field``."""


def obstacle_field_discs(params: Any) -> tuple[np.ndarray, np.ndarray]:
    """Centres (M, 2) and radii (M,) of the field, m.

    Random sequential addition: candidates (centre uniform in ``bounds``, radius from ``radius``)
    are drawn in batches from the map's stream and taken in order when they keep ``gap`` from every
    obstacle taken before and stay out of every free region, until the obstacles' area reaches
    ``density`` x the bounds' area (the last one may pass it by its own area). Raises ValueError
    naming ``environment.density`` when :data:`MAX_FIELD_CANDIDATES` candidates do not reach it.
    """
    rng = stream(params.seed, MAP_STREAM)
    x0, y0, x1, y1 = params.bounds
    target = params.density * (x1 - x0) * (y1 - y0)
    free_c = np.array([r.center for r in params.free_regions], dtype=float).reshape(-1, 2)
    free_r = np.array([r.radius for r in params.free_regions], dtype=float)
    centres, radii = np.empty((0, 2)), np.empty(0)
    area, tried = 0.0, 0
    while area < target and tried < MAX_FIELD_CANDIDATES:
        cand = np.column_stack([rng.uniform(x0, x1, FIELD_BATCH), rng.uniform(y0, y1, FIELD_BATCH)])
        size = (params.radius.sample(rng, FIELD_BATCH) if isinstance(params.radius, Draw)
                else np.full(FIELD_BATCH, params.radius))
        tried += FIELD_BATCH
        ok = _clear_of(cand, size, free_c, free_r, 0.0) & _clear_of(cand, size, centres, radii, params.gap)
        taken = _take_in_order(cand[ok], size[ok], params.gap, target - area)
        centres, radii = np.concatenate([centres, cand[ok][taken]]), np.concatenate([radii, size[ok][taken]])
        area = float(np.sum(np.pi * radii**2))
    if area < target:
        raise ValueError(
            f"environment.density: obstacles of this radius and gap cover only "
            f"{area / (target / params.density):.3g} of the bounds after {MAX_FIELD_CANDIDATES} "
            f"random tries (got {params.density}; lower density or gap)"
        )
    return centres, radii


def _clear_of(cand: np.ndarray, size: np.ndarray, centres: np.ndarray, radii: np.ndarray,
              gap: float) -> np.ndarray:
    """(B,) bool: candidate discs at least ``gap`` from every disc (centres, radii): one k-d tree
    query for the batch."""
    from scipy.spatial import cKDTree

    clear = np.ones(len(cand), dtype=bool)
    if len(centres) == 0:
        return clear
    reach = float(size.max() + radii.max() + gap)
    pairs = cKDTree(centres).sparse_distance_matrix(cKDTree(cand), reach, output_type="ndarray")
    hit = pairs["v"] < radii[pairs["i"]] + size[pairs["j"]] + gap
    clear[pairs["j"][hit]] = False
    return clear


def _take_in_order(cand: np.ndarray, size: np.ndarray, gap: float, area_left: float) -> np.ndarray:
    """Indices of the candidates the sequential rule takes among themselves, until their area
    reaches ``area_left`` (candidates already clear of the obstacles taken before)."""
    taken: list[int] = []
    area = 0.0
    for k in range(len(cand)):  # few survive near saturation; generation runs once per run
        if taken:
            d = np.hypot(*(cand[taken] - cand[k]).T)
            if np.any(d < size[taken] + size[k] + gap):
                continue
        taken.append(k)
        area += math.pi * size[k] ** 2
        if area >= area_left:
            break
    return np.asarray(taken, dtype=int)


def obstacle_field(params: Any) -> list[Polygon]:
    """The field's discs as polygons (the same 16-segment quarter circles as a listed circle)."""
    centres, radii = obstacle_field_discs(params)
    return [Point(c).buffer(r, quad_segs=16) for c, r in zip(centres, radii, strict=True)]
