"""The observation of each agent: what it can sense this tick, as one float32 row per agent.

Row layout (``ObservationLayout``, k = ``neighbours``; world frame, SI units, nothing normalised):

    own_pos        3   position p_i, m
    own_vel        3   velocity v_i, m/s
    healthy        1   1 while the agent flies, 0 once failed
    nbr_pos      3 k   p_j - p_i of the k nearest other agents within the sensing range R, m,
                       nearest first, zero-padded
    nbr_vel      3 k   v_j - v_i of the same agents, m/s, zero-padded
    nbr_mask       k   1 where a neighbour is present, 0 for padding
    obs_clearance  1   signed clearance to the nearest obstacle within R_o, m (R_o when none)
    obs_dir        3   unit vector from the agent to that obstacle's nearest point (x-y plane; 0 when none
                       or inside)
    obs_mask       1   1 when an obstacle is within R_o
    ref_offset     3   p_ref - p_i, the formation's reference position minus the agent's, m
                       (0 when the reference has no position: VELOCITY or HOLD)
    ref_vel        3   the reference's velocity (command or feed-forward), m/s
    ref_mask       1   1 when ``ref_offset`` holds a position reference (POSITION or TRACK)

The reference is the formation's setpoint of the previous guidance tick (none at t = 0): the
kernel runs the formation inside the tick, after the observation of its start was taken, so
both the environment and the ``policy`` plugin observe the last one known. Failed neighbours are
sensed like the others (they still occupy space).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from swarmscene.core.sensing import NEAR_K
from swarmscene.core.setpoint import Mode, Setpoints, is_mode
from swarmscene.core.state import WorldState

OWN = (("own_pos", 3), ("own_vel", 3), ("healthy", 1))
OBSTACLE = (("obs_clearance", 1), ("obs_dir", 3), ("obs_mask", 1))
REFERENCE = (("ref_offset", 3), ("ref_vel", 3), ("ref_mask", 1))


@dataclass(frozen=True)
class ObservationLayout:
    """Where each feature block sits in an observation row of ``k`` neighbours."""

    k: int

    @property
    def blocks(self) -> tuple[tuple[str, int], ...]:
        """Each feature block's name and width, in row order (own state, k neighbours, obstacle, reference)."""
        k = self.k
        return (*OWN, ("nbr_pos", 3 * k), ("nbr_vel", 3 * k), ("nbr_mask", k), *OBSTACLE, *REFERENCE)

    @property
    def size(self) -> int:
        """Length D of a row: 19 + 7 k."""
        return sum(width for _, width in self.blocks)

    def slices(self) -> dict[str, slice]:
        """Each feature block's slice of a row, by name."""
        out, start = {}, 0
        for name, width in self.blocks:
            out[name] = slice(start, start + width)
            start += width
        return out

    def split(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """Views of each block of ``obs`` (N, D): ``nbr_pos``/``nbr_vel`` as (N, k, 3)."""
        parts = {name: obs[..., s] for name, s in self.slices().items()}
        for name in ("nbr_pos", "nbr_vel"):
            parts[name] = parts[name].reshape(*obs.shape[:-1], self.k, 3)
        return parts


def nearest_neighbours(sensing, k: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices (N, k) of each agent's k nearest others within ``radius`` (N where missing), and a
    mask (N, k) of the present ones. Up to ``NEAR_K`` neighbours this is the tick's shared kNN
    query (``Sensing.knn``, which the separation check also reads); more take one query of the
    shared k-d tree."""
    world = sensing.world
    n = world.n
    if k == 0 or n < 2:
        return np.full((n, k), n), np.zeros((n, k), dtype=bool)
    if k <= NEAR_K:
        dist, idx = sensing.knn
        return _within(dist, idx, k, radius, n)
    q = min(k + 1, n)
    _, idx = sensing.tree.query(world.pos, k=q, distance_upper_bound=radius)
    idx = idx.reshape(n, q)
    # Drop the agent itself (not always column 0: agents may coincide) and keep the order.
    valid = (idx < n) & (idx != np.arange(n)[:, None])
    order = np.argsort(~valid, axis=1, kind="stable")
    idx = np.take_along_axis(np.where(valid, idx, n), order, axis=1)[:, :k]
    return _padded(idx, idx < n, k, n)


def _within(dist: np.ndarray, idx: np.ndarray, k: int, radius: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`nearest_neighbours` from the shared query's distances and indices (..., N, <= NEAR_K):
    one world's, or B worlds' stacked (elementwise, the same bits)."""
    mask = dist[..., :k] <= radius
    return _padded(np.where(mask, idx[..., :k], n), mask, k, n)


def _padded(idx: np.ndarray, mask: np.ndarray, k: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``idx`` and ``mask`` (..., N, <= k) padded to k neighbours (index N, absent) where there are
    fewer other agents than k."""
    if idx.shape[-1] < k:
        pad = ((0, 0),) * (idx.ndim - 1) + ((0, k - idx.shape[-1]),)
        idx, mask = np.pad(idx, pad, constant_values=n), np.pad(mask, pad)
    return idx, mask


def obstacle_features(sensing, radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clearance (N,) (``radius`` where none is in range), unit direction (N, 3) to the nearest
    obstacle point and mask (N,), from the tick's shared obstacle query."""
    world, env = sensing.world, sensing.environment
    n = world.n
    clearance = np.full(n, radius)
    direction = np.zeros((n, 3))
    if env.empty:
        return clearance, direction, np.zeros(n, dtype=bool)
    index, signed = sensing.obstacle_nearest(radius)
    near = index >= 0
    clearance[near] = signed[near]
    if near.any():
        xy = world.pos[near, :2]
        geoms = np.array(env.obstacles, dtype=object)[index[near]]
        lines = shapely.shortest_line(geoms, shapely.points(xy))
        closest = shapely.get_coordinates(lines).reshape(-1, 2, 2)[:, 0, :]
        gap = closest - xy
        length = np.linalg.norm(gap, axis=1, keepdims=True)
        direction[near, :2] = np.divide(gap, length, out=np.zeros_like(gap), where=length > 0)
    return clearance, direction, near


def reference_features(world: WorldState, ref: Setpoints | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offset p_ref - p_i (N, 3), reference velocity (N, 3) and position-reference mask (N,)."""
    n = world.n
    if ref is None:
        return np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, dtype=bool)
    return _reference_rows(world.pos, ref.mode, ref.pos, ref.vel)


def _reference_rows(pos: np.ndarray, mode: np.ndarray, ref_pos: np.ndarray, ref_vel: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`reference_features` from the positions (..., 3) and the reference's mode (...,),
    positions and velocities (..., 3): one world's, or B worlds' stacked (elementwise, the same bits)."""
    has_pos = is_mode(mode, Mode.POSITION, Mode.TRACK)
    offset = np.where(has_pos[..., None], ref_pos - pos, 0.0)
    has_vel = is_mode(mode, Mode.VELOCITY, Mode.TRACK, Mode.POSITION)
    return offset, np.where(has_vel[..., None], ref_vel, 0.0), has_pos


def observe(
    sensing, ref: Setpoints | None, layout: ObservationLayout, radius: float, obstacle_radius: float
) -> np.ndarray:
    """Every agent's observation row, shape (N, D) float32 (see the module docstring)."""
    world = sensing.world
    idx, mask = nearest_neighbours(sensing, layout.k, radius)
    features = (*obstacle_features(sensing, obstacle_radius), *reference_features(world, ref))
    return _rows(world.pos[None], world.vel[None], world.healthy[None], idx[None], mask[None],
                 tuple(a[None] for a in features))[0]  # one world: B = 1


def _rows(pos: np.ndarray, vel: np.ndarray, healthy: np.ndarray, idx: np.ndarray, mask: np.ndarray,
          features: tuple[np.ndarray, ...]) -> np.ndarray:
    """The rows (B, N, D) float32 of B worlds (one, for :func:`observe`): their agents' states,
    neighbour slots (``idx``, ``mask``: (B, N, k)) and the obstacle and reference features (clearance,
    direction, near, offset, reference velocity, mask), in the layout's order. Each feature is one
    elementwise pass over the B N rows (a gather, a difference, a choice, the float32 cast),
    nothing whose bits depend on the array's length."""
    b, n, k = idx.shape
    safe = np.where(mask, idx, 0)
    worlds = np.arange(b)[:, None, None]
    nbr_pos = np.where(mask[..., None], pos[worlds, safe] - pos[:, :, None, :], 0.0)
    nbr_vel = np.where(mask[..., None], vel[worlds, safe] - vel[:, :, None, :], 0.0)
    clearance, direction, near, offset, ref_vel, has_ref = features
    return np.concatenate(
        [
            pos, vel, healthy[..., None],
            nbr_pos.reshape(b, n, 3 * k), nbr_vel.reshape(b, n, 3 * k), mask,
            clearance[..., None], direction, near[..., None],
            offset, ref_vel, has_ref[..., None],
        ],
        axis=2,
        dtype=np.float32,
    )


def observe_batch(
    sensings: Sequence, refs: Sequence[Setpoints | None], layout: ObservationLayout, radius: float,
    obstacle_radius: float,
) -> np.ndarray:
    """:func:`observe` of B worlds of N agents each, shape (B, N, D) float32: world b's rows are the
    bits of ``observe(sensings[b], refs[b], ...)``.

    The worlds' states, nearest neighbours (``Sensing.knn``, which a batch answers ahead for
    small worlds) and references are stacked, and the rows made as :func:`observe` makes one
    world's (:func:`_rows`). The obstacle features are each world's own, but constants where no
    obstacle is in range (``Sensing.nothing_within``).
    More neighbours than the shared query holds (``NEAR_K``), none, or fewer than two agents are
    observed world by world. The worlds must have one N (a ``ValueError`` otherwise)."""
    n, k = sensings[0].world.n, layout.k
    if any(s.world.n != n for s in sensings):
        raise ValueError(f"observe_batch: worlds of {sorted({s.world.n for s in sensings})} agents cannot be stacked")
    if k > NEAR_K or k == 0 or n < 2:
        return np.stack([observe(s, ref, layout, radius, obstacle_radius)
                         for s, ref in zip(sensings, refs, strict=True)])
    b = len(sensings)
    pos, vel, healthy = (np.stack([getattr(s.world, name) for s in sensings]) for name in ("pos", "vel", "healthy"))
    idx, mask = _within(np.stack([s.knn[0] for s in sensings]), np.stack([s.knn[1] for s in sensings]), k, radius, n)
    # what obstacle_features gives where no obstacle is in range; the other worlds' own
    clearance, direction, near = np.full((b, n), obstacle_radius), np.zeros((b, n, 3)), np.zeros((b, n), dtype=bool)
    for w, s in enumerate(sensings):
        if not (s.environment.empty or s.nothing_within(obstacle_radius)):
            clearance[w], direction[w], near[w] = obstacle_features(s, obstacle_radius)
    if any(ref is None for ref in refs):
        offset, ref_vel, has_ref = (np.stack(f) for f in zip(
            *(reference_features(s.world, ref) for s, ref in zip(sensings, refs, strict=True)), strict=True))
    else:
        offset, ref_vel, has_ref = _reference_rows(pos, *(np.stack([getattr(ref, name) for ref in refs])
                                                         for name in ("mode", "pos", "vel")))
    return _rows(pos, vel, healthy, idx, mask, (clearance, direction, near, offset, ref_vel, has_ref))
