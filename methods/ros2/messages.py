"""The ROS 2 message types a swarmscene bag holds: their definitions and their CDR layouts.

Definitions are those of ROS 2 Humble's ``common_interfaces``, ``geometry2`` (tf2_msgs),
``rcl_interfaces`` and ``rosgraph_msgs`` packages (comments and default values left out, as
rosbag2 stores them). :func:`msgdef` joins a type's definition with those of the types it uses,
depth first, each once, under ``MSG: pkg/Type`` lines of 80 ``=`` (the ``ros2msg`` schema
encoding of MCAP's ROS 2 profile, which mcap-ros2-support, rosbags and Foxglove parse).

Each ``*_message`` function writes one message with a :class:`~swarmscene.methods.ros2.cdr.CdrBuilder`,
naming the slots that change from tick to tick (``stamp``, ``translation``, ...).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .cdr import CdrBuilder

DEFINITIONS: dict[str, str] = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "builtin_interfaces/Duration": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "std_msgs/Float64": "float64 data",
    "std_msgs/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a",
    "rosgraph_msgs/Clock": "builtin_interfaces/Time clock",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w",
    "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose",
    "geometry_msgs/PoseWithCovariance": "geometry_msgs/Pose pose\nfloat64[36] covariance",
    "geometry_msgs/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular",
    "geometry_msgs/TwistWithCovariance": "geometry_msgs/Twist twist\nfloat64[36] covariance",
    "geometry_msgs/Transform": "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation",
    "geometry_msgs/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform"),
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "nav_msgs/Odometry": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist"),
    "rcl_interfaces/Log": (
        "byte DEBUG=10\nbyte INFO=20\nbyte WARN=30\nbyte ERROR=40\nbyte FATAL=50\n"
        "builtin_interfaces/Time stamp\nuint8 level\nstring name\nstring msg\nstring file\n"
        "string function\nuint32 line"),
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "visualization_msgs/UVCoordinate": "float32 u\nfloat32 v",
    "visualization_msgs/MeshFile": "string filename\nuint8[] data",
    "visualization_msgs/Marker": (
        "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n"
        "int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\n"
        "int32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ADD=0\n"
        "int32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\n"
        "std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n"
        "geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n"
        "builtin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\n"
        "std_msgs/ColorRGBA[] colors\nstring texture_resource\nsensor_msgs/CompressedImage texture\n"
        "visualization_msgs/UVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\n"
        "visualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials"),
    "visualization_msgs/MarkerArray": "visualization_msgs/Marker[] markers",
}
"""Each type's own definition (``pkg/Type``: fields, constants first)."""

SEPARATOR = "=" * 80
LOG_LEVELS = {"DEBUG": 10, "INFO": 20, "WARN": 30, "ERROR": 40, "FATAL": 50}
"""rcl_interfaces/msg/Log's levels."""
MARKER = {"CUBE": 1, "SPHERE": 2, "CYLINDER": 3, "LINE_LIST": 5, "SPHERE_LIST": 7, "TRIANGLE_LIST": 11,
          "ADD": 0, "DELETE": 2, "DELETEALL": 3}
"""visualization_msgs/msg/Marker's types and actions used here."""


def short_name(typename: str) -> str:
    """``pkg/msg/Type`` (a bag's spelling) as ``pkg/Type`` (a definition's)."""
    parts = typename.split("/")
    return f"{parts[0]}/{parts[-1]}"


def _used_types(name: str) -> list[str]:
    """The message types a definition's fields name, in field order."""
    used = []
    for line in DEFINITIONS[name].splitlines():
        kind = line.split()[0].split("[")[0]
        if "/" in kind and "=" not in line:
            used.append(kind)
    return used


def msgdef(typename: str) -> str:
    """The ``ros2msg`` schema text of ``typename`` (``pkg/msg/Type``): its definition, then each
    type it uses, depth first, once."""
    root = short_name(typename)
    order: list[str] = []

    def visit(name: str) -> None:
        for used in _used_types(name):
            if used not in order:
                order.append(used)
                visit(used)

    visit(root)
    parts = [DEFINITIONS[root]] + [f"{SEPARATOR}\nMSG: {name}\n{DEFINITIONS[name]}" for name in order]
    return "\n".join(parts) + "\n"


# -- messages -----------------------------------------------------------------------------------
def clock_message() -> CdrBuilder:
    """rosgraph_msgs/msg/Clock; slot ``stamp``."""
    b = CdrBuilder()
    b.time(slot="stamp")
    return b


def float64_message(value: float = 0.0, slot: str | None = "data") -> CdrBuilder:
    """std_msgs/msg/Float64; slot ``data``."""
    b = CdrBuilder()
    b.f64([value], slot)
    return b


def tf_message(parent: str, children: Sequence[str]) -> CdrBuilder:
    """tf2_msgs/msg/TFMessage: one transform ``parent`` -> each child; slots ``stamp`` (per
    transform) and ``transform`` (translation x, y, z, then rotation x, y, z, w)."""
    b = CdrBuilder()
    b.sequence(len(children))
    for child in children:
        b.header(parent, slot="stamp")
        b.string(child)
        b.f64([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], "transform")
    return b


def odometry_message(parent: str, child: str, pose_covariance: np.ndarray | None = None,
                     twist_covariance: np.ndarray | None = None) -> CdrBuilder:
    """nav_msgs/msg/Odometry; slots ``stamp``, ``pose`` (position x, y, z, orientation x, y, z, w)
    and ``twist`` (linear, angular, in the child frame); the 6 x 6 covariances are fixed, zero when
    not given."""
    b = CdrBuilder()
    b.header(parent, slot="stamp")
    b.string(child)
    b.f64([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], "pose")
    b.f64(np.zeros(36) if pose_covariance is None else np.asarray(pose_covariance, float).reshape(36))
    b.f64([0.0] * 6, "twist")
    b.f64(np.zeros(36) if twist_covariance is None else np.asarray(twist_covariance, float).reshape(36))
    return b


def log_message(t: float, level: str, name: str, text: str) -> bytes:
    """rcl_interfaces/msg/Log: a line of the event log (``level`` of :data:`LOG_LEVELS`)."""
    b = CdrBuilder()
    b.time(t)
    b.u8(LOG_LEVELS[level])
    for field in (name, text, "", ""):  # name, msg, file, function
        b.string(field)
    b.u32(0)  # line
    return b.bytes()


def put_marker(b: CdrBuilder, frame: str, ns: str, marker_id: int, kind: str, *, action: str = "ADD",
               t: float = 0.0, pose: Sequence[float] = (0, 0, 0, 0, 0, 0, 1), scale: Sequence[float] = (1, 1, 1),
               rgba: Sequence[float] = (1, 1, 1, 1), points: np.ndarray | None = None,
               colors: np.ndarray | None = None, stamp_slot: str | None = None,
               points_slot: str | None = None) -> None:
    """One visualization_msgs/msg/Marker (lifetime 0: until replaced or deleted)."""
    b.header(frame, t, stamp_slot)
    b.string(ns)
    b.i32(marker_id)
    b.i32(MARKER[kind])
    b.i32(MARKER[action])
    b.f64(list(pose))
    b.f64(list(scale))
    b.f32(list(rgba))
    b.time(0.0)  # lifetime
    b.u8(0)  # frame_locked
    pts = np.zeros((0, 3)) if points is None else np.asarray(points, float).reshape(-1, 3)
    b.sequence(len(pts))
    if len(pts):
        b.f64(pts.reshape(-1).tolist(), points_slot)
    cols = np.zeros((0, 4)) if colors is None else np.asarray(colors, float).reshape(-1, 4)
    b.sequence(len(cols))
    if len(cols):
        b.f32(cols.reshape(-1).tolist())
    b.string("")  # texture_resource
    b.header("")  # texture: sensor_msgs/CompressedImage (none)
    b.string("")
    b.sequence(0)
    b.sequence(0)  # uv_coordinates
    b.string("")  # text
    b.string("")  # mesh_resource
    b.string("")  # mesh_file: filename, data
    b.sequence(0)
    b.u8(0)  # mesh_use_embedded_materials
