"""The ``swarmlab`` observer: SwarmLab's swarm performance metrics of every guidance tick.

Source: E. Soria, F. Schiano, D. Floreano, "SwarmLab: a Matlab drone swarm simulator", IROS 2020,
section IV-C (``compute_swarm_performance.m``); the definitions and where this follows or departs
from the MATLAB are in :mod:`swarmscene.methods.swarmlab.metrics`. Asked for by name,
``observers=[swarmlab]`` (options: ``observers.swarmlab.r=20``); without it the observer adds
nothing to a run and costs nothing but a hook call.

Each sample (the start, then every ``every``-th guidance tick) measures, over every agent (failed
vehicles included: SwarmLab has no failures, and a failed vehicle is still a body in the air):

* ``safety``: 1 - the share of pairs closer than 2 r_coll (1: no pair that close);
* ``order``: the mean over agents of the mean cosine between its velocity and its neighbours';
* ``union``: (N - components) / (N - 1) of the undirected neighbour graph (1: one component);
* ``alg_conn``: lambda_2 of that graph's Laplacian, divided by N;
* ``safety_obs``: 1 - the share of (agent, obstacle) pairs with the agent inside the obstacle;
* ``min_d_obs``: the smallest signed distance from an agent to an obstacle, m.

Metrics (``metrics.json``): ``swarmlab.<name>`` the mean of each series over the samples, and
``swarmlab.safety_min``, ``swarmlab.union_min`` and ``swarmlab.min_d_obs_min`` the worst sample
(the obstacle keys only on a map with obstacles). The series are written to ``swarmlab.npz`` in the
run directory (``t`` in s and one (T,) array per metric; ``numpy.load``).

Up to 400 agents a sample is one compiled call (:mod:`swarmscene.methods.swarmlab.kernels`) that
starts from the previous sample's neighbour lists and Fiedler vector (``WarmStart``, one per run),
about 0.06 ms for a hundred boids; above, the tick's shared k-d tree and sparse graphs. After the
first sample the compiled calls do not run at their ticks: each tick's positions and velocities are
copied and held, and every :data:`CHUNK`-th sample measures the held states one after another (the
last ones at the run's end), with the kernel's code and data still in the caches; the obstacle
terms, which read the tick's clearances, are taken at the tick. The series are the same, bit for bit. The first
run with the observer compiles its kernels (about 40 s on a loaded 2-core machine, once: numba's
cache keeps them; ``swarmscene-compile`` does it ahead).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.methods.swarmlab.metrics import (
    COMPILED_LIMIT,
    MAX_NEIG_DEFAULT,
    R_COLL_DEFAULT,
    R_DEFAULT,
    WarmStart,
    obstacle_safety,
    swarm_metrics,
)
from swarmscene.plugin import RunView, StrictModel, hookimpl

SERIES = ("safety", "order", "union", "alg_conn", "safety_obs", "min_d_obs")
"""The per-sample metrics, in the order of SwarmLab's outputs."""
WORST = ("safety", "union", "min_d_obs")
"""The metrics whose worst sample is reported beside the mean (``swarmlab.<name>_min``)."""
CHUNK = 32
"""States held before the compiled passes measure them one after another: a hundred boids' pass
between two flocking ticks runs with its code and data out of the caches, about a third slower
than passes in a row."""


class SwarmLab:
    """SwarmLab's safety, order, union, algebraic connectivity and obstacle metrics, per tick."""

    name = "swarmlab"

    class Params(StrictModel):
        """SwarmLab's parameters (``parameters/param_swarm/param_swarm.m``), its defaults."""

        r: float = Field(R_DEFAULT, gt=0, description="r: metric radius of a neighbourhood, m (SwarmLab: 150)")
        max_neig: int = Field(
            MAX_NEIG_DEFAULT, ge=1, description="max_neig: most neighbours, the nearest (SwarmLab: 10)")
        r_coll: float = Field(
            R_COLL_DEFAULT, gt=0,
            description="r_coll: radius of the sphere around one drone, m; a pair closer than 2 r_coll "
            "collides (SwarmLab: 0.5)")
        every: int = Field(1, ge=1, description="sample every k-th guidance tick (SwarmLab: every logged step)")

    def __init__(self, sim: RunView) -> None:
        self.params: SwarmLab.Params | None = sim.config.observers.get(self.name)
        # r and r_coll as floats once: the compiled pass is called with them every sample
        self.radii = (float(self.params.r), float(self.params.r_coll)) if self.params is not None else (0.0, 0.0)
        self.rows: list[tuple[float, ...]] = []  # per sample: t, then SERIES (the obstacle ones on such a map)
        self.obstacles = len(sim.environment.obstacles)  # >= 1 wherever safety_obs is sampled
        self.warm = WarmStart()  # a sample's neighbour lists and lambda_2 start from the previous sample's
        self.held: list[tuple[float, np.ndarray, np.ndarray, tuple[float, ...]]] = []  # states not measured yet

    @hookimpl
    def swarmscene_run_start(self, sim: RunView) -> None:
        """The first sample: the swarm at t = 0 (SwarmLab's history starts there)."""
        if self.params is not None:
            self._sample(sim)

    @hookimpl
    def swarmscene_step_end(self, sim: RunView) -> None:
        """A sample at every ``every``-th guidance tick."""
        if self.params is not None and sim.step_count % self.params.every == 0:
            self._sample(sim)

    def _sample(self, sim: RunView) -> None:
        p = self.params
        assert p is not None
        world = sim.world
        pos = world.pos
        tail = self._obstacle_terms(sim, pos) if self.obstacles else ()  # the tick's clearances: now
        if self.warm.listed:  # the run's first sample settled the size and the buffers: held, measured in chunks
            self.held.append((world.t, pos.copy(), world.vel.copy(), tail))
            if len(self.held) == CHUNK:
                self._measure_held()
            return
        # the first sample, or a large swarm, whose neighbours come from the tick's shared k-d tree
        tree = sim.sensing.tree if len(pos) > COMPILED_LIMIT else None
        sample = swarm_metrics(pos, world.vel, p.r, p.max_neig, p.r_coll, self.warm, tree)
        self.rows.append((world.t, *sample[:4], *tail))

    def _obstacle_terms(self, sim: RunView, pos: np.ndarray) -> tuple[float, float]:
        """safety_obs and min_d_obs of the tick (from its signed clearances: negative inside an obstacle)."""
        clearance = sim.sensing.clearance
        inside = _inside_pairs(sim, pos, clearance)
        return float(obstacle_safety(inside, len(pos), self.obstacles) or 0.0), float(clearance.min())

    def _measure_held(self) -> None:
        """The held states' compiled passes, one after another in the order they were flown (each
        starts from the previous sample's lists and Fiedler vector, as it would have at its tick)."""
        for t, pos, vel, tail in self.held:
            self.rows.append((t, *self.warm.again(pos, vel, *self.radii)[:4], *tail))
        self.held.clear()

    def series(self) -> dict[str, np.ndarray]:
        """The per-sample series: ``t`` and each metric's (T,) array (the obstacle ones on a map with
        obstacles), the states still held measured first."""
        self._measure_held()
        table = np.array(self.rows, dtype=float).reshape(len(self.rows), -1)
        return {key: table[:, column] for column, key in enumerate(("t", *SERIES)) if column < table.shape[1]}

    @hookimpl
    def swarmscene_run_end(self, sim: RunView, metrics: dict[str, Any]) -> None:
        """The means over the samples (and the worst sample of safety, union, min_d_obs)."""
        if self.params is None or not self.rows:
            return
        for key, values in self.series().items():
            if key != "t":
                metrics[f"swarmlab.{key}"] = float(np.mean(values))
                if key in WORST:
                    metrics[f"swarmlab.{key}_min"] = float(np.min(values))

    def run_files(self) -> dict[str, dict[str, np.ndarray]]:
        """``swarmlab.npz``: the per-sample series (none when the observer was not asked for)."""
        if self.params is None:
            return {}
        return {"swarmlab.npz": self.series() if self.rows else {}}


def _inside_pairs(sim: RunView, pos: np.ndarray, clearance: np.ndarray) -> int:
    """(agent, obstacle) pairs with the agent strictly inside the obstacle: only agents inside the
    obstacles' union (negative clearance) are tested, one by each obstacle holding it."""
    inside = np.flatnonzero(clearance < 0)
    if not inside.size:
        return 0
    import shapely

    points = shapely.points(pos[inside, :2])
    hits, _ = sim.environment.tree.query(points, predicate="within")
    return int(len(hits))


@hookimpl
def swarmscene_register_observers(register: Any) -> None:
    """Add :class:`SwarmLab` to the observers every run builds (it measures when asked for)."""
    register(SwarmLab)
