"""The run directory: resolved config, metrics, trajectory and manifest, each written atomically.

Layout of a run directory:
    config.yaml      the resolved, validated scenario config
    metrics.json     flat dotted keys, SI units (docs/outputs.md)
    trajectory.npz   see :mod:`swarmscene.core.recorder`
    manifest.json    config hash, seed, package versions, command line, status; written last, so a
                     directory without it (or with ``"complete": false``) is unfinished.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import sys
import tempfile
from importlib.metadata import PackageNotFoundError, version
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST_PACKAGES = ("swarmscene", "numpy", "scipy", "shapely", "networkx", "pydantic", "pluggy", "hydra-core")


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace`` (never half-written)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


COPY_CHUNK = 16 * 1024 * 1024
"""Bytes per read when a spilled ``.npy`` file is copied into an archive."""


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write an uncompressed ``.npz`` atomically; memory stays bounded whatever the arrays' size.

    An array that is a whole ``.npy`` file memory-mapped (a streamed trajectory,
    :mod:`swarmscene.core.recorder`) is copied into the archive file to file, 16 MiB at a time,
    without mapping its pages; any other array is written by numpy, which also goes in 16 MiB chunks.
    The archive is what ``numpy.savez`` writes: one ``<name>.npy`` member per array.
    """
    import zipfile

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh, zipfile.ZipFile(fh, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
            for name, array in arrays.items():
                with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                    source = _whole_npy_file(array)
                    if source is None:
                        np.lib.format.write_array(member, np.asanyarray(array), allow_pickle=False)
                    else:
                        with open(source, "rb") as src:
                            while block := src.read(COPY_CHUNK):
                                member.write(block)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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
    text = json.dumps(_jsonable(data), indent=2, sort_keys=True) + "\n"
    atomic_write_bytes(path, text.encode())


def config_hash(data: dict[str, Any]) -> str:
    """SHA-256 of the canonical JSON of a config (same scenario and seed, same hash)."""
    canonical = json.dumps(_jsonable(data), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def package_versions() -> dict[str, str]:
    versions = {"python": platform.python_version()}
    for name in MANIFEST_PACKAGES:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def write_run_dir(
    run_dir: Path,
    data: dict[str, Any],
    metrics: dict[str, Any],
    trajectory: dict[str, np.ndarray],
    complete: bool,
    seed: int,
    extras: Sequence[Callable[[Path], Any]] = (),
) -> None:
    """Write a run's files; the manifest goes last and marks the directory complete.

    ``extras`` write further files into the directory (plots, a replay) before the manifest, so
    the manifest lists them and a directory without one was not finished.
    """
    import yaml  # PyYAML comes with hydra-core; imported here to keep start-up light

    run_dir = Path(run_dir)
    atomic_write_bytes(run_dir / "config.yaml", yaml.safe_dump(_jsonable(data), sort_keys=False).encode())
    if trajectory:
        write_npz(run_dir / "trajectory.npz", trajectory)
    atomic_write_json(run_dir / "metrics.json", metrics)
    for extra in extras:
        extra(run_dir)
    manifest = {
        "config_hash": config_hash(data),
        "seed": seed,
        "complete": complete,
        "command": sys.argv,
        "versions": package_versions(),
        "files": sorted(p.name for p in run_dir.iterdir() if not p.name.startswith(".")),
    }
    atomic_write_json(run_dir / "manifest.json", manifest)
