"""Vehicle positions read back from a recording: an MCAP file or a rosbag2 folder with MCAP storage.

Two sources, as labs record them:

* TF (``tf2_msgs/msg/TFMessage`` on ``/tf``, Crazyswarm2's and Aerostack2's way): each transform
  whose parent is the world frame gives its child frame's position (``transform.translation``) at
  its header stamp;
* pose topics, one per vehicle: ``geometry_msgs/msg/PoseStamped`` (``pose.position``),
  ``nav_msgs/msg/Odometry`` (``pose.pose.position``) or ``geometry_msgs/msg/TransformStamped``
  (``transform.translation``), each at its header stamp.

The messages are decoded with mcap-ros2-support from the schemas the file carries (the ``ros``
extra). A recording is a file someone hands the engine: anything wrong with it (missing, a
directory that is not a rosbag2 folder, storage other than MCAP, a truncated or damaged file, a
chunk larger than :data:`MAX_CHUNK_BYTES`, a message its schema does not decode or whose fields
are not its type's, a position that is not finite, stamps spread wider than any run) is a
:class:`BagError`, one line naming the file. The records are read in file order, as a scan has
checked them: every chunk's size, as its own record declares it and, for lz4 (whose decoder
trusts no declared size), as it decompresses; a summary's index is not followed (a damaged one
may point anywhere).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

MAX_CHUNK_BYTES = 256 * 1024 * 1024
"""Largest uncompressed chunk read (a hostile file could declare a decompression bomb)."""
MAX_METADATA_BYTES = 1024 * 1024
"""Largest rosbag2 metadata.yaml read."""
MAX_SPAN_S = 1e9
"""Widest spread of a recording's stamps, s: a run is no longer (``core.fields.MAX_DURATION``). A
wider one is a stamp from another clock (0, or a simulated time among a lab's), whose spline
would put the reference ~1e9 m away."""
POSE_FIELDS = {
    "geometry_msgs/msg/PoseStamped": ("pose", "position"),
    "nav_msgs/msg/Odometry": ("pose", "pose", "position"),
    "geometry_msgs/msg/TransformStamped": ("transform", "translation"),
}
"""Where each pose message type keeps its position."""
TF_TYPE = "tf2_msgs/msg/TFMessage"
EXAMPLE_FLIGHT = Path(__file__).with_name("example_flight")
"""A rosbag2 folder shipped with the package: eight Crazyflies ``cf1``..``cf8`` circling (2 m radius,
20 s a turn, 1.0 +- 0.3 m high),
TF in a ``world`` frame at 10 Hz for 20 s, written by rosbags (docs/examples/ros/make_example_flight.py)."""


class BagError(ValueError):
    """A recording that cannot be read; ``str()`` is one line starting with the file."""

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = Path(path)
        super().__init__(f"{self.path}: {problem}")


@dataclass(frozen=True)
class Track:
    """One vehicle's recorded positions.

    Attributes:
        name: its frame id (TF) or topic.
        t: (K,) s, the header stamps from the recording's earliest one, increasing.
        pos: (K, 3) m, in the recording's world frame.
    """

    name: str
    t: np.ndarray
    pos: np.ndarray


def mcap_files(path: Path | str) -> list[Path]:
    """The MCAP files of a recording: the file itself, or a rosbag2 folder's files as its
    metadata.yaml lists them (each a plain file inside the folder)."""
    path = Path(path)
    if not path.exists():
        raise BagError(path, "missing (give an .mcap file or a rosbag2 folder)")
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise BagError(path, "not a file or a folder")
    meta = path / "metadata.yaml"
    if not meta.is_file() or meta.is_symlink():
        found = sorted(path.glob("*.mcap"))
        if len(found) == 1 and found[0].is_file() and not found[0].is_symlink():  # not a pipe: it would block
            return found  # a folder holding one .mcap (a bag copied without its metadata)
        raise BagError(path, "not a rosbag2 folder (no metadata.yaml, and not one plain .mcap file in it)")
    info = _metadata(meta)
    storage = info.get("storage_identifier")
    if storage != "mcap":
        raise BagError(meta, f"storage_identifier is {storage!r}: only MCAP storage is read "
                             "(convert with `ros2 bag convert` or rosbags-convert)")
    files = []
    listed = info.get("relative_file_paths") or []
    if not isinstance(listed, list):
        raise BagError(meta, f"relative_file_paths is {type(listed).__name__}, not a list of file names")
    for name in listed:
        rel = Path(str(name))
        if rel.is_absolute() or ".." in rel.parts:
            raise BagError(meta, f"relative_file_paths names {str(name)!r}, outside the folder")
        file = path / rel
        # every part, not only the file: a linked subfolder would lead outside the folder
        if any((path / Path(*rel.parts[:k])).is_symlink() for k in range(1, len(rel.parts) + 1)) or not file.is_file():
            raise BagError(file, "listed in metadata.yaml but not a plain file inside the folder")
        files.append(file)
    if not files:
        raise BagError(meta, "lists no files (relative_file_paths)")
    return files


def _metadata(meta: Path) -> dict[str, Any]:
    import yaml

    if meta.stat().st_size > MAX_METADATA_BYTES:
        raise BagError(meta, f"too large (at most {MAX_METADATA_BYTES} bytes)")
    try:
        data = yaml.safe_load(meta.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, yaml.YAMLError, RecursionError) as exc:
        raise BagError(meta, f"not valid YAML ({' '.join(str(exc).split())[:120]})") from None
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise BagError(meta, "lacks rosbag2_bagfile_information")
    return info


def _decoded(file: Path, topics: list[str]) -> Iterator[tuple[str, str, Any]]:
    """(channel topic, schema name, decoded message) of ``topics`` in ``file``, in file order:
    the records :func:`_check_chunks` scanned, read again one after another (not through the
    summary's index; a long recording is not held in memory)."""
    from mcap.reader import NonSeekingReader
    from mcap_ros2.decoder import DecoderFactory

    with open(file, "rb") as fh:
        _check_chunks(file, fh)
        fh.seek(0)
        reader = NonSeekingReader(fh, decoder_factories=[DecoderFactory()], record_size_limit=MAX_CHUNK_BYTES)
        for schema, channel, _message, decoded in reader.iter_decoded_messages(topics=topics, log_time_order=False):
            yield channel.topic, schema.name if schema is not None else "", decoded


def _check_chunks(file: Path, fh: Any) -> None:
    """Every chunk of the file no larger than :data:`MAX_CHUNK_BYTES` uncompressed: as its record
    declares (the zstd decoder is held to that size), and an lz4 chunk as it decompresses (its
    decoder is not), decompressed here at most one byte past what it declares."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    for record in StreamReader(fh, emit_chunks=True, record_size_limit=MAX_CHUNK_BYTES).records:
        if not isinstance(record, Chunk):
            continue
        if record.uncompressed_size > MAX_CHUNK_BYTES:
            raise BagError(file, f"a chunk of {record.uncompressed_size} bytes (at most {MAX_CHUNK_BYTES} are read)")
        if record.compression == "lz4":
            import lz4.frame

            out = lz4.frame.LZ4FrameDecompressor().decompress(record.data, max_length=record.uncompressed_size + 1)
            if len(out) > record.uncompressed_size:
                raise BagError(file, f"an lz4 chunk decompresses past the {record.uncompressed_size} bytes it declares")


def read_messages(path: Path | str, topics: list[str]) -> Iterator[tuple[str, str, Any]]:
    """Every message of ``topics`` in the recording, decoded, one at a time (a long recording is not
    held in memory); any damage is one :class:`BagError` line naming the file."""
    for file in mcap_files(path):
        try:
            yield from _decoded(file, topics)
        except BagError:
            raise
        except ImportError as exc:
            raise BagError(file, f"reading it needs the 'ros' extra: pip install 'swarmscene[ros]' ({exc})") from None
        except Exception as exc:  # noqa: BLE001 - whatever a damaged file makes the reader raise
            first = " ".join(str(exc).split())[:160] or type(exc).__name__
            raise BagError(file, f"not a readable MCAP recording ({type(exc).__name__}: {first})") from None


def _stamp(header: Any) -> int:
    """The header's stamp in integer ns (a lab clock's ~1.7e9 s as a float keeps only ~0.2 us)."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _position(message: Any, fields: tuple[str, ...]) -> tuple[float, float, float]:
    for name in fields:
        message = getattr(message, name)
    return float(message.x), float(message.y), float(message.z)


def natural_key(name: str) -> list[Any]:
    """Sort key putting ``cf2`` before ``cf10``."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name)]


def tf_tracks(path: Path | str, topic: str, world_frame: str) -> dict[str, Track]:
    """Every child frame of ``world_frame`` on the TF ``topic``, by frame id (a leading ``/`` dropped)."""
    samples: dict[str, list[tuple[int, float, float, float]]] = {}
    world = world_frame.lstrip("/")
    for _topic, schema, msg in read_messages(path, [topic]):
        if schema != TF_TYPE:
            raise BagError(path, f"topic {topic} holds {schema}, not {TF_TYPE}")
        try:
            for tf in msg.transforms:
                if tf.header.frame_id.lstrip("/") == world:
                    samples.setdefault(tf.child_frame_id.lstrip("/"), []).append(
                        (_stamp(tf.header), *_position(tf, ("transform", "translation"))))
        except (AttributeError, TypeError, ValueError) as exc:  # a schema of that name with other fields
            raise _misshapen(path, topic, TF_TYPE, exc) from None
    return _tracks(path, samples)


def pose_tracks(path: Path | str, topics: list[str]) -> dict[str, Track]:
    """The positions on each pose topic (module docstring), by topic."""
    samples: dict[str, list[tuple[int, float, float, float]]] = {t: [] for t in topics}
    for topic, schema, msg in read_messages(path, topics):
        fields = POSE_FIELDS.get(schema)
        if fields is None:
            raise BagError(path, f"topic {topic} holds {schema}: a pose topic is one of {', '.join(POSE_FIELDS)}")
        try:
            samples[topic].append((_stamp(msg.header), *_position(msg, fields)))
        except (AttributeError, TypeError, ValueError) as exc:  # a schema of that name with other fields
            raise _misshapen(path, topic, schema, exc) from None
    return _tracks(path, {name: rows for name, rows in samples.items() if rows})


def _misshapen(path: Path | str, topic: str, type_name: str, exc: Exception) -> BagError:
    """A message whose schema has its type's name but other fields (a hand-made recording)."""
    return BagError(path, f"topic {topic}: a message not shaped as {type_name} ({type(exc).__name__}: {exc})")


def _tracks(path: Path | str, samples: dict[str, list[tuple[int, float, float, float]]]) -> dict[str, Track]:
    """Each vehicle's samples in time order, one per stamp (the last written for a repeated stamp),
    times in s from the earliest stamp of them all (subtracted in integer ns: exact). A position
    that is not finite, or stamps spread wider than :data:`MAX_SPAN_S`, is a :class:`BagError`."""
    if not samples:
        return {}
    origin = min(min(row[0] for row in rows) for rows in samples.values())
    last = max(max(row[0] for row in rows) for rows in samples.values())
    if (last - origin) * 1e-9 > MAX_SPAN_S:
        raise BagError(path, f"its stamps span {(last - origin) * 1e-9:.4g} s ({origin} to {last} ns), wider than a "
                             f"run can be ({MAX_SPAN_S:g} s): a stamp from another clock (0?)")
    for name, rows in samples.items():
        bad = next((row for row in rows if not all(math.isfinite(v) for v in row[1:])), None)
        if bad is not None:
            raise BagError(path, f"{name}: a position that is not finite ({bad[1:]}) at stamp {bad[0]} ns")
    out = {}
    for name, rows in samples.items():
        ns = np.array([row[0] for row in rows], dtype=np.int64) - origin
        pos = np.array([row[1:] for row in rows], dtype=float).reshape(-1, 3)
        order = np.argsort(ns, kind="stable")
        ns, pos = ns[order], pos[order]
        keep = np.append(np.diff(ns) > 0, True)  # the last of equal stamps
        out[name] = Track(name, ns[keep] * 1e-9, pos[keep])
    return out
