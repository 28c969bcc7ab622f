"""The run directory: resolved config, metrics, trajectory and manifest, each written atomically.

Layout of a run directory:
    config.yaml      the effective configuration: every engine option and every option of each
                     chosen plugin, defaults included (``Scenario.data``); re-run it exactly with
                     ``swarmscene --config-path <run dir> --config-name config``
    metrics.json     flat dotted keys, SI units (docs/outputs.md)
    trajectory.npz   see :mod:`swarmscene.core.recorder`
    manifest.json    config hash, seed, start time, package versions and source revision, command
                     line, status; written last, so a directory without it (or with
                     ``"complete": false``) is unfinished.

Files are created with the permissions the user's umask gives (``0o666 & ~umask``), like any file
``open()`` creates, although they are written through a private temporary file.
"""

from __future__ import annotations

import errno
import hashlib
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..core import interrupts

MANIFEST_PACKAGES = (
    "swarmscene", "numpy", "scipy", "shapely", "networkx", "pydantic", "pluggy", "hydra-core", "numba",
)
COSMETIC_KEYS = (
    ("description",),
    ("output", "summary"),
    ("output", "progress"),
    ("output", "objective"),
    ("output", "trajectory_stream"),
    ("output", "trajectory_buffer_mb"),
    ("output", "trajectory_spill_dir"),
    ("output", "plots"),
    ("output", "animation"),
    ("output", "animation_frames"),
    ("output", "comm_edges"),
    ("output", "rerun"),
    ("output", "mcap"),
    ("output", "live"),
    ("dynamics", "threads"),
)
"""Options left out of the config hash: they change none of the numbers a run computes nor the
record files (config, metrics, trajectory) it writes: a label, what is printed, what a sweeper is
handed from metrics.json, how the trajectory is buffered on its way to the same trajectory.npz, and
the pictures drawn from the record (plots, animation, replay; ``swarmscene-report --run-plots
--rerun`` draws them later), the live view and the ROS 2 bag (``export --mcap`` converts the
record). ``dynamics.threads`` is how many threads step the physics; a dynamics model that has the
option gives the same numbers bit for bit on any count (the quadrotor's does, tested), so a run on
4 threads has the hash of the same run on 1. A sweep re-run with only these changed resumes (docs/sweeps.md)."""

UNHASHED_AT = {("dynamics", "dtype"): "float64"}
"""Options left out of the config hash at one value: options added after runs were recorded, whose
value here gives those runs' numbers bit for bit, so a sweep recorded before the option existed
resumes. ``dynamics.dtype`` at ``float64`` is the quadrotor's physics step as it was before the
option (0.8.3); ``float32`` changes the numbers and is hashed."""

COMMAND_ENV = "SWARMSCENE_COMMAND"
"""The command as typed (a JSON list), which a sweep hands to its jobs: a job on a Ray or SLURM
worker would otherwise record the worker's own argv."""


def run_command() -> dict[str, Any]:
    """The manifest's ``command`` (as typed: :data:`COMMAND_ENV` when a sweep set it, else this
    process's argv) and ``node`` (``host``; and ``ray_node_id`` inside a Ray task)."""
    import socket

    command: Any = sys.argv
    given = os.environ.get(COMMAND_ENV)
    if given:
        try:
            parsed = json.loads(given)
            if isinstance(parsed, list) and all(isinstance(a, str) for a in parsed):
                command = parsed
        except ValueError:
            pass
    node: dict[str, Any] = {"host": socket.gethostname()}
    ray = sys.modules.get("ray")
    if ray is not None:
        try:
            if ray.is_initialized():
                node["ray_node_id"] = ray.get_runtime_context().get_node_id()
        except Exception:  # an older Ray without the runtime context: the host alone
            pass
    return {"command": list(command), "node": node}


def user_file_mode() -> int:
    """``0o666 & ~umask``: the mode ``open()`` gives a new file (read without changing the umask
    where /proc tells it, since setting it is process-wide)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def _private_temp(path: Path) -> tuple[int, str]:
    """A temporary file beside ``path`` (mkstemp: mode 0600), given the user's file mode."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.fchmod(fd, user_file_mode())
    return fd, tmp


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace`` (never half-written);
    an OSError that names no file (a full disk) is raised naming ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _private_temp(path)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        if exc.filename is None:  # a full disk names no file: the one being written is the news
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextmanager
def private_temp_dir(directory: Path, name: str) -> Iterator[Path]:
    """A path ``<fresh dir>/<name>`` for a writer that opens its file by name (Rerun, matplotlib).

    The fresh directory is made inside ``directory`` by ``mkdtemp`` (mode 0700, a new name):
    nothing can be planted in it, so the writer cannot be led through a symbolic link; move the
    file into place with :func:`publish`. The directory and anything left in it are removed
    afterwards, whether the writer finished or failed.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=directory, prefix=f".{name}.", suffix=".tmp"))
    try:
        yield tmp / name
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def publish(tmp_file: Path, path: Path) -> None:
    """Move a finished temporary file into place atomically (a link at ``path`` is replaced, never
    followed), with the mode ``open()`` would have given it."""
    os.chmod(tmp_file, user_file_mode())
    os.replace(tmp_file, path)


COPY_CHUNK = 16 * 1024 * 1024
"""Bytes per read when a spilled ``.npy`` file is copied into an archive."""


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write an uncompressed ``.npz`` atomically; memory stays bounded whatever the arrays' size.

    An array that is a whole ``.npy`` file memory-mapped (a streamed trajectory,
    :mod:`swarmscene.core.recorder`) is copied into the archive file to file, 16 MiB at a time,
    without mapping its pages, under the header numpy writes; any other array is written by numpy,
    which also goes in 16 MiB chunks. The archive is what ``numpy.savez`` writes (one
    ``<name>.npy`` member per array), with every member stamped :data:`ZIP_EPOCH`: the same arrays,
    streamed or not, give the same bytes.
    """
    import zipfile

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _private_temp(path)
    try:
        with os.fdopen(fd, "wb") as fh, zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, array in arrays.items():
                with zf.open(_member(f"{name}.npy"), "w", force_zip64=True) as member:
                    source = _whole_npy_file(array)
                    if source is None:
                        np.lib.format.write_array(member, np.asanyarray(array), allow_pickle=False)
                    else:  # numpy's own header, then the data: the bytes numpy would write
                        _write_npy_header(member, array)
                        with open(source, "rb") as src:
                            src.seek(cast(np.memmap, array).offset)  # _whole_npy_file: a memmap
                            while block := src.read(COPY_CHUNK):
                                member.write(block)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
"""Every archive member's timestamp: the zip format's earliest date, so the same arrays make the
same bytes (zipfile would stamp the time of writing; the manifest records when the run was)."""


def _member(name: str) -> Any:
    import zipfile

    info = zipfile.ZipInfo(name, date_time=ZIP_EPOCH)
    info.compress_type = zipfile.ZIP_STORED
    info.external_attr = 0o600 << 16  # what zipfile (and so numpy.savez) gives a member by name
    return info


def _write_npy_header(fh: Any, array: np.ndarray) -> None:
    """The header ``numpy.lib.format.write_array`` writes for ``array`` (format 1.0, else 2.0)."""
    header = np.lib.format.header_data_from_array_1_0(array)
    try:
        np.lib.format.write_array_header_1_0(fh, header)
    except ValueError:  # a shape too long for 1.0's 2-byte header length
        np.lib.format.write_array_header_2_0(fh, header)


def _whole_npy_file(array: np.ndarray) -> str | None:
    """The ``.npy`` file ``array`` maps in full (from ``numpy.load(..., mmap_mode=...)``), else None."""
    filename = getattr(array, "filename", None)
    if not isinstance(array, np.memmap) or filename is None or not array.flags.c_contiguous:
        return None
    try:
        size = os.path.getsize(filename)
    except (OSError, TypeError):
        return None
    return str(filename) if array.offset + array.nbytes == size else None


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None  # JSON has no inf/NaN
    return value


def atomic_write_json(path: Path, data: Any) -> None:
    """Write ``data`` as indented JSON with sorted keys (inf and NaN as null), atomically."""
    text = json.dumps(_jsonable(data), indent=2, sort_keys=True) + "\n"
    atomic_write_bytes(path, text.encode())


def config_hash(data: dict[str, Any]) -> str:
    """SHA-256 of the canonical JSON of an effective configuration without :data:`COSMETIC_KEYS`
    (nor the options of :data:`UNHASHED_AT` at their value there).

    ``data`` is the effective configuration (``Scenario.data``, a run directory's config.yaml):
    every value the run uses is in it, so the hash changes when any of them changes, including a
    plugin default changed by an upgrade. Same hash, same numbers for the same package versions.
    An event's and a disturbance model's plugin name is hashed under ``kind`` whichever key holds
    it (:func:`~swarmscene.core.spelling.canonical_names`): a run recorded with ``name`` has the
    hash of the same run recorded with ``kind`` until 0.6.0 (a sweep resumed across it runs nothing again).
    """
    from ..core.spelling import canonical_names

    plain = _jsonable(_without_cosmetic(canonical_names(data)))
    canonical = json.dumps(plain, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def _without_cosmetic(data: dict[str, Any]) -> dict[str, Any]:
    data = dict(data)
    for path in COSMETIC_KEYS + tuple(UNHASHED_AT):
        node = data
        for key in path[:-1]:
            child = node.get(key)
            if not isinstance(child, dict):
                break
            node[key] = child = dict(child)  # copies along the path: the caller's data is untouched
            node = child
        else:
            if path not in UNHASHED_AT or node.get(path[-1], UNHASHED_AT[path]) == UNHASHED_AT[path]:
                node.pop(path[-1], None)
    return data


def package_versions() -> dict[str, str]:
    """Python's version, the engine's packages' (:data:`MANIFEST_PACKAGES`) and every installed
    plugin distribution's (a ``swarmscene`` entry point): what the numbers depend on."""
    from ..core.registry import plugin_distributions

    return {**_engine_versions(), **plugin_distributions()}


@lru_cache(maxsize=1)
def _engine_versions() -> dict[str, str]:
    """Read once per process (each lookup scans the installed metadata: every job paid it)."""
    versions = {"python": platform.python_version()}
    for name in MANIFEST_PACKAGES:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = "not installed"
    return versions


@lru_cache(maxsize=1)
def source_revision() -> dict[str, Any] | None:
    """``{"revision": <commit>, "dirty": <bool>}`` when the swarmscene package runs from a git
    checkout that tracks it (an editable install), else None (an installed wheel: its version says
    what ran). ``dirty``: tracked files differ from the commit."""
    package = Path(__file__).resolve().parent  # core/, tracked in the source tree
    def git(*args: str) -> str | None:
        try:
            proc = subprocess.run(["git", "-C", str(package), *args], capture_output=True, text=True, timeout=10)
        except (OSError, subprocess.SubprocessError):
            return None
        return proc.stdout.strip() if proc.returncode == 0 else None

    # a wheel installed into a virtual environment inside some checkout is not tracked by it
    if git("ls-files", "--error-unmatch", Path(__file__).name) is None:
        return None
    revision = git("rev-parse", "HEAD")
    if not revision:
        return None
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"revision": revision, "dirty": bool(status)}


CONFIG_HEADER = (
    "# The effective configuration of this run: every option, defaults included.\n"
    "# Re-run it exactly: swarmscene --config-path <this directory> --config-name config\n"
)


RUN_FILES = ("config.yaml", "trajectory.npz", "metrics.json", "manifest.json")
"""The files :func:`write_run_dir` writes itself (the extras add theirs)."""
STALE_OUTPUTS = ("bag",)
"""Outputs a run writes under a fixed name only when asked for (the bag folder of
``output.mcap``, ``views/mcap_bag.BAG_DIR``): an earlier run's, in a directory written again, is
removed first, so the manifest never lists another run's bag and an interrupted run leaves none."""


def write_run_dir(
    run_dir: Path,
    data: dict[str, Any],
    metrics: dict[str, Any],
    trajectory: dict[str, np.ndarray],
    complete: bool,
    seed: int,
    extras: Sequence[Callable[[Path], Any]] = (),
    started_at: str | None = None,
) -> None:
    """Write a run's files; the manifest goes last and marks the directory complete.

    ``data`` is the effective configuration (``Scenario.data``); ``started_at`` the run's start,
    UTC ISO 8601. ``extras`` write further files into the directory (plots, a replay) before the
    manifest, so the manifest lists them and a directory without one was not finished.

    Every file is written through a private temporary file and ``os.replace`` (a planted link
    is replaced, never followed). A manifest already there (a directory written again) is removed
    first, so the directory reads as unfinished until the new one lands. When a write fails (a
    full disk, a read-only directory) the files this call wrote are removed, their temporary
    files too, and an OSError naming ``run_dir`` is raised: nothing is left that looks complete.
    """
    run_dir = Path(run_dir)
    if run_dir.is_symlink():  # the files would land wherever the link points
        raise OSError(errno.ELOOP, "is a symbolic link (refused: a run directory is a plain directory)", str(run_dir))
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        remove_stale_temps(run_dir)
        for name in STALE_OUTPUTS:
            _remove_path(run_dir / name)
        before = {p.name for p in run_dir.iterdir()}
        (run_dir / "manifest.json").unlink(missing_ok=True)
        _write_run_files(run_dir, data, metrics, trajectory, complete, seed, extras, started_at)
    except OSError as exc:
        _remove_written(run_dir, before if "before" in locals() else set())
        raise OSError(exc.errno, exc.strerror or str(exc), str(run_dir)) from exc


OBSERVER_FILE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}\.npz")
"""What an observer may name a file of its own (one plain ``.npz`` name in the run directory)."""


def write_observer_files(run_dir: Path, observers: Sequence[Any]) -> None:
    """Write the files each observer hands back from its ``run_files()`` (name -> arrays, an
    ``.npz`` each), through :func:`write_npz` (atomic; a planted link is replaced, never followed).

    A name that is not one plain ``.npz`` file name, or that is one of the engine's own files or
    another observer's, is a ValueError naming the observer: the file would land outside the
    directory or over a record.
    """
    written: dict[str, str] = {}
    for observer in observers:
        files = getattr(observer, "run_files", None)
        if not callable(files):
            continue
        who = type(observer).__qualname__
        for name, arrays in files().items():
            if not (isinstance(name, str) and OBSERVER_FILE.fullmatch(name)) or name in RUN_FILES:
                raise ValueError(f"observer {who}: run_files() names {name!r}; a file of its own is one "
                                 "plain name ending in .npz, not one of the engine's files")
            if name in written:
                raise ValueError(f"observer {who}: run_files() names {name!r}, already written by {written[name]}")
            written[name] = who
            write_npz(Path(run_dir) / name, arrays)


def remove_stale_temps(run_dir: Path) -> list[str]:
    """Remove the temporary files and directories a killed writer left in ``run_dir``
    (``.<name>.<random>.tmp``, :func:`atomic_write_bytes`, :func:`private_temp_dir`); their names.

    A process killed with SIGKILL (or a machine that lost power) cannot remove its own; the next
    write into the directory does. Links are removed as links, never followed.
    """
    removed = []
    for path in Path(run_dir).iterdir():
        if path.name.startswith(".") and path.name.endswith(".tmp") and path.name.count(".") >= 3:
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed.append(path.name)
    return removed


def _remove_path(path: Path) -> None:
    """Remove a file, a link (as a link, never followed) or a directory tree, if there is one."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


def _remove_written(run_dir: Path, before: set[str]) -> None:
    """After a failed write: remove the run's own files and whatever the extras added."""
    try:
        names = {p.name for p in run_dir.iterdir()}
    except OSError:
        return
    for name in names:
        if name in RUN_FILES or (name not in before and not name.startswith(".hydra")):
            try:
                _remove_path(run_dir / name)
            except OSError:
                pass  # a read-only directory: there is nothing of ours to remove either


def _write_run_files(
    run_dir: Path,
    data: dict[str, Any],
    metrics: dict[str, Any],
    trajectory: dict[str, np.ndarray],
    complete: bool,
    seed: int,
    extras: Sequence[Callable[[Path], Any]],
    started_at: str | None,
) -> None:
    import yaml  # PyYAML comes with hydra-core; imported here to keep start-up light

    # libyaml's emitter where PyYAML has it (its wheels do): 4x faster (~4 ms of a sweep job), the
    # same data read back; only a long quoted string with escapes may wrap at another place
    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    text = CONFIG_HEADER + yaml.dump(_jsonable(data), Dumper=dumper, sort_keys=False)
    atomic_write_bytes(run_dir / "config.yaml", text.encode())
    if trajectory:
        write_npz(run_dir / "trajectory.npz", trajectory)
    atomic_write_json(run_dir / "metrics.json", metrics)
    for extra in extras:
        if interrupts.requested() is not None:
            break  # asked to stop: the plots and replay not yet written are left out
        extra(run_dir)
    # A stop request during the writes (Ctrl-C, SIGTERM: core/interrupts.py) marks the directory
    # incomplete: the process ends before its caller would read it back.
    complete = complete and interrupts.requested() is None
    manifest = {
        "config_hash": config_hash(data),
        "scenario": data.get("name"),
        "methods": {kind: (data.get(kind) or {}).get("name") for kind in ("formation", "avoidance", "dynamics")},
        "seed": seed,
        "complete": complete,
        "started_at": started_at,
        **run_command(),
        "versions": package_versions(),
        "files": sorted(p.name for p in run_dir.iterdir() if not p.name.startswith(".")),
    }
    source = source_revision()
    if source is not None:
        manifest["source"] = source
    atomic_write_json(run_dir / "manifest.json", manifest)
