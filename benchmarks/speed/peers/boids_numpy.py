"""Reynolds boids in plain numpy + scipy's cKDTree: the reference the engine's flock is measured against.

    python benchmarks/speed/peers/boids_numpy.py START.npz STEPS PARAMS_JSON   # one run, one JSON line

Written independently of swarmscene (it imports only numpy and scipy): the rules of Reynolds (1987)
as Mesa's BoidFlockers states them, for boids i with heading d_i and neighbours N_i within
``vision`` (minimum image in the torus)::

    c_i = cohere * sum_{j in N_i} (p_j - p_i)
    s_i = -separate * sum_{j in N_i, |p_j - p_i| < separation} (p_j - p_i)
    m_i = match * sum_{j in N_i} d_j
    d_i <- (d_i + (c_i + s_i + m_i) / |N_i|) / |...|         (when N_i is not empty)
    p_i <- p_i + speed * d_i * dt,  folded back into the box [0, L)^2

all boids at once from one snapshot; the flock is planar (z held). The work per step is the
engine's per tick for ``scenario=flocking``: the flock, the motion (a kinematic point flying the
velocity command ``speed * d_i``, its norm clipped at ``u_max``), and a safety monitor measuring
after every step what the engine's does (the smallest distance between two boids, the distinct
pairs closer than ``separation_limit``, whether the communication graph within ``comm_range`` is
connected). Distances for the monitor are Euclidean in the box, as the engine's are.

How, in numpy: one k-d tree per step over the positions (3-D, z constant, as the engine's), one
``query_pairs`` at the widest range anyone needs (``comm_range`` >= ``vision``) serving the monitor
and, filtered to ``vision``, the flock; the pairs through the torus' seams from the images of the
boids near a face queried against the same tree; each unordered pair visited once and feeding both
ends (delta_ji = -delta_ij) through ``np.bincount``; connectivity by
``scipy.sparse.csgraph.connected_components`` on the pair list.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class BoidParams:
    """The flocking preset's values (the runner reads them from the composed scenario)."""

    vision: float = 10.0  # m
    separation: float = 2.0  # m
    cohere: float = 0.03
    separate: float = 0.015
    match: float = 0.05
    speed: float = 1.0  # m/s
    dt: float = 1.0  # s per step
    box: float = 100.0  # m, side of the torus on x and y
    u_max: float = 2.0  # m/s, the kinematic point's speed limit
    comm_range: float = 20.0  # m
    separation_limit: float = 0.3  # m


# -- neighbours ---------------------------------------------------------------------------
SHIFTS = np.array([[1, -1], [1, 0], [1, 1], [0, 1]])
"""Half of the 8 neighbouring images of the 2-D torus, in box units: an unordered pair across a
seam is met through exactly one of them (vision < L / 2)."""


def seam_pairs(pos: np.ndarray, tree: cKDTree, box: float, radius: float):
    """Pairs (i, j) within ``radius`` through the seams and their vectors p_j - (p_i + shift), (2, M)."""
    agents, images = [], []
    for shift in SHIFTS:
        near = np.ones(len(pos), dtype=bool)
        for k in (0, 1):
            if shift[k] > 0:
                near &= pos[:, k] <= radius
            elif shift[k] < 0:
                near &= pos[:, k] >= box - radius
        idx = np.flatnonzero(near)
        image = pos[idx].copy()
        image[:, :2] += shift * box
        agents.append(idx)
        images.append(image)
    agents_all, images_all = np.concatenate(agents), np.concatenate(images)
    if agents_all.size == 0:
        return np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((2, 0))
    hits = cKDTree(images_all).sparse_distance_matrix(tree, radius, output_type="ndarray")
    row, j = hits["i"], hits["j"]
    delta = np.ascontiguousarray((pos[j, :2] - images_all[row, :2]).T)
    return agents_all[row], j, delta


def pair_vectors(pos: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """p_j - p_i on x and y, axis-major (2, M)."""
    out = np.empty((2, len(i)))
    for k in (0, 1):
        col = np.ascontiguousarray(pos[:, k])
        np.subtract(col.take(j), col.take(i), out=out[k])
    return out


# -- the rules ----------------------------------------------------------------------------
def steer(i, j, delta, heading, p: BoidParams):
    """c_i + s_i + m_i (N, 3) and |N_i| (N,) from unordered pairs i, j with delta = p_j - p_i (2, M)."""
    n = len(heading)
    total = np.zeros((n, 3))
    if len(i) == 0:
        return total, np.zeros(n)
    close = np.flatnonzero(np.einsum("km,km->m", delta, delta) < p.separation * p.separation)
    ci, cj = i[close], j[close]
    for k in (0, 1):
        d_k = delta[k]
        h_k = np.ascontiguousarray(heading[:, k])
        to_i = p.cohere * d_k + p.match * h_k.take(j)
        to_j = p.match * h_k.take(i) - p.cohere * d_k
        s_k = np.bincount(i, to_i, n) + np.bincount(j, to_j, n)
        if close.size:
            near = d_k.take(close)
            s_k -= p.separate * (np.bincount(ci, near, n) - np.bincount(cj, near, n))
        total[:, k] = s_k
    count = (np.bincount(i, minlength=n) + np.bincount(j, minlength=n)).astype(float)
    return total, count


def turn(heading: np.ndarray, total: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The new unit headings; a boid with no neighbours keeps its heading."""
    turning = (count > 0) | np.any(total != 0.0, axis=1)
    new = heading + total / np.maximum(count, 1.0)[:, None]
    norm = np.sqrt(np.einsum("ij,ij->i", new, new))
    turning &= norm > 0.0
    new /= np.where(turning, norm, 1.0)[:, None]
    return np.where(turning[:, None], new, heading)


# -- the monitor --------------------------------------------------------------------------
class Monitor:
    """Per step: smallest separation, distinct pairs closer than the limit, connectivity."""

    def __init__(self, n: int, limit: float) -> None:
        self.n, self.limit = n, limit
        self.min_separation = np.inf
        self.collision_keys: list[np.ndarray] = []
        self.connected = True

    def observe(self, pos: np.ndarray, tree: cKDTree, pairs: np.ndarray, d2: np.ndarray) -> None:
        """Fold one step into the figures: the smallest separation, the colliding pairs, connectivity."""
        if len(pairs):
            closest = float(np.sqrt(d2.min()))
        else:  # nobody within range: the 2-nearest query
            closest = float(tree.query(pos, k=2)[0][:, 1].min())
        self.min_separation = min(self.min_separation, closest)
        if closest < self.limit:
            hit = pairs[d2 < self.limit * self.limit]
            self.collision_keys.append(hit[:, 0].astype(np.int64) * self.n + hit[:, 1])
        graph = scipy.sparse.coo_matrix(
            (np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(self.n, self.n))
        if scipy.sparse.csgraph.connected_components(graph, directed=False)[0] != 1:
            self.connected = False

    def collisions(self) -> int:
        """The number of distinct pairs that came closer than the limit."""
        return int(np.unique(np.concatenate(self.collision_keys)).size) if self.collision_keys else 0


def sense(pos: np.ndarray, radius: float):
    """One tree, its pairs (M, 2) within ``radius``, their vectors p_j - p_i (2, M) and squared lengths."""
    tree = cKDTree(pos)
    pairs = tree.query_pairs(radius, output_type="ndarray")
    delta = pair_vectors(pos, pairs[:, 0], pairs[:, 1])
    return tree, pairs, delta, np.einsum("km,km->m", delta, delta)


def run(pos2d: np.ndarray, dir2d: np.ndarray, steps: int, p: BoidParams) -> dict:
    """``steps`` steps of the flock from positions (N, 2) and headings (N, 2); times and results."""
    n = len(pos2d)
    pos = np.column_stack([pos2d, np.full(n, 2.0)])
    heading = np.column_stack([dir2d, np.zeros(n)])
    reach = max(p.vision, p.comm_range)
    monitor = Monitor(n, p.separation_limit)
    tree, pairs, delta, d2 = sense(pos, reach)
    monitor.observe(pos, tree, pairs, d2)
    seconds = np.zeros(steps)
    for step in range(steps):
        t0 = time.perf_counter()
        # flock: the interior pairs within vision, then those through the seams
        inside = d2 <= p.vision * p.vision
        si, sj, sdelta = seam_pairs(pos, tree, p.box, p.vision)
        i, j = np.concatenate([pairs[inside, 0], si]), np.concatenate([pairs[inside, 1], sj])
        delta = np.concatenate([delta[:, inside], sdelta], axis=1)
        total, count = steer(i, j, delta, heading, p)
        heading = turn(heading, total, count)
        # motion: a kinematic point flies the command speed * d_i (norm clipped at u_max)
        u = p.speed * heading
        u *= np.minimum(1.0, p.u_max / np.maximum(np.sqrt(np.einsum("ij,ij->i", u, u)), 1e-300))[:, None]
        pos += u * p.dt
        xy = np.mod(pos[:, :2], p.box)
        xy[xy >= p.box] = 0.0  # np.mod of a tiny negative can round up to the side itself
        pos[:, :2] = xy
        # monitor, on the new state (its pairs are the next step's flock's)
        tree, pairs, delta, d2 = sense(pos, reach)
        monitor.observe(pos, tree, pairs, d2)
        seconds[step] = time.perf_counter() - t0
    unit = heading / np.maximum(np.linalg.norm(heading, axis=1, keepdims=True), 1e-12)
    return {
        "step_seconds": seconds.tolist(),
        "polarization": float(np.linalg.norm(unit.mean(axis=0))),
        "min_separation": monitor.min_separation,
        "collisions": monitor.collisions(),
        "connected": monitor.connected,
        "mean_neighbours": float(count.mean()),
    }


def main(argv: list[str]) -> None:
    """Run the reference from argv (start .npz, steps, parameters as JSON) and print its figures as JSON."""
    start = np.load(argv[0])
    params = BoidParams(**json.loads(argv[2]))
    print(json.dumps(run(start["pos"], start["dir"], int(argv[1]), params)))


if __name__ == "__main__":
    main(sys.argv[1:])
