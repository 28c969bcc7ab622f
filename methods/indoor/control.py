"""Indoor swarming, thesis sections 5.3.3-5.3.4: follower potentials and leader control.

Karydes (2020), chapter 5. Inputs are displacements per sampling period T_s (m), as in eq. 5.1;
positions are planar (N, 2) arrays in the world x-y plane. Follower input (eq. 5.30-5.31):

    w_i = w_obs + w_col + w_con + w_com + w_led,   u_i = sat(w_i, u_sat).

The obstacle and collision terms (:func:`w_obs`, :func:`w_col`) are the avoidance part, the other
three (:func:`w_con`, :func:`w_com`, :func:`w_led`) the formation part; each is callable alone
(analysis, figures). The plugins' per-tick path is :func:`formation_step` (formation part, ranks
and the leader's Algorithm 1), :func:`avoidance_terms` and :func:`barrier_command`, compiled
kernels (``kernels.py``) with the same arithmetic; the numpy follower and leader laws they were
checked against are tests/oracles/indoor.py's.

Sign convention: every pair term is psi(||r_j - r_i||) (r_j - r_i)/||r_j - r_i||, so psi > 0
attracts agent i toward j (or toward the obstacle point) and psi < 0 repels. Following the notes
that come with the source text: psi_obs and psi_col (eq. 5.34, 5.36) are held at their boundary
value -K below d_o and d_c (the printed "0 otherwise" would switch repulsion off exactly when a
vehicle is too close); psi_con (eq. 5.38) is +K_con at d_n and 0 at l_n, i.e. it attracts (the
text's "psi_con(d_n) = -K_con" contradicts its own formula and purpose).
"""

from __future__ import annotations

from dataclasses import astuple, dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from swarmscene.core.setpoint import Mode
from swarmscene.core.state import Role

from .graphs import EdgeList, check_reading, graphs_from_kernel, tick_graphs
from .sensing import Obstacles, nearest_obstacle

if TYPE_CHECKING:  # pragma: no cover
    from scipy.spatial import cKDTree


@dataclass(frozen=True)
class IndoorGains:
    """Parameters of the indoor swarm; defaults are the thesis' Table 5.1 (lengths in m)."""

    T_s: float = 0.01  # sampling period, s
    u_max: float = 0.025  # maximum input (hardware), m per T_s
    d_c: float = 0.3  # collision-free distance
    d_o: float = 0.1  # obstacle-free distance
    d_s: float = 2.0  # sensing range
    d_l: float = 0.05  # LOS clearance distance
    d_n: float = 1.0  # neighbour maximum distance
    phi_d: float = 0.2  # edge deactivation threshold
    # Reading of the candidates m of eq. 5.15-5.16 (not in Table 5.1; graphs module docstring).
    deactivation_candidates: str = "neighbours"
    u_sat: float = 0.02  # input saturation level, m per T_s
    K_obs: float = 200.0
    eps_obs: float = 1e-4
    l_o: float = 0.7
    K_col: float = 200.0
    eps_col: float = 1e-4
    l_c: float = 0.7
    K_con: float = 200.0
    eps_con: float = 1e-4
    l_n: float = 0.7
    K_com: float = 0.1
    alpha_com: float = 0.8
    K_led: float = 0.06
    alpha_lsat: float = 0.7
    alpha_lcon: float = 0.95

    # The kernels' gain arrays and the sensing memo's key are built once per gain set and kept on
    # it (a frozen dataclass: cached_property writes the instance dict, not a field), so they live
    # and die with the plugin that owns the gains; hashing the 26 fields every tick would cost
    # more than the lookup saves.

    @cached_property
    def formation_kernel_gains(self) -> np.ndarray:
        """The gains :func:`~.kernels.formation_kernel` reads (:data:`FORMATION_GAINS`), in its order."""
        return self.kernel_gains(FORMATION_GAINS)

    @cached_property
    def avoidance_kernel_gains(self) -> np.ndarray:
        """The gains :func:`~.kernels.avoidance_kernel` reads (:data:`AVOIDANCE_GAINS`), in its order."""
        return self.kernel_gains(AVOIDANCE_GAINS)

    def kernel_gains(self, names: tuple[str, ...]) -> np.ndarray:
        """The named gains as the float array a compiled kernel takes (built on every call)."""
        values = dict(zip(IndoorGains.__dataclass_fields__, astuple(self), strict=True))
        return np.array([float(values[k]) for k in names])

    @cached_property
    def sensing_reach(self) -> float:
        """How far obstacles are looked for: min(l_o, d_s) (nothing beyond l_o acts, eq. 5.34)."""
        return min(self.l_o, self.d_s)

    @cached_property
    def snapshot_key(self) -> tuple[tuple[str, object], ...]:
        """The parameters that define one tick's sensing graphs (the shared memo's key)."""
        return (("d_n", self.d_n), ("d_l", self.d_l), ("phi_d", self.phi_d),
                ("reach", self.sensing_reach), ("deactivation_candidates", self.deactivation_candidates))


TABLE_5_1 = IndoorGains()
"""The thesis' simulation parameters (Table 5.1)."""


def _hyperbolic(x: np.ndarray, gain: float, eps: float) -> np.ndarray:
    """K ((1 + eps) / (x + eps) - 1) eps: K at x = 0, 0 at x = 1 (shape of eq. 5.34, 5.36, 5.38)."""
    return gain * ((1.0 + eps) / (x + eps) - 1.0) * eps


def psi_obs(z: np.ndarray, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Obstacle repulsion psi_obs(z) (thesis eq. 5.34): -K_obs at d_o (held below), 0 beyond l_o."""
    x = np.clip((np.asarray(z, dtype=float) - g.d_o) / (g.l_o - g.d_o), 0.0, None)
    return np.where(x <= 1.0, -_hyperbolic(np.minimum(x, 1.0), g.K_obs, g.eps_obs), 0.0)


def psi_col(z: np.ndarray, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Collision repulsion psi_col(z) (thesis eq. 5.36): -K_col at d_c (held below), 0 beyond l_c."""
    x = np.clip((np.asarray(z, dtype=float) - g.d_c) / (g.l_c - g.d_c), 0.0, None)
    return np.where(x <= 1.0, -_hyperbolic(np.minimum(x, 1.0), g.K_col, g.eps_col), 0.0)


def psi_con(z: np.ndarray, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Connectivity attraction psi_con(z) (thesis eq. 5.38): 0 below l_n, +K_con at d_n, 0 beyond."""
    x = (np.asarray(z, dtype=float) - g.d_n) / (g.l_n - g.d_n)
    inside = (x >= 0.0) & (x <= 1.0)
    return np.where(inside, _hyperbolic(np.clip(x, 0.0, 1.0), g.K_con, g.eps_con), 0.0)


def psi_com(z: np.ndarray, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Compactness psi_com(z) (thesis eq. 5.40): linear on [d_c, d_n], zero at d_c + alpha (d_n - d_c)."""
    z = np.asarray(z, dtype=float)
    value = g.K_com * ((z - g.d_c) / (g.alpha_com * (g.d_n - g.d_c)) - 1.0)
    return np.where((z >= g.d_c) & (z <= g.d_n), value, 0.0)


def psi_led(z: np.ndarray, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Leader traction psi_led(z) = K_led z (thesis eq. 5.42)."""
    return g.K_led * np.asarray(z, dtype=float)


@dataclass(frozen=True)
class PairGeometry:
    """Directed G_sigma edges (src i, dst j) with unit vectors e_ij and lengths, shared by 5.35-5.39."""

    n: int
    src: np.ndarray
    unit: np.ndarray
    length: np.ndarray

    @classmethod
    def of(cls, r: np.ndarray, g_sigma: EdgeList) -> PairGeometry:
        """The geometry of every arc (i, j) of ``g_sigma`` at positions ``r`` (N, 2)."""
        src, dst = g_sigma.directed()
        d = r[dst] - r[src]
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        return cls(len(r), src, d / np.maximum(length, 1e-12)[:, None], length)

    def sum(self, psi: np.ndarray) -> np.ndarray:
        """(N, 2) sum over neighbours j of psi_ij e_ij."""
        out = np.empty((self.n, 2))
        out[:, 0] = np.bincount(self.src, weights=psi * self.unit[:, 0], minlength=self.n)
        out[:, 1] = np.bincount(self.src, weights=psi * self.unit[:, 1], minlength=self.n)
        return out


def w_obs(r: np.ndarray, o: np.ndarray, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Obstacle avoidance term (thesis eq. 5.32-5.33) from the nearest detected points o (N, 2).

    Rows of ``o`` that are NaN (nothing detected, O_i empty) give 0.
    """
    d = o - r
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    seen = np.isfinite(dist) & (dist > 0.0)
    out = np.zeros_like(r, dtype=float)
    out[seen] = (psi_obs(dist[seen], g) / dist[seen])[:, None] * d[seen]
    return out


def w_col(r: np.ndarray, g_sigma: EdgeList | PairGeometry, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Collision avoidance term, sum of psi_col over N_i(G_sigma) (thesis eq. 5.35-5.36)."""
    pg = g_sigma if isinstance(g_sigma, PairGeometry) else PairGeometry.of(r, g_sigma)
    return pg.sum(psi_col(pg.length, g))


def w_con(r: np.ndarray, g_sigma: EdgeList | PairGeometry, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Connectivity maintenance term, sum of psi_con over N_i(G_sigma) (thesis eq. 5.37-5.38)."""
    pg = g_sigma if isinstance(g_sigma, PairGeometry) else PairGeometry.of(r, g_sigma)
    return pg.sum(psi_con(pg.length, g))


def w_com(r: np.ndarray, g_sigma: EdgeList | PairGeometry, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """Compactness term, sum of psi_com over N_i(G_sigma) (thesis eq. 5.39-5.40)."""
    pg = g_sigma if isinstance(g_sigma, PairGeometry) else PairGeometry.of(r, g_sigma)
    return pg.sum(psi_com(pg.length, g))


def w_led(
    r: np.ndarray, l: np.ndarray, has_neighbour: np.ndarray, g: IndoorGains = TABLE_5_1  # noqa: E741 (l_i, eq. 5.41)
) -> np.ndarray:
    """Leader traction toward the virtual leader l_i (thesis eq. 5.41-5.42).

    psi_led(z) z_hat = K_led (l_i - r_i); zero where N_i(G_sigma) is empty.
    """
    return np.where(has_neighbour[:, None], g.K_led * (l - r), 0.0)


FORMATION_GAINS = ("d_c", "d_n", "l_n", "K_con", "eps_con", "K_com", "alpha_com", "K_led", "u_sat",
                   "alpha_lsat", "alpha_lcon")
"""The gains :func:`~.kernels.formation_kernel` reads, in its order."""
AVOIDANCE_GAINS = ("d_o", "l_o", "K_obs", "eps_obs", "d_c", "l_c", "K_col", "eps_col")
"""The gains :func:`~.kernels.avoidance_kernel` reads, in its order."""


def formation_step(
    snap: IndoorSnapshot, rho_bar: np.ndarray, leader: int, waypoints: np.ndarray, m: int,
    g: IndoorGains = TABLE_5_1,
) -> tuple[np.ndarray, int, np.ndarray]:
    """One tick of the formation's part of the method, one compiled call (eq. 5.24-5.26, 5.37-5.44).

    w_i = w_con + w_com + w_led for the followers (the sum over N_i(G_sigma) of
    :func:`psi_con` + :func:`psi_com`, and :func:`w_led` toward :func:`~.graphs.virtual_leader`),
    row ``leader`` the leader's input u_N = w_N min(u_lsat, u_lcon) (Algorithm 1, eq. 5.43-5.44:
    u_lcon from the nearest G_sigma neighbour, 0 without one; at the final way-point the step is
    also capped by the remaining distance), with the numpy oracle's arithmetic bit for bit
    (tests/oracles/indoor.py: ``follower_input``, ``leader_input``).

    Returns:
        w: (N, 2) m per T_s; the new way-point index m; rho_bar(k+1) (:func:`~.graphs.rank_estimate_step`).
    """
    from .kernels import formation_kernel  # numba loads at first use, not at registration

    _, dst = snap.g_sigma.directed()
    w, m, rho_bar = formation_kernel(
        snap.r, snap.g_sigma.indptr, dst, rho_bar, leader, waypoints, m, g.formation_kernel_gains
    )
    return w, int(m), rho_bar


def avoidance_terms(snap: IndoorSnapshot, g: IndoorGains = TABLE_5_1) -> np.ndarray:
    """w_obs + w_col (N, 2), m per T_s (eq. 5.32-5.36): :func:`w_obs` plus :func:`w_col` over
    G_sigma in one compiled call, bit for bit."""
    from .kernels import avoidance_kernel  # numba loads at first use, not at registration

    _, dst = snap.g_sigma.directed()
    return avoidance_kernel(snap.r, snap.o, snap.g_sigma.indptr, dst, g.avoidance_kernel_gains)


_VELOCITY, _LEADER = int(Mode.VELOCITY), int(Role.LEADER)


def barrier_command(
    vel: np.ndarray, mode: np.ndarray, healthy: np.ndarray, role: np.ndarray, w: np.ndarray,
    T_s: float, u_sat: float, exempt_leader: bool,
) -> int:
    """vel[k, :2] = sat(vel[k, :2] T_s + w[k], u_sat) / T_s (eq. 5.30) in place for the healthy
    agents in VELOCITY mode (not the leader when ``exempt_leader``), one compiled call with the
    arithmetic of ``saturate(vel * T_s + w, u_sat) / T_s``. Returns how many acting agents are in
    another mode (left to the caller)."""
    from .kernels import barrier_kernel  # numba loads at first use, not at registration

    return barrier_kernel(
        vel, mode, healthy, role, w, float(T_s), float(u_sat), bool(exempt_leader),
        _VELOCITY, _LEADER,
    )


@dataclass(frozen=True)
class IndoorSnapshot:
    """What the swarm senses at one instant (section 5.2): nearest obstacle points and the graphs.

    Attributes:
        r: (N, 2) positions, m.
        o: (N, 2) nearest detected obstacle point within l_o, NaN where none (eq. 5.32).
        obstacle_distance: (N,) its distance, m (``inf`` where none).
        g_n: the graph G_n (eq. 5.11-5.12).
        g_sigma: the graph G_sigma (eq. 5.13-5.22).
    """

    r: np.ndarray
    o: np.ndarray
    obstacle_distance: np.ndarray
    g_n: EdgeList
    g_sigma: EdgeList

    @cached_property
    def pair_geometry(self) -> PairGeometry:
        """G_sigma's directed edges with unit vectors and lengths, computed once for every term."""
        return PairGeometry.of(self.r, self.g_sigma)


def sense(
    r: np.ndarray,
    obstacles: Obstacles,
    g: IndoorGains = TABLE_5_1,
    tree: cKDTree | None = None,
    nearest: tuple[np.ndarray, np.ndarray] | None = None,
    candidates: np.ndarray | None = None,
) -> IndoorSnapshot:
    """Sensing and graphs of one step: o_i, G_n with LOS, G_sigma (eq. 5.4-5.22), the graphs in
    one compiled call (:func:`~.graphs.tick_graphs`).

    Obstacles are sensed up to l_o only (l_o < d_s): psi_obs vanishes beyond l_o, so this is exact
    for the control law and cheaper; call :func:`~.indoor_sensing.nearest_obstacle` with d_s for
    the full detection set. The obstacle distances double as LOS certificates (see
    :func:`~.indoor_sensing.sensing_pairs`), so most pairs skip the shapely segment test.
    ``tree`` is an optional prebuilt cKDTree over the positions (the engine's shared tree);
    ``nearest`` optional precomputed (o, distance) within min(l_o, d_s), as
    :func:`~.indoor_sensing.nearest_obstacle` returns them (the engine's shared obstacle query);
    ``candidates`` optional pairs within d_n (the engine's cached pair list).
    """
    reach = min(g.l_o, g.d_s)
    o, dist = nearest if nearest is not None else nearest_obstacle(r, obstacles, max_distance=reach)
    g_n, g_sigma = tick_graphs(
        r, obstacles, g.d_n, g.d_l, g.phi_d, g.deactivation_candidates, tree, np.minimum(dist, reach),
        candidates,
    )
    return IndoorSnapshot(r, o, dist, g_n, g_sigma)


def sense_indexed(
    r: np.ndarray,
    footprints: tuple[np.ndarray, ...],
    g: IndoorGains,
    index: np.ndarray,
    dist: np.ndarray,
    candidates: np.ndarray,
) -> IndoorSnapshot:
    """:func:`sense` when each agent's nearest obstacle within min(l_o, d_s) is already known as
    its ``index`` among the obstacles (-1: none) and its distance ``dist`` (the engine's shared
    query, ``Sensing.obstacle_nearest``): o_i, G_n and G_sigma in one compiled call.
    ``footprints``: the obstacles as segment arrays (``Environment.footprints``, or
    ``sensing.kernel_obstacles`` of their geometries); ``candidates``: the pairs within d_n
    (``Sensing.pairs``)."""
    from .kernels import READINGS, snapshot_kernel  # numba loads at first use, not at registration

    check_reading(g.deactivation_candidates)
    r = np.ascontiguousarray(r, dtype=float)
    o, out = snapshot_kernel(
        r, np.asarray(index, dtype=np.intp), np.asarray(dist, dtype=float), float(min(g.l_o, g.d_s)),
        np.asarray(candidates, dtype=np.intp).reshape(-1, 2), float(g.d_l), float(g.phi_d),
        READINGS[g.deactivation_candidates], *footprints,
    )
    g_n, g_sigma = graphs_from_kernel(out, len(r), g.deactivation_candidates)
    return IndoorSnapshot(r, o, dist, g_n, g_sigma)
