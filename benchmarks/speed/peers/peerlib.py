"""What every peer comparison shares: one core, one thread, a fresh process per measurement.

Each peer lives in its own virtual environment under ``benchmarks/speed/peers/.venv-<name>/`` (git
ignores ``.venv-*/``), created on first use from PyPI by :func:`ensure_venv`; nothing of a peer is
copied into the repository. Every measurement is a child process started by :func:`child_json`:
pinned to one core (``taskset -c CORE``), with single-threaded BLAS, OpenMP and XLA
(:data:`ONE_THREAD`), printing one JSON line last.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import venv
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]  # benchmarks/speed/peers -> the repository

CORE = 1
"""The core every child is pinned to (``run.py --core``); the scripts run alone used core 0."""

ONE_THREAD = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
    # XLA's CPU client: no Eigen thread pool, one intra-op thread (JAX peers).
    "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1",
    "PYTHONWARNINGS": "ignore",
}


def pinned(cmd: list[str]) -> list[str]:
    """``cmd`` on one core (taskset), where the OS has it."""
    return ["taskset", "-c", str(CORE), *cmd] if shutil.which("taskset") else cmd


def child_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """The parent's environment with one thread everywhere (and ``extra`` on top)."""
    return {**os.environ, **ONE_THREAD, **(extra or {})}


def _label(cmd: list[str]) -> str:
    """The command for an error message, with an inline ``-c`` program shortened."""
    return " ".join("<program>" if k > 0 and cmd[k - 1] == "-c" else a for k, a in enumerate(cmd[:4]))


def child_json(cmd: list[str], extra_env: dict[str, str] | None = None, timeout: float = 1800.0,
               cwd: str | None = None) -> dict:
    """Run ``cmd`` pinned, one thread; its last stdout line is JSON. A failure raises with stderr's tail."""
    proc = subprocess.run(pinned(cmd), capture_output=True, text=True, env=child_env(extra_env),
                          timeout=timeout, cwd=cwd)
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-15:])
        raise RuntimeError(f"{_label(cmd)} ... exited with {proc.returncode}:\n{tail}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def alternate(sides: dict[str, tuple[list[str], str | None]], repeat: int, key: str,
              measure: Callable[[dict], dict] = lambda result: result) -> dict[str, dict]:
    """Run every side's command ``(cmd, cwd)`` in turn, ``repeat`` times (so a burst of load on the
    shared machine hits every side alike); keep each side's run with the highest ``measure(run)[key]``.
    A side that fails keeps ``{"error": its last line, "detail": stderr's tail}`` and is not run again,
    so one broken side does not lose the others' figures."""
    best: dict[str, dict] = {}
    for _ in range(repeat):
        for side, (cmd, cwd) in sides.items():
            if "error" in best.get(side, {}):
                continue
            try:
                result = measure(child_json(cmd, cwd=cwd))
            except (RuntimeError, ValueError, subprocess.TimeoutExpired) as exc:
                lines = str(exc).splitlines()
                best[side] = {"error": lines[-1] if lines else type(exc).__name__, "detail": str(exc)}
                continue
            if side not in best or result[key] > best[side][key]:
                best[side] = result
    return best


def timed_process(cmd: list[str], extra_env: dict[str, str] | None = None, cwd: str | None = None) -> tuple[float, str]:
    """Wall seconds from starting ``cmd`` (pinned, one thread) to its exit, and its stdout."""
    start = time.perf_counter()
    proc = subprocess.run(pinned(cmd), capture_output=True, text=True, env=child_env(extra_env), cwd=cwd)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-15:])
        raise RuntimeError(f"{_label(cmd)} ... exited with {proc.returncode}:\n{tail}")
    return wall, proc.stdout


def ensure_venv(name: str, requirements: list[str]) -> Path:
    """The interpreter of ``benchmarks/speed/peers/.venv-<name>``, created with ``requirements`` on first use.

    The folder also gets a ``.gitignore`` of ``*`` (besides the repository's ``.venv-*/`` rule), so
    a copy of the tree elsewhere never commits a peer. An install that fails removes the half-built
    folder, so the next run tries again.
    """
    folder = HERE / f".venv-{name}"
    python = folder / "bin" / "python"
    if not python.exists():
        print(f"creating {folder.relative_to(ROOT)} and installing {' '.join(requirements)} "
              "from PyPI (first run only)", flush=True)
        venv.create(folder, with_pip=True)
        (folder / ".gitignore").write_text("*\n")
        done = subprocess.run([str(python), "-m", "pip", "install", "-q", *requirements])
        if done.returncode != 0:
            shutil.rmtree(folder, ignore_errors=True)
            raise RuntimeError(f"pip install {' '.join(requirements)} failed in {folder}")
    return python


def load_average() -> float:
    """The 1-minute load average (NaN where the platform has none)."""
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def swarmscene_python() -> str:
    """The interpreter running the runner: the one with this tree's swarmscene installed."""
    return sys.executable
