"""Safety monitor: separation, clearance, connectivity and the keep-out ellipsoid, measured on every tick.

A verdict is computed from the recorded states, never from an algorithm's own belief. The monitor
uses the tick's shared :class:`~swarmscene.core.sensing.Sensing` (its one k-d tree), so it costs
O(N log N) per tick and never builds an N x N matrix.

Metrics (``metrics.json``):
    min_separation: smallest distance between any two agents over the run, m.
    min_clearance: smallest signed distance from an agent to an obstacle, m (null: no obstacles).
    collisions: distinct pairs that came closer than ``safety.separation_limit``.
    clearance_violations: distinct agents that came closer than ``safety.clearance_limit`` to an
        obstacle.
    connected: the communication graph was connected at every tick.
    min_keep_out: only with ``safety.keep_out``: smallest ||E^-1 (p_i - p_j)||, E = diag(radii),
        over the pairs within the largest radius of each other (null: no pair came that close).
        Every pair inside the ellipsoid is among them, so the value is exact whenever it is below
        1; above 1 it is the least over the pairs within reach.
    keep_out_conflicts: only with ``safety.keep_out``: distinct pairs that came inside the
        keep-out ellipsoid.
    violations.<condition>.first_time / .agents: for each violated condition (``separation``,
        ``clearance``, ``connectivity``, ``keep_out``), when it first happened (s) and the agents
        involved.

The keep-out ellipsoid is the one of Crazyswarm's planners (Preiss et al., "Downwash-aware
trajectory planning for large quadrotor teams", IROS 2017: radii 0.12, 0.12, 0.3 m for a
Crazyflie), set with ``safety.keep_out``; the ``downwash`` disturbance model reports its own
measure of it (``disturbances.downwash.*``), only while that model runs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import shapely

from .hookspecs import hookimpl
from .vectors import DENSE_POINTS, ellipsoid_norm

if TYPE_CHECKING:  # pragma: no cover
    from .run_view import RunView


FAR_BATCH = 65_536
"""Agent positions (summed over ticks) whose distance to the obstacles is computed in one batch."""

CLEARANCE_HORIZON = 0.5
"""m: least range of the monitor's bounded clearance query (a short range is cheap near walls; on
ticks where no agent is inside it, the minimum is the swarm's distance to the obstacles' union)."""


class ConnectivityCertificate:
    """Connectivity of the communication graph from tick to tick, exact and mostly free.

    A spanning tree of the graph whose links are all still within range, over the same members,
    proves the graph connected. So after an exact test that finds the graph connected, keep a
    minimum spanning tree (:meth:`Sensing.comm_spanning_tree`: the shortest links, the last to
    break) and on the next ticks only check its m - 1 lengths; test exactly again when one broke.
    In the 100-agent building run a tree lasts ~140 ticks. In a graph that changes every tick
    (a fast flock) the trees break at once and would cost more than they save, so each short-lived
    one doubles a pause (up to ``MAX_PAUSE`` ticks) before the next is built. A swarm of at most
    ``DENSE_POINTS`` agents is tested exactly every tick: that costs less than a tree.
    """

    MIN_LIFE = 4
    """ticks a tree must last to be worth building again at once"""
    MAX_PAUSE = 64

    def __init__(self) -> None:
        self.links: np.ndarray | None = None
        self.members: np.ndarray | None = None
        self.life = 0
        self.pause = 0
        self.wait = 0

    def connected(self, sensing: Any) -> bool:
        """Whether the communication graph of this tick is connected (exact: a kept tree's links
        all in range prove it, else the exact test runs)."""
        if sensing.world.n <= DENSE_POINTS or sensing.periodic is not None:  # a tree's plain lengths
            return bool(sensing.comm_connected)  # would not see links across a torus' seam
        if self.links is not None:
            if self._holds(sensing, self.links):
                self.life += 1
                return True
            short_lived = self.life < self.MIN_LIFE
            self.pause = min(2 * self.pause + 1, self.MAX_PAUSE) if short_lived else 0
            self.wait, self.links = self.pause, None
        connected = bool(sensing.comm_connected)
        if connected and self.wait == 0:
            self.links, self.members, self.life = sensing.comm_spanning_tree(), sensing.comm_members, 0
        self.wait = max(self.wait - 1, 0)
        return connected

    def _holds(self, sensing: Any, links: np.ndarray) -> bool:
        """The kept tree ``links`` (m - 1, 2) still spans the same members, every link in range."""
        if (sensing.comm_members != self.members).any():
            return False
        pos = sensing.world.pos
        gap = pos[links[:, 1]] - pos[links[:, 0]]
        return bool(np.all(np.einsum("ij,ij->i", gap, gap) <= sensing.comm_range**2))


class DistinctPairs:
    """The distinct agent pairs (i < j) seen over a run, as keys i * N + j in chunks merged now and
    then: 8 bytes per pair (a set of tuples costs ~500 and grew to 1 GB over 1,000 ticks of 100,000
    boids)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self._keys: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
        self._unmerged = 0

    def add(self, pairs: np.ndarray) -> None:
        """Record ``pairs`` (M, 2), i < j."""
        keys = pairs[:, 0].astype(np.int64) * self.n + pairs[:, 1]
        self._keys.append(keys)
        self._unmerged += keys.size
        if self._unmerged > max(1_000_000, self._keys[0].size):
            self._merge()

    def count(self) -> int:
        """How many distinct pairs were recorded."""
        return int(self._merge().size)

    def _merge(self) -> np.ndarray:
        merged = np.unique(np.concatenate(self._keys))
        self._keys, self._unmerged = [merged], 0
        return merged


class SafetyMonitor:
    """Records min separation, min clearance, connectivity and (with ``safety.keep_out``) the
    keep-out ellipsoid at t = 0 and after every tick."""

    def __init__(self, sim: RunView) -> None:
        self.d_sep = sim.config.safety.separation_limit
        self.d_clear = sim.config.safety.clearance_limit
        # Clearance is exact within the horizon; the minimum over agents is then exact too,
        # since agents beyond it are farther than any agent inside it.
        self.horizon = max(CLEARANCE_HORIZON, 4.0 * self.d_clear)
        self.stop_on_collision = sim.config.termination.on_collision
        size = sim.total_steps + 1
        self.t = np.zeros(size)
        self.min_separation = np.full(size, np.inf)
        self.min_clearance = np.full(size, np.inf)
        self.connected = np.ones(size, dtype=bool)
        self.count = 0
        self.n = sim.world.n
        self.collisions = DistinctPairs(self.n)  # pairs closer than d_sep
        self.clearance_agents: set[int] = set()
        keep_out = sim.config.safety.keep_out
        self.keep_out = None if keep_out is None else np.asarray(keep_out, dtype=float)
        # Only pairs within the largest radius can be inside the ellipsoid: ||d|| <= max(radii) * ||E^-1 d||.
        self.keep_out_reach = 0.0 if keep_out is None else float(max(keep_out))
        self.min_keep_out = np.full(size if keep_out is not None else 0, np.inf)  # 8 bytes a tick, only when on
        self.keep_out_pairs = DistinctPairs(self.n)
        self.first: dict[str, tuple[float, list[int]]] = {}
        self.certificate = ConnectivityCertificate()
        # Ticks with every agent beyond the horizon, and their x-y positions: their min_clearance
        # (the swarm's distance to the obstacles' union) is computed in batches (_settle_far).
        self.environment = sim.environment
        self._far_ticks: list[int] = []
        self._far_xy: list[np.ndarray] = []

    def _observe(self, sim: RunView) -> None:
        sensing, t, k = sim.sensing, sim.world.t, self.count
        self.t[k] = t
        # Connectivity first: the pair list it may build makes the separation free.
        connected = self.connected[k] = self.certificate.connected(sensing)
        separation = self.min_separation[k] = sensing.min_separation
        if separation < self.d_sep:
            pairs = sensing.pairs(self.d_sep)
            self.collisions.add(pairs)
            if "separation" not in self.first:
                self._first("separation", t, np.unique(pairs).tolist())
            if self.stop_on_collision:
                sim.request_stop("collision")
        if not sensing.environment.empty:  # open space: min_clearance stays inf
            self._observe_clearance(sensing, t, k)
        if self.keep_out is not None and separation <= self.keep_out_reach:  # else no pair within reach
            self._observe_keep_out(sensing, t, k, self.keep_out)
        if not connected:
            self._first("connectivity", t, np.flatnonzero(sensing.comm_members).tolist())
        self.count += 1

    def _observe_clearance(self, sensing: Any, t: float, k: int) -> None:
        if sensing.nothing_within(self.horizon):  # shown by the tick (a batch's prefetch): no query
            self._wait_far(sensing, k)  # (2 us less a world-step of a vector environment)
            return
        clearance = sensing.clearance_within(self.horizon)
        nearest = np.minimum.reduce(clearance, initial=np.inf)
        if not nearest < np.inf:  # every agent beyond the horizon
            self._wait_far(sensing, k)
            return
        self.min_clearance[k] = nearest  # some agent within the horizon
        if nearest < self.d_clear:
            agents = np.flatnonzero(clearance < self.d_clear)
            self.clearance_agents.update(agents.tolist())
            self._first("clearance", t, agents.tolist())

    def _wait_far(self, sensing: Any, k: int) -> None:
        """Tick k has every agent beyond the horizon: only the swarm's distance to the obstacles is
        left to know, farther than the horizon > d_clear, so no violation; its value can wait for
        a batch of such ticks (:meth:`_settle_far`)."""
        self._far_ticks.append(k)
        self._far_xy.append(sensing.world.pos[:, :2].copy())
        if len(self._far_ticks) * self.n >= FAR_BATCH:
            self._settle_far()

    def _observe_keep_out(self, sensing: Any, t: float, k: int, radii: np.ndarray) -> None:
        """The pairs within the largest of ``radii`` (the tick's shared pair list, filtered from the
        widest one listed), their ellipsoid norms, and those inside (norm < 1)."""
        pairs = sensing.pairs(self.keep_out_reach)
        if not len(pairs):
            return
        pos = sensing.world.pos
        norm = ellipsoid_norm(pos[pairs[:, 1]] - pos[pairs[:, 0]], radii)
        self.min_keep_out[k] = norm.min()
        inside = pairs[norm < 1.0]
        if len(inside):
            self.keep_out_pairs.add(inside)
            self._first("keep_out", t, np.unique(inside).tolist())

    def _settle_far(self) -> None:
        """The waiting ticks' min_clearance: ``Environment.distance`` of each tick's positions, one
        vectorised GEOS call for them all (the same distance of the same multipoint, to the bit:
        ~1 us a tick instead of ~10 us of per-call overhead for a small swarm)."""
        if not self._far_ticks:
            return
        if self.n:
            points = shapely.multipoints(np.stack(self._far_xy))
            self.min_clearance[self._far_ticks] = shapely.distance(self.environment.union, points)
        self._far_ticks, self._far_xy = [], []

    def _first(self, condition: str, t: float, agents: list[int]) -> None:
        self.first.setdefault(condition, (float(t), agents))

    @hookimpl
    def swarmscene_run_start(self, sim: RunView) -> None:
        """Observe the initial state (tick 0)."""
        self._observe(sim)

    @hookimpl
    def swarmscene_step_end(self, sim: RunView) -> None:
        """Observe the state after this tick: separation, clearance, connectivity, keep-out."""
        self._observe(sim)

    @hookimpl
    def swarmscene_event(self, sim: RunView, event: Any) -> None:
        """Re-test connectivity after an event (a failure may cut the graph)."""
        # A link lost by an event is lost at the event's tick, not at the end of it.
        if not sim.sensing.comm_connected:
            self.connected[self.count - 1] = False
            self._first("connectivity", sim.world.t, np.flatnonzero(sim.sensing.comm_members).tolist())

    @hookimpl
    def swarmscene_run_end(self, sim: RunView, metrics: dict[str, Any]) -> None:
        """Add the safety metrics: min_separation, min_clearance, collisions, clearance_violations,
        connected, min_keep_out, keep_out_conflicts, and each violated condition's first time and
        agents."""
        self._settle_far()
        k = self.count
        min_sep = float(self.min_separation[:k].min()) if k else float("inf")
        min_clear = float(self.min_clearance[:k].min()) if k else float("inf")
        metrics["min_separation"] = min_sep if np.isfinite(min_sep) else None
        metrics["min_clearance"] = min_clear if np.isfinite(min_clear) else None
        metrics["collisions"] = self.collisions.count()
        metrics["clearance_violations"] = len(self.clearance_agents)
        metrics["connected"] = bool(self.connected[:k].all())
        if self.keep_out is not None:  # without it, no key: the metrics of a run as before the option
            min_keep_out = float(np.minimum.reduce(self.min_keep_out[:k], initial=np.inf))
            metrics["min_keep_out"] = min_keep_out if np.isfinite(min_keep_out) else None
            metrics["keep_out_conflicts"] = self.keep_out_pairs.count()
        for condition, (t, agents) in sorted(self.first.items()):
            metrics[f"violations.{condition}.first_time"] = t
            metrics[f"violations.{condition}.agents"] = agents

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded series, trimmed to the ticks that ran."""
        self._settle_far()
        k = self.count
        series = {
            "t": self.t[:k],
            "min_separation": self.min_separation[:k],
            "min_clearance": self.min_clearance[:k],
            "connected": self.connected[:k],
        }
        if self.keep_out is not None:  # inf: no pair within the largest radius at that tick
            series["min_keep_out"] = self.min_keep_out[:k]
        return series


@hookimpl
def swarmscene_register_observers(register: Any) -> None:
    """Add :class:`SafetyMonitor` to the observers every run builds."""
    register(SafetyMonitor)
