"""A minimal MCAP writer whose per-tick path is one NumPy fill and one append.

MCAP (https://mcap.dev/spec, format version 0) is a log of records: a magic, a Header, Schema and
Channel records, Chunks of Message records (each Chunk followed by one Message Index record per
channel in it), Data End, a summary section (the Schemas and Channels again, Chunk Indexes,
Statistics) with its Summary Offsets, a Footer and the magic again. Every record is an opcode
(uint8), a content length (uint64) and the content; strings are a uint32 byte length and UTF-8
bytes; maps a uint32 byte length and their pairs.

Why not the ``mcap`` package's ``Writer``: it builds each message record in Python (about 15 us a
message), so a tick of 100 vehicles' odometry costs 1.5 ms, several times a swarm's own tick. Here
the messages of a tick are laid out once (:class:`RecordBlock`: channels and payload layouts fixed
for the run) and each tick fills that block with a few strided copies; each full chunk is
compressed and written by a writer thread while the run goes on; message indexes are built per
chunk from arrays. The CRC fields are left 0, "not computed", which the specification allows. The
files are read back in the tests by four independent readers: ``mcap``, mcap-ros2-support,
rosbags and Rerun (tests/test_ros_bag.py).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import IO, Any

import numpy as np

from ..methods.ros2.cdr import CdrTemplate

MAGIC = b"\x89MCAP0\r\n"
OP = {"header": 0x01, "footer": 0x02, "schema": 0x03, "channel": 0x04, "message": 0x05, "chunk": 0x06,
      "message_index": 0x07, "chunk_index": 0x08, "statistics": 0x0B, "metadata": 0x0C,
      "summary_offset": 0x0E, "data_end": 0x0F}
"""Record opcodes (MCAP specification, "Records")."""
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # opcode, length, channel_id, sequence, log_time, publish_time
CHUNK_BYTES = 4 * 1024 * 1024
"""Uncompressed bytes of messages gathered before a chunk is compressed and written."""


def _string(text: str) -> bytes:
    raw = text.encode()
    return struct.pack("<I", len(raw)) + raw


def _map(pairs: Sequence[tuple[bytes, bytes]]) -> bytes:
    body = b"".join(k + v for k, v in pairs)
    return struct.pack("<I", len(body)) + body


def _record(op: str, content: bytes) -> bytes:
    return struct.pack("<BQ", OP[op], len(content)) + content


class RecordBlock:
    """Message records of a fixed layout, one per (channel, message of ``template``), refilled
    each time they are written: the time fields and the template's slots change, nothing else.

    Args:
        channels: the channel id of each of ``template``'s messages.
        template: their payloads (:class:`~swarmscene.methods.ros2.cdr.CdrTemplate`).
    """

    def __init__(self, channels: Sequence[int], template: CdrTemplate) -> None:
        if len(channels) != template.count:
            raise ValueError(f"{len(channels)} channels for {template.count} messages")
        self.template = template
        self.channels = np.asarray(channels, dtype=np.uint16)
        sizes = np.diff(template.bounds)
        heads = [_MESSAGE_HEAD.pack(OP["message"], 22 + int(size), int(ch), 0, 0, 0)
                 for ch, size in zip(self.channels, sizes, strict=True)]
        payloads = template.split(template.base.tobytes())
        self.base = np.frombuffer(b"".join(h + p for h, p in zip(heads, payloads, strict=True)), np.uint8).copy()
        self.offsets = np.concatenate([[0], np.cumsum(sizes + _MESSAGE_HEAD.size)[:-1]]).astype(np.int64)
        # where each payload byte moved: payload k's bytes shift by the heads before it and its own
        shift = np.repeat(np.arange(1, len(sizes) + 1) * _MESSAGE_HEAD.size, sizes)
        self.slots = {name: (dtype, index + shift[index]) for name, (dtype, index) in template.index.items()}
        times = (self.offsets[:, None] + 15 + np.arange(16)).reshape(-1)  # log_time, publish_time
        self.slots["_times"] = ("<u8", times)

        self.out = self.base.copy()  # filled in place each time: the bytes outside the slots never change
        self.views = {name: _strided_views(self.out, index) for name, (dtype, index) in self.slots.items()}
        self.counts = np.bincount(self.channels)  # messages per channel id in one block

    def fill(self, t_ns: int, **values: Any) -> np.ndarray:
        """The records (a buffer reused by the next call) at log and publish time ``t_ns`` with the
        template's slots set. A slot's value is all its numbers, or one run's worth (the ``stamp``
        of a tick): that run is then written into every run of the slot."""
        values["_times"] = np.array([t_ns, t_ns], dtype=np.uint64)
        for name, (dtype, _) in self.slots.items():
            raw = np.ascontiguousarray(values[name], dtype=dtype).reshape(-1).view(np.uint8)
            for view, start, length in self.views[name]:
                view[...] = raw if raw.size == view.shape[1] else raw[start:start + length].reshape(view.shape)
        return self.out


def _strided_views(out: np.ndarray, index: np.ndarray) -> list[tuple[np.ndarray, int, int]]:
    """A slot's bytes ``index`` (in value order) as few 2-D strided views of ``out`` (runs of equal
    length at a constant stride: the same field of messages of one layout), each with where its
    bytes start in the slot's value and how many there are: the fill is then a handful of strided
    copies instead of a gather of every byte."""
    from numpy.lib.stride_tricks import as_strided

    breaks = np.flatnonzero(np.diff(index) != 1) + 1
    starts = np.concatenate([[0], breaks])  # positions in index where a contiguous run starts
    lengths = np.diff(np.concatenate([starts, [len(index)]]))
    views: list[tuple[np.ndarray, int, int]] = []
    k = 0
    while k < len(starts):  # the longest progression from run k: same length, constant stride
        j = k + 1
        stride = int(index[starts[j]] - index[starts[k]]) if j < len(starts) else 0
        while (j < len(starts) and lengths[j] == lengths[k]
               and index[starts[j]] - index[starts[j - 1]] == stride and stride > 0):
            j += 1
        count, length = j - k, int(lengths[k])
        first = int(index[starts[k]])
        view = as_strided(out[first:], shape=(count, length), strides=(stride if count > 1 else length, 1))
        views.append((view, int(starts[k]), count * length))
        k = j
    return views


class McapWriter:
    """Writes an MCAP file to ``fh`` (an open binary file, positioned at 0).

    Args:
        fh: the file.
        profile: the Header's profile (``ros2``: the messages are CDR, the schemas ``ros2msg``).
        library: the Header's library string.
        compression: chunk compression, ``zstd``, ``lz4`` or ``""`` (none).
        chunk_bytes: uncompressed bytes per chunk.
    """

    def __init__(self, fh: IO[bytes], profile: str, library: str, compression: str = "zstd",
                 chunk_bytes: int = CHUNK_BYTES) -> None:
        self.fh = fh
        self.compression = compression
        self.chunk_bytes = chunk_bytes
        self._compress = _compressor(compression)
        self.schemas: list[bytes] = []
        self.channels: list[bytes] = []
        self.chunk_indexes: list[bytes] = []
        self.counts = np.zeros(1, dtype=np.int64)  # messages per channel id (0 unused)
        self.message_count = 0
        self.start_time: int | None = None
        self.end_time = 0
        self.metadata_count = 0
        self._chunk = np.zeros(chunk_bytes + 1024 * 1024, dtype=np.uint8)  # grown when a block does not fit
        self._spare: np.ndarray | None = None  # the other buffer, while one is compressed and written
        self._chunk_size = 0
        self._index: list[tuple[np.ndarray, int, np.ndarray]] = []  # (channels, time, offsets in the chunk)
        self._pool: Any = None
        self._pending: Any = None
        self._chunk_times: tuple[int, int] | None = None
        fh.write(MAGIC)
        fh.write(_record("header", _string(profile) + _string(library)))

    # -- schemas and channels ---------------------------------------------------------------------
    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """A Schema record; its id (from 1)."""
        schema_id = len(self.schemas) + 1
        content = struct.pack("<H", schema_id) + _string(name) + _string(encoding) + struct.pack("<I", len(data)) + data
        record = _record("schema", content)
        self.schemas.append(record)
        self.fh.write(record)
        return schema_id

    def add_channel(self, topic: str, schema_id: int, encoding: str, metadata: dict[str, str] | None = None) -> int:
        """A Channel record; its id (from 1, as rosbag2 numbers them: rosbags takes the ids for its own)."""
        channel_id = len(self.channels) + 1
        pairs = [(_string(k), _string(v)) for k, v in sorted((metadata or {}).items())]
        content = struct.pack("<HH", channel_id, schema_id) + _string(topic) + _string(encoding) + _map(pairs)
        record = _record("channel", content)
        self.channels.append(record)
        self.counts = np.append(self.counts, 0)
        self.fh.write(record)
        return channel_id

    # -- messages -----------------------------------------------------------------------------------
    def write_block(self, block: RecordBlock, t_ns: int, **values: Any) -> None:
        """``block``'s messages at time ``t_ns`` (ns), slots from ``values``."""
        self._append(block.fill(t_ns, **values), block.channels, block.offsets, t_ns, block.counts)

    def write_message(self, channel_id: int, t_ns: int, data: bytes) -> None:
        """One message (a rare one: a log line, a marker) at time ``t_ns``."""
        head = _MESSAGE_HEAD.pack(OP["message"], 22 + len(data), channel_id, 0, t_ns, t_ns)
        record = np.frombuffer(head + data, dtype=np.uint8)
        self._append(record, np.array([channel_id], np.uint16), np.zeros(1, np.int64), t_ns,
                     np.bincount([channel_id]))

    def _append(self, records: np.ndarray, channels: np.ndarray, offsets: np.ndarray, t_ns: int,
                counts: np.ndarray) -> None:
        end = self._chunk_size + len(records)
        if end > len(self._chunk):
            self._chunk = np.concatenate([self._chunk[:self._chunk_size], np.zeros(2 * len(records), np.uint8),
                                          np.zeros(len(self._chunk), np.uint8)])
        self._chunk[self._chunk_size:end] = records  # one copy of the tick's bytes
        self._index.append((channels, t_ns, offsets + self._chunk_size))
        self._chunk_size = end
        lo, hi = self._chunk_times or (t_ns, t_ns)
        self._chunk_times = (min(lo, t_ns), max(hi, t_ns))
        self.counts[:len(counts)] += counts
        self.message_count += len(channels)
        self.start_time = t_ns if self.start_time is None else min(self.start_time, t_ns)
        self.end_time = max(self.end_time, t_ns)
        if self._chunk_size >= self.chunk_bytes:
            self.flush_chunk()

    def flush_chunk(self) -> None:
        """Hand the gathered messages to the writer thread, which compresses them and writes the
        Chunk and its Message Index records (one chunk in flight at most: memory stays two chunks)."""
        if not self._chunk_size:
            return
        self.wait()
        job = (self._chunk, self._chunk_size, self._index, self._chunk_times or (0, 0))
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(1, thread_name_prefix="mcap-chunks")
        self._pending = self._pool.submit(self._write_chunk, *job)
        self._chunk, self._spare = self._spare if self._spare is not None else np.zeros_like(self._chunk), self._chunk
        self._chunk_size, self._index, self._chunk_times = 0, [], None

    def wait(self) -> None:
        """Wait for the chunk in flight (its error, if any, is raised here)."""
        if self._pending is not None:
            pending, self._pending = self._pending, None
            pending.result()

    def _write_chunk(self, buffer: np.ndarray, size: int, index: list[tuple[np.ndarray, int, np.ndarray]],
                     times: tuple[int, int]) -> None:
        """Compress (zstandard and lz4 release the GIL: the run goes on meanwhile) and write one chunk."""
        raw = buffer[:size]  # an ndarray: both compressors take any buffer
        data = self._compress(raw)
        lo, hi = times
        content = (struct.pack("<QQQI", lo, hi, size, 0) + _string(self.compression)
                   + struct.pack("<Q", len(data)) + data)
        chunk_start = self.fh.tell()
        self.fh.write(_record("chunk", content))
        chunk_length = self.fh.tell() - chunk_start
        index_offsets = []
        index_start = self.fh.tell()
        channels = np.concatenate([c for c, _, _ in index])
        stamps = np.repeat(np.array([t for _, t, _ in index], dtype=np.uint64), [len(c) for c, _, _ in index])
        offsets = np.concatenate([o for _, _, o in index]).astype(np.uint64)
        order = np.argsort(channels, kind="stable")  # per channel, in the order written (time order)
        channels = channels[order]
        pairs = np.empty((len(order), 2), dtype="<u8")
        pairs[:, 0], pairs[:, 1] = stamps[order], offsets[order]
        ids, first = np.unique(channels, return_index=True)
        last = np.append(first[1:], len(channels))
        records, at = [], index_start
        for ch, a, b in zip(ids.tolist(), first.tolist(), last.tolist(), strict=True):
            body = pairs[a:b].tobytes()
            record = _record("message_index", struct.pack("<HI", ch, len(body)) + body)
            index_offsets.append((ch, at))
            records.append(record)
            at += len(record)
        self.fh.write(b"".join(records))
        index_length = self.fh.tell() - index_start
        offset_map = _map([(struct.pack("<H", ch), struct.pack("<Q", off)) for ch, off in index_offsets])
        self.chunk_indexes.append(_record("chunk_index", (
            struct.pack("<QQQQ", lo, hi, chunk_start, chunk_length) + offset_map + struct.pack("<Q", index_length)
            + _string(self.compression) + struct.pack("<QQ", len(data), size))))

    def close(self) -> None:
        """Stop the writer thread (after :meth:`finish`, or to abandon the file)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        """A Metadata record (outside chunks)."""
        self.flush_chunk()
        self.wait()
        pairs = [(_string(k), _string(v)) for k, v in sorted(values.items())]
        self.fh.write(_record("metadata", _string(name) + _map(pairs)))
        self.metadata_count += 1

    def finish(self) -> None:
        """The last chunk, Data End, the summary section, the Footer and the closing magic."""
        self.flush_chunk()
        self.wait()
        self.close()
        self.fh.write(_record("data_end", struct.pack("<I", 0)))
        summary_start = self.fh.tell()
        counts = _map([(struct.pack("<H", ch), struct.pack("<Q", k))
                       for ch, k in enumerate(self.counts.tolist()) if ch])  # ids from 1
        statistics = _record("statistics", struct.pack(
            "<QHIIIIQQ", self.message_count, len(self.schemas), len(self.channels), 0, self.metadata_count,
            len(self.chunk_indexes), self.start_time or 0, self.end_time) + counts)
        offsets = []
        for op, records in (("schema", self.schemas), ("channel", self.channels),
                            ("chunk_index", self.chunk_indexes), ("statistics", [statistics])):
            if records:
                start = self.fh.tell()
                self.fh.write(b"".join(records))
                offsets.append(_record("summary_offset", struct.pack("<BQQ", OP[op], start, self.fh.tell() - start)))
        offset_start = self.fh.tell()
        self.fh.write(b"".join(offsets))
        self.fh.write(_record("footer", struct.pack("<QQI", summary_start, offset_start, 0)))
        self.fh.write(MAGIC)


def _compressor(name: str) -> Any:
    """The chunk compressor of ``name`` (the mcap package installs both libraries)."""
    if name == "zstd":
        import zstandard

        return zstandard.ZstdCompressor(level=-1).compress  # a fast level: half level 1's time, as small here
    if name == "lz4":
        import lz4.frame

        return lz4.frame.compress
    if name == "":
        return lambda raw: bytes(raw)
    raise ValueError(f"compression: must be zstd, lz4 or '' (got {name!r})")
