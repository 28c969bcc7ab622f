"""SwarmLab's ``compute_swarm_performance.m`` for one time step, transcribed line by line from the
MATLAB (github.com/lis-epfl/swarmlab, ``math_tools/``): all pairs, a dense neighbourhood matrix,
a breadth-first component count (``network_components.m``) and every eigenvalue of the
Laplacian. The oracle of ``swarmscene.methods.swarmlab.metrics`` (tests/methods/swarmlab), with
the two documented departures: a cosine with a zero velocity counts 0 (MATLAB: NaN), and no
obstacle leaves S_obs undefined (MATLAB: 0)."""

from __future__ import annotations

import numpy as np


def distance_matrix(pos: np.ndarray) -> np.ndarray:
    """squareform(pdist(pos)): every pair's Euclidean distance (the same sum, then the root)."""
    return np.sqrt(((pos[:, None, :] - pos[None, :, :]) ** 2).sum(axis=2))


def compute_neighborhood(dist: np.ndarray, r_comm: float, max_neig: int) -> np.ndarray:
    """M(i, j) = 1 when i is a neighbour of j (column j: j's neighbours)."""
    n = dist.shape[1]
    m = np.ones((n, n)) - np.eye(n)
    dist = dist.copy()
    dist[np.eye(n, dtype=bool)] = np.inf
    m[dist > r_comm] = 0
    nn = m.sum(axis=0)
    for agent in np.flatnonzero(nn > max_neig):
        ranked = np.argsort(dist[:, agent], kind="stable")  # MATLAB's sort is stable
        m[ranked[max_neig:], agent] = 0
    return m


def network_components(a: np.ndarray) -> int:
    """The number of connected components, by the MATLAB's breadth-first discovery."""
    n = a.shape[0]
    a = a.copy()
    a[np.eye(n, dtype=bool)] = 0
    a = a + a.T
    discovered = np.zeros(n, dtype=bool)
    components = 0
    for node in range(n):
        if discovered[node]:
            continue
        members = [node]
        discovered[node] = True
        ptr = 0
        while ptr < len(members):
            nbrs = np.flatnonzero(a[:, members[ptr]])
            new = nbrs[~discovered[nbrs]]
            discovered[new] = True
            members.extend(new.tolist())
            ptr += 1
        components += 1
    return components


def swarm_performance(pos, vel, r, max_neig, r_coll, inside=None):
    """(safety, order, union, alg_conn, safety_obs) of one step; ``inside`` (N, n_o) bool: agent in
    obstacle (None: no obstacle)."""
    n = len(pos)
    dist = distance_matrix(pos)
    upper = dist[np.triu_indices(n, 1)]
    safety = 1.0 - (upper < 2 * r_coll).sum() / len(upper) if len(upper) else 1.0
    m = compute_neighborhood(dist, r, max_neig)
    order = 0.0
    for agent in range(n):
        neig = m[:, agent] == 1
        nn = neig.sum()
        if nn != 0:
            scalar_prod = vel[agent] @ vel[neig].T
            speed_agent = np.linalg.norm(vel[agent])
            speed_neig = np.sqrt((vel[neig] ** 2).sum(axis=1))
            denom = speed_agent * speed_neig
            cos = np.divide(scalar_prod, denom, out=np.zeros_like(scalar_prod), where=denom > 0)
            order += cos.sum() / nn
        else:
            order += 1
    order /= n
    a = ((m + m.T) > 0).astype(float)
    n_cc = network_components(a)
    union = (n - n_cc) / (n - 1) if n > 1 else 1.0
    lap = np.diag(a.sum(axis=1)) - a
    eig = np.sort(np.linalg.eigvalsh(lap))
    alg_conn = eig[1] / n if n > 1 else 0.0
    safety_obs = None if inside is None or inside.shape[1] == 0 else 1.0 - inside.sum() / inside.size
    return safety, order, union, alg_conn, safety_obs
