"""Map generators: obstacle maps from a few numeric parameters, so a map is swept like any option.

``environment.generator`` chooses one; its parameters sit beside it in the ``environment`` section
(``environment.width=0.5,0.6,0.7`` sweeps a corridor's width) and the run's config records all of
them, defaults included. Listed ``obstacles`` are added to what the generator builds.

- ``corridor``: a corridor of width w between two square rooms, straight or bent once at its middle
  by ``bend`` degrees (thesis section 5.4, Fig. 5.11: straight, and Fig. 5.12: ``bend: 90``, the
  L corridor).
- ``building``: a floor with a start hall and an end hall on its west side and a ring corridor
  around a block of ``rooms`` rooms in two rows, each room with a door on the corridor, open or
  closed (thesis Appendix A: ``rooms: 4``).
- ``obstacle_field``: round obstacles with random sizes at random places until they cover a given
  fraction of a rectangle, never inside the declared free regions (start, goal), seeded.

Walls are built as in the thesis' maps (:mod:`swarmscene.methods.indoor.maps`, which this module
reproduces without importing: the engine owns geometry): the free space is a union of rectangles,
each straight piece of its boundary becomes a ``wall_thickness`` rectangle on the outer side, so the
free space keeps its exact width and every clearance equals the distance to a wall face. Vertices
are rounded to :data:`DECIMALS` places, so a generated map equals its listed-obstacle form exactly.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import shapely
from pydantic import Field, field_validator, model_validator
from shapely.geometry import LineString, Point, Polygon, box
from shapely.ops import unary_union

from .distributions import MAP_STREAM, Draw, number_adapter, parse_draw, stream
from .fields import MAX_LENGTH, Point2, StrictModel, key_error

DECIMALS = 9
"""Decimal places of generated coordinates (1 nm): float sums such as 10.0 + 0.2 land on the
nearest double of the decimal value, as a map written by hand does."""
MAX_FIELD_CANDIDATES = 200_000
"""Random obstacles tried by ``obstacle_field`` before a density is refused as out of reach."""
PARTITION = 0.2
"""Thickness of the walls of the building's block of rooms, m (thesis Appendix A plan)."""
SEPARATION = 2.0
"""Depth of the wall block between the building's start and end halls, m."""
DOOR_OVERLAP = 0.1
"""How far a door opening reaches past each face of the wall it cuts, m (a clean cut)."""

class CorridorParams(StrictModel):
    """``generator: corridor``: thesis section 5.4 (10 m corridors; 6 m rooms are this engine's choice)."""

    width: float = Field(gt=0, le=MAX_LENGTH, description="corridor width w, m")
    length: float = Field(10.0, gt=0, le=MAX_LENGTH, description="corridor length along its axis, m")
    bend: float = Field(
        0.0, gt=-180, lt=180,
        description="turn at the corridor's middle, degrees, positive to the left (90: the L corridor)",
    )
    room: float = Field(6.0, gt=0, le=MAX_LENGTH, description="side of the square room at each end, m")
    wall_thickness: float = Field(0.1, gt=0, le=MAX_LENGTH, description="wall rectangles' thickness, m")


class BuildingParams(StrictModel):
    """``generator: building``: thesis Appendix A (four rooms: a 28 m x 22 m floor)."""

    rooms: int = Field(4, ge=2, le=1000, description="rooms in the central block, two rows (even)")
    doors_open: bool = Field(False, description="each room's door onto the ring corridor is open")
    door_width: float = Field(0.9, gt=0, le=MAX_LENGTH, description="m")
    room_size: tuple[float, float] = Field(
        (7.2, 7.7), description="[along the rows (east), across (north)] of each room, m"
    )
    corridor_width: float = Field(3.0, gt=0, le=MAX_LENGTH, description="ring corridor width, m")
    hall: float = Field(
        10.0, gt=0, le=MAX_LENGTH, description="east-west depth of the start and end halls, m"
    )
    wall_thickness: float = Field(0.1, gt=0, le=MAX_LENGTH, description="wall rectangles' thickness, m")

    @field_validator("rooms")
    @classmethod
    def _even(cls, value: int) -> int:
        if value % 2:
            raise ValueError("must be even (two rows of rooms)")
        return value

    @field_validator("room_size")
    @classmethod
    def _positive(cls, value: tuple[float, float]) -> tuple[float, float]:
        if min(value) <= 0 or max(value) > MAX_LENGTH:
            raise ValueError(f"must be two lengths in (0, {MAX_LENGTH:g}] m")
        return value

    @model_validator(mode="after")
    def _door_fits(self) -> BuildingParams:
        if self.door_width >= self.room_size[0]:
            width = self.room_size[0]
            raise key_error("door_width", f"must be < the room's width {width} m", self.door_width)
        return self


class FreeRegion(StrictModel):
    """A disc that no generated obstacle enters (a start or a goal area)."""

    center: Point2 = Field(description="[x, y], m")
    radius: float = Field(gt=0, le=MAX_LENGTH, description="m")


_RADIUS = number_adapter(0.0, MAX_LENGTH)


class ObstacleFieldParams(StrictModel):
    """``generator: obstacle_field``: random round obstacles (pillars, trees) of a given density."""

    bounds: tuple[float, float, float, float] = Field(
        (0.0, -10.0, 40.0, 10.0), description="[x_min, y_min, x_max, y_max] of the obstacles' centres, m"
    )
    density: float = Field(
        gt=0, le=0.5, description="fraction of the bounds' area the obstacles cover (a disc counts whole)"
    )
    radius: Draw | float = Field(
        description="obstacle radius, m: a number or a distribution with positive values "
        "({uniform: [a, b]} with a > 0, {lognormal: [mu, sigma]}, {exponential: mean}, {choice: [...]})"
    )
    gap: float = Field(0.0, ge=0, le=MAX_LENGTH, description="least distance between two obstacles, m")
    free_regions: list[FreeRegion] = Field(
        default_factory=list, description="discs kept free of obstacles (start and goal areas)"
    )
    seed: int = Field(0, ge=0, description="seed of the map's own stream (not the run's generator)")

    @field_validator("radius", mode="wrap")
    @classmethod
    def _number_or_distribution(cls, value: Any, handler: Any) -> Any:
        radius = parse_draw(value, _RADIUS)
        if not (radius.positive() if isinstance(radius, Draw) else radius > 0):
            raise ValueError("must be a positive number or a distribution of positive values "
                             "(uniform with low > 0, lognormal, exponential, choice of positives)")
        return radius

    @field_validator("bounds")
    @classmethod
    def _ordered(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        if not (value[0] < value[2] and value[1] < value[3]) or max(map(abs, value)) > MAX_LENGTH:
            raise ValueError("must be [x_min, y_min, x_max, y_max] with x_min < x_max, y_min < y_max")
        return value


# -- shared construction ----------------------------------------------------------------------
def snap(value: Any) -> Any:
    """Coordinates rounded to :data:`DECIMALS` places (Python's correctly rounded ``round``)."""
    array = np.asarray(value, dtype=float)
    return np.vectorize(lambda x: round(float(x), DECIMALS) + 0.0, otypes=[float])(array)


def snapped_box(x0: float, y0: float, x1: float, y1: float) -> Polygon:
    """The rectangle [x0, x1] x [y0, y1], its corners rounded by :func:`snap` like every generated
    coordinate, so that boxes built from the same numbers share exact edges."""
    return box(*snap([x0, y0, x1, y1]))


def wall_polygons(free_space: Any, thickness: float) -> list[Polygon]:
    """Each straight piece of the boundary of ``free_space`` as a ``thickness`` rectangle on its
    outer side: the rectangle [a, b, b + t n_out, a + t n_out], in the boundary's order."""
    parts = shapely.get_parts(free_space)
    rings = [ring for part in parts for ring in (part.exterior, *part.interiors)]
    coords = [np.asarray(ring.coords) for ring in rings]
    segments = np.concatenate([np.stack([c[:-1], c[1:]], axis=1) for c in coords])
    a, b = segments[:, 0], segments[:, 1]
    tangent = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    probe = (a + b) / 2 + 1e-6 * normal
    inward = shapely.contains_xy(free_space, probe[:, 0], probe[:, 1])
    out = np.where(inward[:, None], -normal, normal) * thickness
    quads = snap(np.stack([a, b, b + out, a + out, a], axis=1))
    return list(shapely.polygons(quads))


# -- corridor ---------------------------------------------------------------------------------
def corridor_axis(params: CorridorParams) -> np.ndarray:
    """(k, 2) corridor axis from the origin east: straight, or bent by ``bend`` at its middle."""
    if params.bend == 0:
        return snap([[0.0, 0.0], [params.length, 0.0]])
    half, turn = params.length / 2, math.radians(params.bend)
    return snap([[0.0, 0.0], [half, 0.0], [half + half * math.cos(turn), half * math.sin(turn)]])


def _room(anchor: np.ndarray, heading: np.ndarray, side: float, behind: bool) -> Polygon:
    """A square of ``side`` whose mid-side sits at ``anchor``, before or after it along ``heading``."""
    t = heading / np.linalg.norm(heading)
    n = np.array([-t[1], t[0]])
    far = anchor + (-side if behind else side) * t
    pts = [anchor + side / 2 * n, far + side / 2 * n, far - side / 2 * n, anchor - side / 2 * n]
    return Polygon(snap(pts)).normalize()


def corridor_free_space(params: CorridorParams) -> Any:
    """Entrance room, corridor of width w along :func:`corridor_axis`, exit room (one polygon)."""
    axis = corridor_axis(params)
    corridor = LineString(axis).buffer(params.width / 2, cap_style="flat", join_style="mitre")
    entrance = _room(axis[0], axis[1] - axis[0], params.room, behind=True)
    exit_room = _room(axis[-1], axis[-1] - axis[-2], params.room, behind=False)
    return unary_union([entrance, corridor, exit_room]).normalize()


def corridor(params: CorridorParams) -> list[Polygon]:
    """The corridor map's walls."""
    return wall_polygons(corridor_free_space(params), params.wall_thickness)


# -- building ---------------------------------------------------------------------------------
def building_free_space(params: BuildingParams) -> Any:
    """The floor minus the block of rooms (rooms hollow, doors cut when open) and the wall block
    between the halls. Layout, x east: halls [0, hall], block from x = hall, ring corridor around
    it; y north: the block between corridors of ``corridor_width``, the halls split at mid-height."""
    per_row = params.rooms // 2
    rx, ry = params.room_size
    p, c = PARTITION, params.corridor_width
    block_w, block_h = per_row * rx + (per_row + 1) * p, 2 * ry + 3 * p
    width, height = params.hall + block_w + c, block_h + 2 * c
    x0 = params.hall + p + np.arange(per_row) * (rx + p)  # each column's west wall face
    rows = [(c + 2 * p + ry, c + 2 * p + 2 * ry), (c + p, c + p + ry)]  # north row, south row
    rooms = [snapped_box(x, y0, x + rx, y1) for y0, y1 in rows for x in x0]
    mid = x0 + rx / 2
    door_rows = [(rows[0][1] - DOOR_OVERLAP, c + block_h + DOOR_OVERLAP),
                 (c - DOOR_OVERLAP, rows[1][0] + DOOR_OVERLAP)]
    doors = [snapped_box(m - params.door_width / 2, y0, m + params.door_width / 2, y1)
             for y0, y1 in door_rows for m in mid]
    block = snapped_box(params.hall, c, params.hall + block_w, c + block_h)
    solid = block.difference(unary_union(rooms + (doors if params.doors_open else [])))
    separation = snapped_box(0.0, (height - SEPARATION) / 2, params.hall, (height + SEPARATION) / 2)
    return snapped_box(0.0, 0.0, width, height).difference(unary_union([solid, separation])).normalize()


def building(params: BuildingParams) -> list[Polygon]:
    """The building map's walls."""
    return wall_polygons(building_free_space(params), params.wall_thickness)


# -- random obstacle field --------------------------------------------------------------------
def obstacle_field_discs(params: ObstacleFieldParams) -> tuple[np.ndarray, np.ndarray]:
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


FIELD_BATCH = 1024
"""Candidate obstacles drawn at once by ``obstacle_field``."""


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


def obstacle_field(params: ObstacleFieldParams) -> list[Polygon]:
    """The field's discs as polygons (the same 16-segment quarter circles as a listed circle)."""
    centres, radii = obstacle_field_discs(params)
    return [Point(c).buffer(r, quad_segs=16) for c, r in zip(centres, radii, strict=True)]


class MapGenerator:
    """A map generator: obstacle footprints from a few numeric parameters (``environment.generator``).

    Subclasses declare ``name``, a ``Params`` model (its parameters, which sit beside
    ``generator`` in the ``environment`` section: ``environment.width=0.5``) and :meth:`build`.
    Errors a build finds (a density out of reach) are ``ValueError`` whose message starts with
    the key it names (``environment.density: ...``).
    """

    name: ClassVar[str]
    Params: ClassVar[type[StrictModel]] = StrictModel

    @classmethod
    def build(cls, params: Any) -> list[Polygon]:
        """The obstacle footprints (shapely polygons, m) of ``params``, a validated ``Params``."""
        raise NotImplementedError


class Corridor(MapGenerator):
    """A corridor of width w between two square rooms, straight or bent once (thesis 5.4)."""

    name = "corridor"
    Params = CorridorParams

    @classmethod
    def build(cls, params: Any) -> list[Polygon]:
        """The corridor's wall polygons (:func:`corridor`)."""
        return corridor(params)


class Building(MapGenerator):
    """A floor with start and end halls and a ring corridor around rooms (thesis Appendix A)."""

    name = "building"
    Params = BuildingParams

    @classmethod
    def build(cls, params: Any) -> list[Polygon]:
        """The building's wall polygons (:func:`building`)."""
        return building(params)


class ObstacleField(MapGenerator):
    """Round obstacles of random sizes covering a fraction of a rectangle, seeded."""

    name = "obstacle_field"
    Params = ObstacleFieldParams

    @classmethod
    def build(cls, params: Any) -> list[Polygon]:
        """The field's round obstacles (:func:`obstacle_field`), drawn from its ``seed``."""
        return obstacle_field(params)


BUILTIN_GENERATORS: tuple[type[MapGenerator], ...] = (Corridor, Building, ObstacleField)
"""The built-in generators (``plugins/generator/`` registers each through
``swarmscene_register_generators``; the numerics above stay here, beside the geometry they share)."""
