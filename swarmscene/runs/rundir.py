"""The one checked reader of run directories: every tool that reads one goes through here.

A run directory (docs/outputs.md) may be damaged (a disk filled up, a job killed mid-write) or
hostile (files planted by someone else). Every reader here checks what it reads (its size, its
type and, for the trajectory, every array's name, dtype and shape) and turns any problem into a
:class:`RunFileError`: one line naming the file and what is wrong. Nothing is unpickled
(``numpy.load(allow_pickle=False)``, ``yaml.safe_load`` with no aliases).

    from swarmscene.runs.rundir import RunDir, RunFileError
    run = RunDir(path)
    run.metrics()        # dict, checked
    run.trajectory()     # {"t": (T,), "pos": (T, N, 3), "vel": (T, N, 3), "healthy": (T, N), "quat"?: (T, N, 4)}
    run.check_trajectory()  # shapes only, without reading the arrays (a resume's test)
"""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

MAX_JSON_BYTES = 64 * 1024 * 1024
"""Largest metrics/manifest/error/sweep JSON file read (bytes); larger is damage, not a record."""
MAX_YAML_BYTES = 16 * 1024 * 1024
"""Largest config/overrides YAML file read (bytes)."""

CONFIG = "config.yaml"
METRICS = "metrics.json"
MANIFEST = "manifest.json"
ERROR = "error.json"
TRAJECTORY = "trajectory.npz"
OVERRIDES = ".hydra/overrides.yaml"

TRAJECTORY_ARRAYS = {"t": 1, "pos": 3, "vel": 3, "healthy": 2}
"""Required trajectory arrays and their number of axes (optional: ``quat``, 3 axes)."""


class RunFileError(ValueError):
    """A file of a run or sweep directory that is missing, unreadable or not what it should be.

    ``str(error)`` is one line that starts with the file's path.
    """

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


def _plain_file(path: Path) -> None:
    """Refuse a planted link, a missing file and anything that is not a regular file."""
    if path.is_symlink():
        raise RunFileError(path, "is a symbolic link (refused: a run directory's files are plain files)")
    if not path.exists():
        raise RunFileError(path, "missing")
    if not path.is_file():
        raise RunFileError(path, "not a regular file")


def _read_bytes(path: Path, limit: int) -> bytes:
    path = Path(path)
    _plain_file(path)
    try:
        size = path.stat().st_size
        if size > limit:
            raise RunFileError(path, f"too large ({size} bytes; at most {limit})")
        return path.read_bytes()
    except OSError as exc:
        raise RunFileError(path, f"cannot be read ({exc.strerror or exc})") from exc


def read_text(path: Path | str, limit: int = MAX_YAML_BYTES) -> str:
    """A plain file's text (UTF-8, at most ``limit`` bytes), checked like every other read."""
    raw = _read_bytes(Path(path), limit)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        raise RunFileError(path, "not UTF-8 text") from None


def _finite_numbers(value: Any) -> Any:
    """JSON's NaN/Infinity extensions are refused: our writers never produce them."""
    raise ValueError(f"non-standard number {value}")


def read_json(path: Path | str, kind: type | tuple[type, ...] = dict) -> Any:
    """A JSON file's content, checked to be of type ``kind`` (a dict unless told)."""
    raw = _read_bytes(Path(path), MAX_JSON_BYTES)
    try:
        value = json.loads(raw.decode("utf-8"), parse_constant=_finite_numbers)
    except UnicodeDecodeError:
        raise RunFileError(path, "not UTF-8 text") from None
    except (ValueError, RecursionError) as exc:
        raise RunFileError(path, f"not valid JSON ({str(exc).splitlines()[0]})") from None
    _expect(path, value, kind)
    return value


def read_yaml(path: Path | str, kind: type | tuple[type, ...] = dict) -> Any:
    """A YAML file written by the engine (config, overrides): plain data, no aliases, no tags."""
    import yaml

    raw = _read_bytes(Path(path), MAX_YAML_BYTES)
    try:
        # yaml.safe_load's own steps, the text parsed once: its node tree checked, then constructed
        loader = yaml.SafeLoader(raw.decode("utf-8"))
        try:
            node = loader.get_single_node()
            if node is not None and _has_alias(node):
                raise RunFileError(path, "holds YAML aliases (refused: the engine never writes them)")
            value = None if node is None else loader.construct_document(node)
        finally:
            loader.dispose()
    except UnicodeDecodeError:
        raise RunFileError(path, "not UTF-8 text") from None
    except (yaml.YAMLError, RecursionError) as exc:
        raise RunFileError(path, f"not valid YAML ({' '.join(str(exc).split())[:160]})") from None
    _expect(path, value, kind)
    return value


def _has_alias(root: Any) -> bool:
    """Whether a composed YAML tree uses an alias (a node reached twice)."""
    import yaml

    seen: set[int] = set()
    stack = [root]
    while stack:
        node = stack.pop()
        if id(node) in seen:
            return True
        seen.add(id(node))
        if isinstance(node, yaml.MappingNode):
            stack.extend(n for pair in node.value for n in pair)
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
    return False


_KIND_WORDS: dict[type, str] = {dict: "a mapping", list: "a list", str: "a string"}


def _expect(path: Path | str, value: Any, kind: type | tuple[type, ...]) -> None:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if not isinstance(value, kinds):
        wanted = " or ".join(_KIND_WORDS.get(k, k.__name__) for k in kinds)
        got = "null" if value is None else type(value).__name__
        raise RunFileError(path, f"should hold {wanted}, holds {got}")


def _member_header(zf: zipfile.ZipFile, name: str) -> tuple[tuple[int, ...], np.dtype]:
    with zf.open(name) as fh:
        version = np.lib.format.read_magic(fh)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read(fh)
    return shape, dtype


def check_trajectory(path: Path | str) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Each array's (shape, dtype) from a trajectory archive's headers, checked, without reading data.

    Raises RunFileError when the archive is truncated or damaged, an array is missing, holds
    objects, or the shapes disagree (``t`` (T,), ``pos``/``vel`` (T, N, 3), ``healthy`` (T, N),
    ``quat`` (T, N, 4)).
    """
    path = Path(path)
    _plain_file(path)
    headers: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                headers[info.filename[:-4]] = _member_header(zf, info.filename)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise RunFileError(path, f"not a readable numpy archive ({str(exc).splitlines()[0]})") from None
    _check_shapes(path, headers)
    return headers


def _check_shapes(path: Path, headers: dict[str, tuple[tuple[int, ...], np.dtype]]) -> None:
    missing = [name for name in TRAJECTORY_ARRAYS if name not in headers]
    if missing:
        raise RunFileError(path, f"lacks the array(s) {', '.join(missing)}")
    for name, (_shape, dtype) in headers.items():
        if dtype.hasobject:
            raise RunFileError(path, f"array {name!r} holds Python objects (refused: nothing is unpickled)")
        # real numbers (flags for healthy): not text, records or complex numbers
        kinds, word = ("biu", "flags") if name == "healthy" else ("fiu", "real numbers")
        if name in (*TRAJECTORY_ARRAYS, "quat") and (dtype.kind not in kinds or dtype.fields is not None):
            raise RunFileError(path, f"array {name!r} holds {dtype} values, not {word}")
    need = sum(int(np.prod(shape, dtype=float)) * dtype.itemsize for shape, dtype in headers.values())
    memory = _physical_memory()
    if memory is not None and need > memory:
        raise RunFileError(path, f"its arrays would take {need / 2**30:.1f} GiB in memory, more than this machine's "
                                 f"{memory / 2**30:.1f} GiB (a damaged header, or a bomb of zeros)")
    expected = dict(TRAJECTORY_ARRAYS, quat=3)
    for name, ndim in expected.items():
        if name in headers and len(headers[name][0]) != ndim:
            raise RunFileError(path, f"array {name!r} has shape {headers[name][0]}, expected {ndim} axes")
    steps, agents = headers["pos"][0][0], headers["pos"][0][1]
    if steps == 0 or agents == 0:  # a run records its start, and flies at least one agent
        empty = "no frame" if steps == 0 else "no agent"
        raise RunFileError(path, f"array 'pos' holds {empty} (shape {headers['pos'][0]})")
    wanted = {"t": (steps,), "pos": (steps, agents, 3), "vel": (steps, agents, 3), "healthy": (steps, agents),
              "quat": (steps, agents, 4)}
    for name, shape in wanted.items():
        if name in headers and headers[name][0] != shape:
            raise RunFileError(path, f"array {name!r} has shape {headers[name][0]}, expected {shape}")


def _physical_memory() -> int | None:
    """This machine's memory, bytes (None where the system does not say)."""
    import os

    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def read_trajectory(path: Path | str) -> dict[str, np.ndarray]:
    """The trajectory's arrays (``t``, ``pos``, ``vel``, ``healthy``, and ``quat`` if recorded), checked."""
    path = Path(path)
    check_trajectory(path)
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files if name in (*TRAJECTORY_ARRAYS, "quat")}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise RunFileError(path, f"not a readable numpy archive ({str(exc).splitlines()[0]})") from None
    t = arrays["t"]
    if t.size and not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise RunFileError(path, "array 't' is not finite and increasing")
    return arrays


class RunDir:
    """A run directory, read through the checked readers above.

    Args:
        path: the directory; a missing one (or a file) is a RunFileError at construction.
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        if self.path.is_symlink():  # the tools that write into a run directory would write through it
            raise RunFileError(self.path, "is a symbolic link (refused: a run directory is a plain directory)")
        if not self.path.is_dir():
            raise RunFileError(self.path, "not a run directory (missing, or not a directory)")

    def metrics(self) -> dict[str, Any]:
        """``metrics.json``, checked to be a JSON object."""
        return read_json(self.path / METRICS)

    def manifest(self) -> dict[str, Any]:
        """``manifest.json``, checked to be a JSON object."""
        return read_json(self.path / MANIFEST)

    def error(self) -> dict[str, Any]:
        """``error.json`` (a failed run's), checked to be a JSON object."""
        return read_json(self.path / ERROR)

    def config(self) -> dict[str, Any]:
        """``config.yaml``, the resolved scenario, checked to be a mapping."""
        return read_yaml(self.path / CONFIG)

    def overrides(self) -> list[str]:
        """The job's overrides as Hydra recorded them (``.hydra/overrides.yaml``)."""
        values = read_yaml(self.path / OVERRIDES, list)
        return [str(v) for v in values]

    def trajectory(self) -> dict[str, np.ndarray]:
        """The trajectory's arrays by name, read and checked (missing when ``output.trajectory`` was false)."""
        path = self.path / TRAJECTORY
        if not path.exists() and not path.is_symlink():
            raise RunFileError(path, "missing (was the run made with output.trajectory=false?)")
        return read_trajectory(path)

    def check_trajectory(self) -> None:
        """Check the trajectory file's columns and shapes without keeping its arrays."""
        check_trajectory(self.path / TRAJECTORY)

    def has(self, name: str) -> bool:
        """Whether the directory holds a file (or a planted link) of that name."""
        path = self.path / name
        return path.exists() or path.is_symlink()


def finite_or_none(value: Any) -> float | None:
    """A metric value as a finite float, or None (missing, null, non-numeric, NaN or infinite)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None
