"""Indoor maps of the thesis' section 5.4 and Appendix A, as shapely geometries.

Karydes (2020), chapter 5. Each builder returns an :class:`IndoorMap`: the free space as a
polygon, the walls as one 2-point LineString per wall segment (the boundary of the free space,
split so an STRtree indexes every wall on its own), the leader's way-points (Algorithm 1) and the
end region that every agent must reach. World frame: x east, y north, metres.

The text gives the corridors' length (10 m) and widths but not the rooms around them, nor the
building's plan (only snapshots, Appendix A). Choices: a 6 m x 6 m room at each end of a corridor
(the swarm starts in the entrance room and must funnel into the corridor, which is where the
thesis saw LOS break for w < 0.7 m; it ends in the exit room), and a 28 m x 22 m floor with a
central block of rooms, a 3 m ring corridor, a start hall and an end hall, the path going around
the block (about 64 m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon, box
from shapely.ops import unary_union


@dataclass(frozen=True)
class IndoorMap:
    """An indoor environment for the leader-follower swarm.

    Attributes:
        name: short identifier.
        free_space: the region agents may occupy (walls are its boundary).
        walls: wall segments, each a 2-point LineString (the obstacles O of eq. 5.3).
        waypoints: (n_wp, 2) leader path P, m: ``corners`` resampled every 0.25 m.
        start_region: where random initial swarms are drawn.
        end_region: success region: every agent must end inside it.
        corners: (k, 2) the path's vertices (what a scenario file lists).
    """

    name: str
    free_space: Polygon | MultiPolygon
    walls: list[LineString]
    waypoints: np.ndarray
    start_region: Polygon
    end_region: Polygon
    corners: np.ndarray

    def wall_array(self) -> np.ndarray:
        """(W, 2, 2) wall end points, for configs and plots."""
        return shapely.get_coordinates(np.asarray(self.walls, dtype=object)).reshape(-1, 2, 2)

    def wall_polygons(self, thickness: float = 0.1) -> list[Polygon]:
        """Each wall as a ``thickness`` m rectangle on the outer side of the free space.

        For the engine's environment, whose obstacles are polygons: the walls' inner faces are the
        free-space boundary, so the corridor keeps its width w and every clearance is unchanged.
        """
        seg = self.wall_array()
        a, b = seg[:, 0], seg[:, 1]
        t = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
        normal = np.column_stack([-t[:, 1], t[:, 0]])
        probe = (a + b) / 2 + 1e-6 * normal
        inward = shapely.contains_xy(self.free_space, probe[:, 0], probe[:, 1])
        out = np.where(inward[:, None], -normal, normal) * thickness
        quads = np.stack([a, b, b + out, a + out, a], axis=1)
        return list(shapely.polygons(quads))


def wall_segments(free_space: Polygon | MultiPolygon) -> list[LineString]:
    """The boundary of ``free_space`` (one or several polygons) as one 2-point LineString per segment."""
    parts = shapely.get_parts(free_space)
    rings = [ring for part in parts for ring in (part.exterior, *part.interiors)]
    segs = [np.stack([c[:-1], c[1:]], axis=1) for c in (np.asarray(r.coords) for r in rings)]
    return list(shapely.linestrings(np.concatenate(segs)))


def resample_path(vertices: np.ndarray, spacing: float) -> np.ndarray:
    """Way-points every ``spacing`` m along the polyline ``vertices`` (k, 2), keeping every vertex."""
    out = [vertices[:1]]
    for a, b in zip(vertices[:-1], vertices[1:], strict=True):  # a handful of segments, built once per map
        count = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        t = np.arange(1, count + 1)[:, None] / count
        out.append(a + t * (b - a))
    return np.concatenate(out)


def _room(anchor: np.ndarray, heading: np.ndarray, depth: float, width: float, behind: bool) -> Polygon:
    """A depth x width rectangle whose mid-side sits at ``anchor``, extending along +/-``heading``."""
    t = heading / np.linalg.norm(heading)
    n = np.array([-t[1], t[0]])
    far = anchor + (-depth if behind else depth) * t
    pts = [anchor + width / 2 * n, far + width / 2 * n, far - width / 2 * n, anchor - width / 2 * n]
    return Polygon(pts).normalize()


def corridor_map(
    centerline: np.ndarray,
    width: float,
    name: str,
    room: float = 6.0,
    margin: float = 0.3,
    spacing: float = 0.25,
) -> IndoorMap:
    """A corridor of ``width`` along ``centerline`` between an entrance room and an exit room.

    Args:
        centerline: (k, 2) corridor axis, m; rooms attach at its two ends.
        width: corridor width w, m.
        name: map name.
        room: side of the square rooms, m.
        margin: distance kept from the walls by the start region, m.
        spacing: way-point spacing of the leader path, m.
    """
    centerline = np.asarray(centerline, dtype=float)
    corridor = LineString(centerline).buffer(width / 2, cap_style="flat", join_style="mitre")
    head_in = centerline[1] - centerline[0]
    head_out = centerline[-1] - centerline[-2]
    entrance = _room(centerline[0], head_in, room, room, behind=True)
    exit_room = _room(centerline[-1], head_out, room, room, behind=False)
    free = unary_union([entrance, corridor, exit_room]).normalize()
    t_in = head_in / np.linalg.norm(head_in)
    t_out = head_out / np.linalg.norm(head_out)
    # Leader path: from the room side of the entrance, along the axis, to the middle of the exit
    # room. Algorithm 1 switches to p_{m+1} as soon as the leader passes p_m across the next
    # segment, so a sparse path cuts corners into the walls: the axis is resampled every
    # ``spacing`` m (the thesis asks for a "sufficiently smooth" path).
    axis = np.vstack([centerline[0] - 0.5 * t_in, centerline, centerline[-1] + 0.5 * room * t_out])
    waypoints = resample_path(axis, spacing)
    return IndoorMap(
        name=name,
        free_space=free,
        walls=wall_segments(free),
        waypoints=waypoints,
        start_region=entrance.buffer(-margin, join_style="mitre"),
        end_region=exit_room,
        corners=axis,
    )


def straight_corridor(width: float, length: float = 10.0) -> IndoorMap:
    """Straight corridor of ``length`` (10 m in the thesis) and ``width`` w along +x (Fig. 5.11)."""
    return corridor_map(np.array([[0.0, 0.0], [length, 0.0]]), width, "straight_corridor")


def l_corridor(width: float, length: float = 10.0) -> IndoorMap:
    """L-shaped corridor of total axis length ``length`` (10 m): east, then north (Fig. 5.12)."""
    half = length / 2
    return corridor_map(np.array([[0.0, 0.0], [half, 0.0], [half, half]]), width, "l_corridor")


def building(doors_open: bool = False) -> IndoorMap:
    """A floor plan with rooms and a ring corridor; the path goes around the building (Appendix A).

    28 m x 22 m: start hall (north-west, 10 m x 10 m) and end hall (south-west) separated by a
    2 m wall block; a 3 m corridor runs north, east and south around a 15 m x 16 m central block
    split into four rooms by 0.2 m walls, each room with a 0.9 m door on the corridor. The leader
    leaves the start hall by the north corridor, goes round the block and stops in the end hall.

    Choice: the doors are closed by default (the rooms are then separate pieces of free space).
    With open doors (``doors_open=True``) a tail agent pressed against the block wall can slip
    into a doorway and lose line of sight behind the jamb; the method has no LOS maintenance
    (section 5.3.3), so it is cut off: 2 of 10 runs of N = 100 failed that way with 1.2 m doors
    and still some with 0.9 m doors, while the thesis reports every run successful.
    """
    outer = box(0.0, 0.0, 28.0, 22.0)
    block = box(10.0, 3.0, 25.0, 19.0)
    separation = box(0.0, 10.0, 10.0, 12.0)
    rooms = [box(10.2, 11.1, 17.4, 18.8), box(17.6, 11.1, 24.8, 18.8),
             box(10.2, 3.2, 17.4, 10.9), box(17.6, 3.2, 24.8, 10.9)]
    doors = [box(13.35, 18.7, 14.25, 19.1), box(20.75, 18.7, 21.65, 19.1),
             box(13.35, 2.9, 14.25, 3.3), box(20.75, 2.9, 21.65, 3.3)]
    solid = block.difference(unary_union(rooms + (doors if doors_open else [])))
    free = outer.difference(unary_union([solid, separation])).normalize()
    start_hall = box(0.0, 12.0, 10.0, 22.0)
    end_hall = box(0.0, 0.0, 10.0, 10.0)
    corners = np.array([[5.0, 17.0], [11.5, 20.5], [26.5, 20.5], [26.5, 1.5], [11.5, 1.5], [5.0, 5.0]])
    waypoints = resample_path(corners, 0.25)
    return IndoorMap(
        name="building_open_doors" if doors_open else "building",
        free_space=free,
        walls=wall_segments(free),
        waypoints=waypoints,
        start_region=start_hall.buffer(-0.4, join_style="mitre"),
        end_region=end_hall,
        corners=corners,
    )


def open_map(size: float) -> IndoorMap:
    """An open square of side ``size`` with no walls (scale benchmarks); the path crosses it."""
    free = box(-size / 2, -size / 2, size / 2, size / 2)
    path = np.array([[0.0, 0.0], [size / 2, 0.0]])
    return IndoorMap(
        name="open",
        free_space=free,
        walls=[],
        waypoints=path,
        start_region=free,
        end_region=box(size / 4, -size / 2, size / 2, size / 2),
        corners=path,
    )


def in_region(r: np.ndarray, region: Polygon) -> np.ndarray:
    """(N,) bool: agents inside ``region`` (vectorised shapely.contains_xy)."""
    return shapely.contains_xy(region, r[:, 0], r[:, 1])
