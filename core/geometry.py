"""Turning validated config into geometry: obstacle footprints and initial positions."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

if TYPE_CHECKING:  # pragma: no cover
    from .config import EnvironmentConfig, ScenarioConfig


def build_obstacles(env: "EnvironmentConfig") -> tuple[list, list[str]]:
    """Shapely polygons for the configured obstacles, and one error line per malformed one."""
    polygons, errors = [], []
    for k, obstacle in enumerate(env.obstacles):
        key = f"environment.obstacles.{k}"
        if obstacle.type == "circle":
            polygons.append(Point(obstacle.center).buffer(obstacle.radius, quad_segs=16))
        elif obstacle.type == "wall":
            line = LineString(obstacle.points)
            if line.length == 0:
                errors.append(f"{key}.points: a wall needs two distinct points (got {obstacle.points})")
                continue
            polygons.append(line.buffer(obstacle.thickness / 2, cap_style="flat", join_style="mitre"))
        else:
            polygon = Polygon(obstacle.points)
            if not polygon.is_valid or polygon.area == 0:
                reason = shapely.is_valid_reason(polygon)
                errors.append(f"{key}.points: malformed polygon ({reason}) (got {obstacle.points})")
                continue
            polygons.append(polygon)
    return polygons, errors


def initial_positions(config: "ScenarioConfig", rng: np.random.Generator) -> np.ndarray:
    """Positions (N, 3) at t = 0 from ``swarm.start`` (see :class:`~swarmscene.core.config.StartConfig`)."""
    start, n = config.swarm.start, config.swarm.n
    center = np.asarray(start.center, dtype=float)
    s = start.spacing
    if start.kind == "explicit":
        return np.asarray(start.positions, dtype=float)
    if start.kind == "line":
        offsets = np.zeros((n, 3))
        offsets[:, 1] = (np.arange(n) - (n - 1) / 2) * s
    elif start.kind == "grid":
        cols = math.ceil(math.sqrt(n))
        k = np.arange(n)
        offsets = np.zeros((n, 3))
        offsets[:, 0] = (k // cols - (math.ceil(n / cols) - 1) / 2) * s
        offsets[:, 1] = (k % cols - (cols - 1) / 2) * s
    elif start.kind == "circle":
        radius = start.radius if start.radius is not None else s * n / (2 * math.pi)
        radius = radius if n > 1 else 0.0
        angle = 2 * math.pi * np.arange(n) / n
        offsets = np.stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(n)], axis=1)
    elif not start.connected:  # random: rejection sampling keeps the run seeded and agents apart
        offsets = _random_spread(n, start.extent, s, rng)
    else:
        offsets = _connected_spread(n, start.extent, s, config.comm.range, rng)
    return center + offsets


CONNECTED_DRAWS = 200
"""Whole-swarm draws tried for ``swarm.start.connected`` before the scenario is refused."""


def _connected_spread(
    n: int, extent: float, spacing: float, comm_range: float, rng: np.random.Generator
) -> np.ndarray:
    """A random spread redrawn whole until its disk graph of radius ``comm_range`` is connected.

    Whole redraws (not moving single agents) keep each draw uniform, so the accepted swarm is a
    uniform draw conditioned on connectivity; a first draw that is connected is returned as is.
    """
    from scipy.spatial import cKDTree

    from .sensing import _components  # the comm graph's own component count

    for _ in range(CONNECTED_DRAWS):
        offsets = _random_spread(n, extent, spacing, rng)
        pairs = cKDTree(offsets).query_pairs(comm_range, output_type="ndarray")
        if _components(n, pairs[:, 0], pairs[:, 1]) == 1:
            return offsets
    raise ValueError(
        f"swarm.start: no connected swarm (comm.range = {comm_range} m) in {CONNECTED_DRAWS} random "
        f"draws of {n} agents {spacing} m apart in a {extent} m square; shrink swarm.start.extent"
    )


def _random_spread(n: int, extent: float, spacing: float, rng: np.random.Generator) -> np.ndarray:
    points = np.empty((0, 2))
    for _ in range(200):
        candidates = rng.uniform(-extent / 2, extent / 2, size=(4 * n, 2))
        for c in candidates:
            if len(points) == n:
                break
            if len(points) == 0 or np.min(np.hypot(*(points - c).T)) >= spacing:
                points = np.vstack([points, c])
        if len(points) == n:
            break
    if len(points) < n:
        raise ValueError(
            f"swarm.start: cannot place {n} agents {spacing} m apart in a {extent} m square"
        )
    return np.column_stack([points, np.zeros(n)])
