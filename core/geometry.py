"""Turning validated config into geometry: obstacle footprints and initial positions.

This module knows the config only by the attributes it reads (``env.obstacles``, ``env.generator``,
``config.swarm``, ``config.comm.range``): it does not import :mod:`swarmscene.core.config`, which
calls it during validation (:func:`swarmscene.core.validation.validate` builds the obstacles and the
start positions once and hands them to the simulation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon


def build_obstacles(env: Any) -> tuple[list, list[str]]:
    """Shapely polygons for an ``EnvironmentConfig``: its generator's (if it has one, a registered
    :class:`~swarmscene.core.generators.MapGenerator`), then its listed ``obstacles``; and one error line per
    malformed obstacle or unbuildable map."""
    polygons, errors = env.generated() if hasattr(env, "generated") else ([], [])
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


def initial_positions(config: Any, rng: np.random.Generator) -> np.ndarray:
    """Positions (N, 3), m, at t = 0 from ``config.swarm.start`` (a ``ScenarioConfig``; see
    :class:`~swarmscene.core.config.StartConfig`). Raises ValueError with one line on a start
    that cannot be drawn."""
    start, n = config.swarm.start, config.swarm.n
    center = np.asarray(start.center, dtype=float)
    s = start.spacing
    if start.layout == "explicit":
        return np.asarray(start.positions, dtype=float)
    if start.layout == "line":
        offsets = np.zeros((n, 3))
        offsets[:, 1] = (np.arange(n) - (n - 1) / 2) * s
    elif start.layout == "grid":
        cols = math.ceil(math.sqrt(n))
        k = np.arange(n)
        offsets = np.zeros((n, 3))
        offsets[:, 0] = (k // cols - (math.ceil(n / cols) - 1) / 2) * s
        offsets[:, 1] = (k % cols - (cols - 1) / 2) * s
    elif start.layout == "circle":
        radius = start.radius if start.radius is not None else s * n / (2 * math.pi)
        radius = radius if n > 1 else 0.0
        angle = 2 * math.pi * np.arange(n) / n
        offsets = np.stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(n)], axis=1)
    elif not start.connected:  # random: rejection sampling keeps the run seeded and agents apart
        offsets = random_spread(n, start.extent, s, rng)
    else:
        offsets = connected_spread(n, start.extent, s, config.comm.range, rng)
    return center + offsets


# -- random starts ------------------------------------------------------------------------------
SPREAD_ROUNDS = 200
"""Rounds of ``4 N`` candidate draws tried for a random start before the scenario is refused."""
CONNECTED_DRAWS = 200
"""Whole-swarm draws tried for ``swarm.start.connected`` before the scenario is refused."""
PAIR_BUDGET = 4_000_000
"""Expected close candidate pairs resolved at once (bounds the sampler's memory, ~100 MB)."""


def max_spread(extent: float, spacing: float) -> int:
    """Most points pairwise at least ``spacing`` apart in a square of side ``extent`` (Groemer's
    inequality for a convex region of area A and perimeter P: n <= 2 A / (sqrt(3) s^2) + P / (2 s) + 1)."""
    ratio = extent / spacing
    if ratio > 1e9:  # room for more agents than any scenario may have (and no float overflow)
        return 10**18
    return int(math.floor(2.0 / math.sqrt(3.0) * ratio * ratio + 2.0 * ratio + 1.0 + 1e-9))


def random_spread(n: int, extent: float, spacing: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` points (n, 3), z = 0, uniform in a square of side ``extent`` and ``spacing`` apart.

    Each round draws ``4 n`` candidates and accepts them greedily in order: a candidate is taken
    when it is at least ``spacing`` from every point taken before it (earlier rounds and earlier
    candidates of its round), until ``n`` are taken. The order-dependent greedy rule is resolved
    for all candidates of a round at once: candidates too close to an earlier round's points are
    dropped (k-d tree), then the conflicts among the rest decide in a few vectorised sweeps (a
    candidate is taken once every earlier conflicting candidate is dropped, dropped once one is
    taken). The draws and the rule are those of a one-by-one loop, so the positions are the same
    for the same seed. A count that cannot fit (:func:`max_spread`) is refused without drawing.
    """
    if n > max_spread(extent, spacing):
        raise ValueError(
            f"swarm.start: cannot place {n} agents {spacing} m apart in a {extent} m square "
            f"(at most {max_spread(extent, spacing)} fit; raise swarm.start.extent)"
        )
    points = np.empty((0, 2))
    for _ in range(SPREAD_ROUNDS):
        candidates = rng.uniform(-extent / 2, extent / 2, size=(4 * n, 2))
        points = _accept_in_order(points, candidates, n, spacing, extent)
        if len(points) == n:
            break
    if len(points) < n:
        raise ValueError(f"swarm.start: cannot place {n} agents {spacing} m apart in a {extent} m square")
    return np.column_stack([points, np.zeros(n)])


def _accept_in_order(
    points: np.ndarray, candidates: np.ndarray, n: int, spacing: float, extent: float
) -> np.ndarray:
    """``points`` extended by the candidates the one-by-one greedy rule takes, up to ``n`` in all.

    The candidates are resolved in consecutive blocks (the rule is sequential, so a block only
    needs the points taken before it), each about as long as the acceptance rate of the previous
    block says it takes to reach ``n``: a sparse start resolves ``n`` candidates, not ``4 n``.
    Expected close pairs among B uniform candidates are B^2 pi s^2 / (2 A), so a block is also
    capped to keep them near :data:`PAIR_BUDGET`.
    """
    ratio = min(extent / spacing, 1e9)
    cap = max(1024.0, ratio * math.sqrt(PAIR_BUDGET * 2.0 / math.pi))
    start, rate = 0, 1.0
    while start < len(candidates) and len(points) < n:
        need = n - len(points)
        size = int(min(len(candidates) - start, cap, max(1024.0, 1.25 * need / rate)))
        taken = _greedy_block(points, candidates[start:start + size], spacing)
        rate = max(len(taken) / size, 1e-9)
        points = np.concatenate([points, taken[:need]])
        start += size
    return points


def _close(a: np.ndarray, b: np.ndarray, spacing: float) -> np.ndarray:
    """Which pairs of rows are closer than ``spacing``, by the one-by-one loop's own distance."""
    return np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1]) < spacing


def _greedy_block(points: np.ndarray, cand: np.ndarray, spacing: float) -> np.ndarray:
    """Candidates of ``cand`` (in order) the greedy rule takes, given the already taken ``points``."""
    from scipy.spatial import cKDTree

    reach = spacing * (1.0 + 1e-9)  # the tree's distances may differ from hypot's in the last bit
    alive = np.ones(len(cand), dtype=bool)
    # Unbalanced, non-compact trees build several times faster and answer these queries as fast.
    cand_tree = cKDTree(cand, balanced_tree=False, compact_nodes=False)
    if len(points):
        points_tree = cKDTree(points, balanced_tree=False, compact_nodes=False)
        hits = points_tree.sparse_distance_matrix(cand_tree, reach, output_type="ndarray")
        near = _close(points[hits["i"]], cand[hits["j"]], spacing)
        alive[hits["j"][near]] = False
    pairs = cand_tree.query_pairs(reach, output_type="ndarray")
    if len(pairs):
        pairs = pairs[_close(cand[pairs[:, 0]], cand[pairs[:, 1]], spacing)]
        first, second = pairs.min(axis=1), pairs.max(axis=1)
        keep = alive[first] & alive[second]
        first, second = first[keep], second[keep]
    else:
        first = second = np.empty(0, dtype=np.intp)
    # state: 1 taken, -1 dropped, 0 undecided; a candidate waits on its earlier conflicting ones.
    state = np.where(alive, 0, -1).astype(np.int8)
    while (state == 0).any():
        blocking = np.bincount(second[state[first] != -1], minlength=len(cand))
        state[(state == 0) & (blocking == 0)] = 1
        beaten = np.zeros(len(cand), dtype=bool)
        beaten[second[state[first] == 1]] = True
        state[(state == 0) & beaten] = -1
    return cand[state == 1]


def connected_spread(
    n: int, extent: float, spacing: float, comm_range: float, rng: np.random.Generator
) -> np.ndarray:
    """A random spread redrawn whole until its disk graph of radius ``comm_range`` is connected.

    Whole redraws (not moving single agents) keep each draw uniform, so the accepted swarm is a
    uniform draw conditioned on connectivity; a first draw that is connected is returned as is.
    Agents ``spacing`` apart can never link when ``comm_range`` is shorter: refused without drawing.
    """
    from scipy.spatial import cKDTree

    if n > 1 and comm_range < spacing:
        raise ValueError(
            f"swarm.start: agents {spacing} m apart cannot link at comm.range = {comm_range} m "
            "(swarm.start.connected needs comm.range >= swarm.start.spacing)"
        )
    for _ in range(CONNECTED_DRAWS):
        offsets = random_spread(n, extent, spacing, rng)
        pairs = cKDTree(offsets).query_pairs(comm_range, output_type="ndarray")
        if component_count(n, pairs) == 1:
            return offsets
    raise ValueError(
        f"swarm.start: no connected swarm (comm.range = {comm_range} m) in {CONNECTED_DRAWS} random "
        f"draws of {n} agents {spacing} m apart in a {extent} m square; shrink swarm.start.extent"
    )


def component_count(n: int, pairs: np.ndarray) -> int:
    """Connected components of the graph on ``n`` nodes with edges ``pairs`` (E, 2)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(pairs) < n - 1:
        return 2  # a spanning tree needs n - 1 edges
    graph = coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return int(connected_components(graph, directed=False)[0])
