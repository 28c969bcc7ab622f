"""Trajectory recorder: the agents' states over time, written as ``trajectory.npz``.

Format (one documented columnar file, numpy ``.npz``; every array has time along axis 0):
    t: (T,) s.
    pos: (T, N, 3) m, world frame (x east, y north, z up).
    vel: (T, N, 3) m/s.
    healthy: (T, N) bool.
    quat: (T, N, 4) (w, x, y, z), only when the dynamics model has attitude.
Frames are taken at t = 0 and after every ``output.trajectory_every``-th guidance tick; arrays are
float32 when ``output.float32`` is set.

Memory. A small record is kept whole in memory. A large one is streamed to disk: frames gather in
an in-memory chunk of at most ``output.trajectory_buffer_mb`` MiB, and each full chunk is appended
to one ``.npy`` file per array in a spill directory (``output.trajectory_spill_dir``, default the
system's temporary directory). ``output.trajectory_stream`` chooses: ``auto`` streams when the
whole record would not fit in the buffer, ``on`` always, ``off`` never. Either way
:meth:`TrajectoryRecorder.arrays` returns the same arrays (memory-mapped, read-only, when streamed)
and ``trajectory.npz`` is the same file: it is written from the memory maps 16 MiB at a time, so
memory stays bounded by the buffer however long the run (100,000 agents x 10,000 frames of
float32 positions and velocities is 24 GB on disk, twice while the archive is written, and one
buffer in memory). The spill directory is a fresh one (``mkdtemp``, mode 0700) and each of its
files is created exclusively (``O_EXCL | O_NOFOLLOW``), so no planted link is written through; it
is removed when the recorder is garbage-collected or the interpreter exits.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import weakref
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .hookspecs import hookimpl

if TYPE_CHECKING:  # pragma: no cover
    from .run_view import RunView

MIB = 1024 * 1024
_NPY_HEADER_BYTES = 256
"""Fixed size of the spill files' .npy header, so it can be rewritten in place as frames arrive."""


def npy_header(dtype: np.dtype, shape: tuple[int, ...]) -> bytes:
    """A .npy (format 1.0) header of exactly ``_NPY_HEADER_BYTES`` bytes (a multiple of 64)."""
    fields = {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)), "fortran_order": False, "shape": shape}
    text = repr(fields).encode("latin1")
    head = b"\x93NUMPY\x01\x00"
    pad = _NPY_HEADER_BYTES - len(head) - 2 - len(text) - 1
    if pad < 0:  # pragma: no cover - a shape of three 20-digit numbers still fits
        raise ValueError(f"shape {shape} too long for the spill header")
    body = text + b" " * pad + b"\n"
    return head + len(body).to_bytes(2, "little") + body


def create_exclusive(path: Path) -> int:
    """A new file at ``path`` for writing (mode 0600): refused when anything is there already,
    a symbolic link included (``O_EXCL``, and ``O_NOFOLLOW`` where the system has it)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    return os.open(path, flags, 0o600)


class NpyAppender:
    """One ``.npy`` file grown by appending frames; its header always names the frames written."""

    def __init__(self, path: Path, frame_shape: tuple[int, ...], dtype: np.dtype) -> None:
        self.path = path
        self.frame_shape = frame_shape
        self.dtype = np.dtype(dtype)
        self.frames = 0
        self._fh = os.fdopen(create_exclusive(path), "wb")
        self._fh.write(npy_header(self.dtype, (0, *frame_shape)))

    def append(self, block: np.ndarray) -> None:
        """Append frames ``block`` (k, *frame_shape), converted to this file's dtype."""
        data = np.ascontiguousarray(block, dtype=self.dtype)  # no copy for a buffer slice
        # mypy is wrong: an ndarray is a buffer (numpy declares __buffer__ to mypy for Python 3.12+ only)
        self._fh.write(data.reshape(-1).view(np.uint8))  # type: ignore[arg-type]
        self.frames += len(block)

    def sync(self) -> None:
        """Rewrite the header with the frame count and flush, so the file reads as a whole array."""
        if self._fh.closed:
            return  # closed files were synced on closing
        end = self._fh.tell()
        self._fh.seek(0)
        self._fh.write(npy_header(self.dtype, (self.frames, *self.frame_shape)))
        self._fh.seek(end)
        self._fh.flush()

    def close(self) -> None:
        """Write the final header and close the file (a second call does nothing)."""
        if not self._fh.closed:
            self.sync()
            self._fh.close()

    def load(self) -> np.ndarray:
        """The frames written so far, memory-mapped read-only."""
        self.sync()
        if self.frames == 0:
            return np.zeros((0, *self.frame_shape), dtype=self.dtype)
        return np.load(self.path, mmap_mode="r")


class TrajectoryRecorder:
    """Keeps decimated frames of the world state in memory, or streams them to disk in chunks."""

    def __init__(self, sim: RunView) -> None:
        out = sim.config.output
        self.enabled = out.trajectory
        self.every = out.trajectory_every
        self.count = 0
        if not self.enabled:
            return
        self.frames = sim.total_steps // self.every + 1
        n = sim.world.n
        dtype = np.float32 if out.float32 else np.float64
        self.shapes: dict[str, tuple[tuple[int, ...], Any]] = {
            "pos": ((n, 3), dtype),
            "vel": ((n, 3), dtype),
            "healthy": ((n,), bool),
        }
        if sim.has_attitude:
            self.shapes["quat"] = ((n, 4), dtype)
        frame_bytes = sum(np.prod(s) * np.dtype(d).itemsize for s, d in self.shapes.values())
        budget = out.trajectory_buffer_mb * MIB
        self.streaming = out.trajectory_stream == "on" or (
            out.trajectory_stream == "auto" and self.frames * frame_bytes > budget
        )
        self.chunk = max(1, min(self.frames, int(budget // frame_bytes))) if self.streaming else self.frames
        self.t = np.zeros(self.frames)  # small: kept whole in memory either way
        self.buffer = {key: np.zeros((self.chunk, *s), dtype=d) for key, (s, d) in self.shapes.items()}
        self.filled = 0  # frames in the buffer not yet appended to disk
        self.spill_dir: Path | None = None
        self.files: dict[str, NpyAppender] = {}
        if self.streaming:
            self._open_spill(out.trajectory_spill_dir)

    def _open_spill(self, where: str | None) -> None:
        if where is not None:
            Path(where).mkdir(parents=True, exist_ok=True)
        self.spill_dir = Path(tempfile.mkdtemp(prefix="swarmscene-trajectory-", dir=where))
        self.files = {
            key: NpyAppender(self.spill_dir / f"{key}.npy", s, d) for key, (s, d) in self.shapes.items()
        }
        # Runs when the recorder is collected or at interpreter exit; memory maps handed out stay
        # valid on POSIX (an unlinked file lives while mapped).
        self._cleanup = weakref.finalize(self, _remove_spill, self.spill_dir, list(self.files.values()))

    def _record(self, sim: RunView) -> None:
        world, k = sim.world, self.filled
        self.t[self.count] = world.t
        self.buffer["pos"][k] = world.pos
        self.buffer["vel"][k] = world.vel
        self.buffer["healthy"][k] = world.healthy
        if "quat" in self.buffer and world.quat is not None:
            self.buffer["quat"][k] = world.quat
        self.count += 1
        self.filled += 1
        if self.streaming and self.filled == self.chunk:
            self._flush()

    def _flush(self) -> None:
        """Append the buffered frames to the spill files."""
        for key, appender in self.files.items():
            appender.append(self.buffer[key][: self.filled])
        self.filled = 0

    @hookimpl
    def swarmscene_run_start(self, sim: RunView) -> None:
        """Record the initial frame (tick 0)."""
        if self.enabled:
            self._record(sim)

    @hookimpl
    def swarmscene_step_end(self, sim: RunView) -> None:
        """Record a frame every ``every`` ticks."""
        if self.enabled and sim.step_count % self.every == 0:
            self._record(sim)

    @hookimpl
    def swarmscene_run_end(self, sim: RunView, metrics: dict[str, Any]) -> None:
        """Streamed: append the buffered frames and leave each spill file a whole ``.npy``."""
        if self.enabled and self.streaming:
            self._flush()
            for appender in self.files.values():
                appender.sync()

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded frames (empty dict when recording is off); memory-mapped when streamed."""
        if not self.enabled:
            return {}
        k = self.count
        if self.streaming:
            self._flush()
            arrays = {key: appender.load() for key, appender in self.files.items()}
        else:
            arrays = {key: buf[:k] for key, buf in self.buffer.items()}
        return {"t": self.t[:k], **arrays}

    def buffer_bytes(self) -> int:
        """Bytes of frame data this recorder holds in memory (the buffer; ``t`` aside)."""
        return sum(buf.nbytes for buf in self.buffer.values()) if self.enabled else 0


def _remove_spill(spill_dir: Path, files: list[NpyAppender]) -> None:
    for appender in files:
        appender._fh.close()
    shutil.rmtree(spill_dir, ignore_errors=True)


@hookimpl
def swarmscene_register_observers(register: Any) -> None:
    """Add :class:`TrajectoryRecorder` to the observers every run builds."""
    register(TrajectoryRecorder)
