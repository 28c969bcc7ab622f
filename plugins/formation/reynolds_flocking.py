"""Reynolds flocking: boids steering by separation, alignment and cohesion (Reynolds 1987).

A thin adapter over :mod:`swarmscene.methods.flocking`: the rule as Mesa's BoidFlockers example
steers (cohesion, separation, alignment within ``vision``; its choices) is
:mod:`~swarmscene.methods.flocking.steering`, the periodic space :mod:`~swarmscene.methods.flocking.torus`,
the compiled sums :mod:`~swarmscene.methods.flocking.kernels`. This module keeps each boid's
heading between ticks and turns it into VELOCITY setpoints (``vel = speed * d_i``, HOLD for
failed boids; ``planar``: altitude held). In a batch of worlds (docs/batched.md) the flocks
of every world steer and turn in one pass (:meth:`ReynoldsFlocking.setpoints_batch`).

A boid without neighbours keeps its heading. Optional goal seeking adds ``goal_weight`` times the
unit vector toward ``goal`` to the steer (before normalising), for every boid. In a ``bounded``
space a boid closer than ``vision`` to a face of the box is steered back in proportion to how deep
it is in that band (``boundary_weight`` at the face). Initial headings come from the run's one
generator, so a run is seeded.

Space (``space``): ``open`` (no walls), ``bounded`` (steered back into the box ``box_min``..
``box_max``), ``toroidal`` (periodic box on the x-y axes, or x-y-z when not planar, as Mesa's
``ContinuousSpace(torus=True)``). Neighbours always come from the tick's shared pair list,
``sensing.pairs(vision)``; in a torus the pairs through the seams are added
(:func:`~swarmscene.methods.flocking.torus.torus_neighbours`, exact minimum image while ``vision``
< half the box). The plugin declares the box (:meth:`periodic_box`) and the kernel folds
positions back into it in its ``wrap`` phase, after every physics update and before any observer
reads them, so monitors, recorders and the next tick see positions in the box, as in Mesa. The
engine's connectivity check links agents by their minimum-image distance on the torus (a flock
across a seam stays one graph); its separation check still measures Euclidean distance in the
box, so pairs close across a seam are not seen by it. Distances are 3-D (equal to Mesa's 2-D ones
while the flock shares one altitude).

Memory per boid (plugin scratch): the heading (3 float64) plus, per tick, O(neighbours) pair arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from swarmscene.methods.flocking.steering import (
    boundary_steer,
    current_headings,
    goal_steer,
    initial_headings,
    turn_headings,
)
from swarmscene.methods.flocking.torus import in_box, minimum_image, pair_offsets, periodic_shifts, torus_neighbours
from swarmscene.plugin import (
    BuildContext,
    Formation,
    Mode,
    PluginParams,
    Sensing,
    SetpointBatch,
    Setpoints,
    WorldState,
    hookimpl,
    wrap,
)

if TYPE_CHECKING:  # pragma: no cover
    from swarmscene.plugin import RunView

Point3 = tuple[float, float, float]
__all__ = ["FlockingParams", "ReynoldsFlocking", "minimum_image", "params_from_mesa", "periodic_shifts"]


class FlockingParams(PluginParams):
    """Options of ``reynolds_flocking``; Mesa's BoidFlockers names in brackets."""

    vision: float = Field(10.0, gt=0, description="radius within which a boid sees neighbours, m [vision]")
    separation: float = Field(
        2.0, ge=0, description="neighbours closer than this push the boid away, m [separation]"
    )
    cohere: float = Field(0.03, ge=0, description="cohesion weight, 1/m [cohere]")
    separate: float = Field(0.015, ge=0, description="separation weight, 1/m [separate]")
    match: float = Field(0.05, ge=0, description="alignment weight (headings are unit-free) [match]")
    speed: float = Field(
        1.0, gt=0, description="cruise speed, m/s [speed per step / clock.guidance_period]"
    )
    space: Literal["open", "bounded", "toroidal"] = Field(
        "open", description="open | bounded (steered back into the box) | toroidal (periodic box)"
    )
    box_min: Point3 = Field((0.0, 0.0, 0.0), description="lower corner of the box, m [0, 0]")
    box_max: Point3 = Field((100.0, 100.0, 100.0), description="upper corner, m [width, height]")
    boundary_weight: float = Field(
        1.0, ge=0, description="bounded space: steer back at a face of the box (per unit heading)"
    )
    planar: bool = Field(True, description="headings in the x-y plane, altitude held (Mesa is 2-D)")
    goal: Point3 | None = Field(None, description="optional point the flock seeks, m")
    goal_weight: float = Field(0.0, ge=0, description="weight of the unit vector toward goal")
    goal_tolerance: float = Field(
        5.0, gt=0, description="mission complete when the flock's centroid is this close to goal, m"
    )

    @model_validator(mode="after")
    def _box_not_empty(self) -> FlockingParams:
        axes = 2 if self.planar else 3
        sides = [hi - lo for lo, hi in zip(self.box_min[:axes], self.box_max[:axes], strict=True)]
        if min(sides) <= 0:
            raise ValueError(f"box_max: must exceed box_min on every axis (got {self.box_max})")
        if self.space == "toroidal" and self.vision >= min(sides) / 2:
            raise ValueError(f"vision: must be below half the torus' smallest side {min(sides)} (got {self.vision})")
        return self


def params_from_mesa(
    width: float = 100.0,
    height: float = 100.0,
    speed: float = 1.0,
    vision: float = 10.0,
    separation: float = 2.0,
    cohere: float = 0.03,
    separate: float = 0.015,
    match: float = 0.05,
    guidance_period: float = 1.0,
) -> FlockingParams:
    """The Params equal to Mesa's ``BoidFlockers(width, height, speed, vision, ...)`` (its defaults).

    Mesa moves a boid ``speed`` units per step in a torus ``[0, width] x [0, height]``; one Mesa step
    is one guidance tick, so the cruise speed is ``speed / guidance_period`` m/s.
    """
    return FlockingParams(
        vision=vision, separation=separation, cohere=cohere, separate=separate, match=match,
        speed=speed / guidance_period, space="toroidal", box_min=(0.0, 0.0, 0.0),
        box_max=(width, height, max(width, height)), planar=True,
    )


class ReynoldsFlocking(Formation):
    """Boids: separation, alignment, cohesion within ``vision``; optional goal; open, bounded or torus."""

    name = "reynolds_flocking"
    avoids_collisions = False
    """Boids steer apart (separation) but nothing keeps them apart: the run summary says so beside
    the separation verdict (swarmscene/views/summary.py)."""
    metric_prefix = "flocking"
    Params = FlockingParams
    params: FlockingParams

    def __init__(self, params: FlockingParams, ctx: BuildContext) -> None:
        super().__init__(params, ctx)
        # The compiled steer (numba) is imported when a flock is built, not when it is registered.
        from swarmscene.methods.flocking.kernels import flocking_steer

        self._steer = flocking_steer
        self.heading = initial_headings(ctx.rng, ctx.n, params.planar)
        self.axes = 2 if params.planar else 3
        self.lo = np.asarray(params.box_min, dtype=float)
        self.hi = np.asarray(params.box_max, dtype=float)
        self.size = self.hi - self.lo
        self._shifts = periodic_shifts(self.axes).astype(float)
        self.neighbour_count = np.zeros(ctx.n)
        self._centroid_error = np.inf
        obstacles = len(ctx.environment.obstacles)
        if params.space == "toroidal" and obstacles:  # the kernel's wrap would cross walls
            raise ValueError(
                f"space: toroidal wraps agents across the box's faces, through obstacles: "
                f"environment {ctx.environment.name!r} has {obstacles} (use space: open or bounded)"
            )

    # -- neighbours --------------------------------------------------------------------------
    def neighbours(self, world: WorldState, sensing: Sensing) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pairs within ``vision`` as index arrays i, j (M,) and p_j - p_i on the steered axes (A, M)."""
        a = self.axes
        pairs = sensing.pairs(self.params.vision)  # the tick's shared pair list (in a torus: the interior)
        if self.params.space != "toroidal":
            return pair_offsets(world.pos, pairs, a)
        if not in_box(world.pos, self.lo[:a], self.hi[:a]):  # not wrapped by the kernel's hooks: wrap a copy
            pos = world.pos.copy()
            pos[:, :a] = wrap(pos[:, :a], self.lo[:a], self.size[:a])
            wrapped = WorldState.at_rest(pos)
            return self.neighbours(wrapped, Sensing(wrapped, sensing.environment, sensing.comm_range))
        return torus_neighbours(world.pos, pairs, self.lo[:a], self.hi[:a], self.params.vision, self._shifts)

    # -- the tick ----------------------------------------------------------------------------
    def setpoints(self, world: WorldState, sensing: Sensing) -> Setpoints:
        """Steer every boid by Mesa's rule from this tick's neighbours; fly the new headings."""
        p = self.params
        heading = current_headings(world.vel, self.heading, p.speed, p.planar)
        i, j, delta = self.neighbours(world, sensing)
        self.heading, self.neighbour_count = self._turned(world.pos, world.healthy, heading, self.heading, i, j, delta)
        self._track_goal(world)
        return self._velocity_setpoints(world.pos, world.healthy, self.heading)

    @classmethod
    def setpoints_batch(cls, formations: Sequence[ReynoldsFlocking], worlds: Sequence[WorldState],
                        sensings: Sequence[Sensing]) -> SetpointBatch | object:
        """``setpoints`` of B flocks of N boids as one :class:`SetpointBatch`. Each flock's pairs
        are found as its own ``setpoints`` finds them (:meth:`neighbours`) and shifted to its rows;
        then one steer over all pairs (each boid's sums taken in its own flock's pair order) and
        the headings, turn and velocities in row-by-row passes over the stacked boids, which give
        every boid its single run's bits. Declined where the instances' options or the worlds'
        sizes differ."""
        first, n = formations[0], len(worlds[0].pos)
        if any(f.params != first.params for f in formations) or any(len(world.pos) != n for world in worlds):
            return NotImplemented
        p = first.params
        pos = np.concatenate([world.pos for world in worlds])
        healthy = np.concatenate([world.healthy for world in worlds])
        last = np.concatenate([f.heading for f in formations])
        heading = current_headings(np.concatenate([world.vel for world in worlds]), last, p.speed, p.planar)
        found = [f.neighbours(world, sensing) for f, world, sensing in zip(formations, worlds, sensings, strict=True)]
        i = np.concatenate([pairs[0] + b * n for b, pairs in enumerate(found)])
        j = np.concatenate([pairs[1] + b * n for b, pairs in enumerate(found)])
        delta = np.concatenate([pairs[2] for pairs in found], axis=1)
        turned, count = first._turned(pos, healthy, heading, last, i, j, delta)
        for b, (f, world) in enumerate(zip(formations, worlds, strict=True)):
            f.heading, f.neighbour_count = turned[b * n:(b + 1) * n], count[b * n:(b + 1) * n]
            f._track_goal(world)
        return SetpointBatch(first._velocity_setpoints(pos, healthy, turned), len(worlds))

    def _turned(self, pos: np.ndarray, healthy: np.ndarray, heading: np.ndarray, last: np.ndarray, i: np.ndarray,
                j: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The new headings (N, 3) and |N_i| (N,) of boids at ``pos`` reading ``heading`` (``last``:
        the previous tick's), from their pairs i, j and offsets ``delta``: the steer, the goal and
        boundary terms, the turn. Row by row, so stacked flocks (their pairs shifted to their rows)
        turn as each alone."""
        p = self.params
        steer, count = self._steer(i, j, delta, heading, healthy, p.cohere, p.match, p.separate, p.separation)
        goal = None
        if p.goal is not None and p.goal_weight > 0:
            size = self.size[: self.axes] if p.space == "toroidal" else None
            goal = goal_steer(pos, np.asarray(p.goal, dtype=float), p.goal_weight, size)
        push = None
        if p.space == "bounded":
            push = boundary_steer(pos, self.lo, self.hi, p.vision, p.boundary_weight)
        return turn_headings(heading, last, healthy, steer, count, p.planar, goal, push), count

    def _velocity_setpoints(self, pos: np.ndarray, healthy: np.ndarray, heading: np.ndarray) -> Setpoints:
        n = len(pos)
        everyone = bool(healthy.all())
        mode = np.full(n, Mode.VELOCITY, dtype=np.int8)
        vel = self.params.speed * heading
        if not everyone:
            mode[~healthy] = Mode.HOLD
            vel[~healthy] = 0.0
        return Setpoints(
            mode=mode,
            pos=pos.copy(),
            vel=vel,
            acc=np.zeros((n, 3)),
            yaw=np.arctan2(heading[:, 1], heading[:, 0]),
        )

    def _track_goal(self, world: WorldState) -> None:
        if self.params.goal is not None:
            centroid = world.pos[world.healthy].mean(axis=0) if world.healthy.any() else world.pos.mean(0)
            self._centroid_error = float(np.linalg.norm(centroid - np.asarray(self.params.goal)))

    def complete(self, world: WorldState) -> bool | None:
        """With a goal: the flock's centroid is within ``goal_tolerance`` of it; else no mission."""
        if self.params.goal is None:
            return None
        return self._centroid_error <= self.params.goal_tolerance

    # -- periodic space ----------------------------------------------------------------------
    def periodic_box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The torus (x-y, or x-y-z when not planar) for the kernel's wrap phase; else ``None``."""
        if self.params.space != "toroidal":
            return None
        return self.lo[: self.axes].copy(), self.size[: self.axes].copy()

    @hookimpl
    def swarmscene_run_end(self, sim: RunView, metrics: dict[str, Any]) -> None:
        """``flocking.*`` metrics: polarization of the healthy boids' headings, mean |N_i|."""
        heading = self.heading[sim.world.healthy]
        unit = heading / np.maximum(np.linalg.norm(heading, axis=1, keepdims=True), 1e-12)
        metrics["flocking.polarization"] = float(np.linalg.norm(unit.mean(axis=0))) if len(unit) else None
        metrics["flocking.mean_neighbours"] = float(self.neighbour_count.mean())


@hookimpl
def swarmscene_register_formations(register) -> None:
    """Register ``reynolds_flocking``."""
    register(ReynoldsFlocking)
