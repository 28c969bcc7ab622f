"""A sweep directory's records: each job's outcome, the grid that owns the directory, its lock.

A sweep directory (Hydra's ``hydra.sweep.dir``) holds one run directory per job (docs/outputs.md)
and three records of the sweep itself:

    sweep.json    the grid as given and every job's overrides (job ``i`` is ``jobs[i]``), written
                  before the first job starts (:func:`record_grid`)
    .sweep.lock   held (``flock``) by the process that runs the sweep, for as long as it runs
    summary.*     the tables (:mod:`swarmscene.sweeps.tables`)

A directory belongs to one grid: a launch of another grid into it is refused with one line
(:func:`check_grid_owner`); the same grid resumes (a job complete for the same config hash is
skipped, :func:`completed_metrics`). Overrides of display options (:data:`DISPLAY_KEYS`) are not
part of a job's identity: ``+sweep=fast output.progress=off`` resumes ``+sweep=fast``. Every file
read here may be damaged or planted: it is read through :mod:`swarmscene.runs.rundir`, and a damaged
``sweep.json`` or lock is one line (:class:`~swarmscene.core.errors.ConfigError`), never a warning.
"""

from __future__ import annotations

import os
import traceback
from pathlib import Path
from typing import Any

from ..runs.outputs import atomic_write_json, config_hash, package_versions, run_command

ERROR_FILE = "error.json"
MANIFEST = "manifest.json"
SWEEP_FILE = "sweep.json"
LOCK_FILE = ".sweep.lock"
DISPLAY_KEYS = (
    "output.progress", "output.summary", "output.plots", "output.animation", "output.animation_frames",
    "output.comm_edges", "output.rerun", "output.live", "output.objective", "description",
)
"""Options that change what is shown or drawn, not what a job computes: their overrides are left
out when a directory's grid is compared (and out of the config hash: ``COSMETIC_KEYS``)."""


# -- one job ------------------------------------------------------------------------------------
def record_failure(run_dir: Path, exc: BaseException, data: dict[str, Any]) -> None:
    """Write ``error.json`` and a manifest with status ``failed`` for a job that raised."""
    from ..core.errors import ConfigError

    run_dir = Path(run_dir)
    refuse_linked_job_dir(run_dir)
    write_overrides(run_dir)
    lines = exc.lines if isinstance(exc, ConfigError) else [f"{type(exc).__name__}: {exc}"]
    message = "; ".join(line.splitlines()[0] for line in lines if line) or type(exc).__name__
    atomic_write_json(
        run_dir / ERROR_FILE,
        {
            "error": message,
            "reason": failure_reason(exc),
            "type": type(exc).__name__,
            "lines": lines,
            "traceback": "".join(traceback.format_exception(exc)),
        },
    )
    atomic_write_json(
        run_dir / MANIFEST,
        {
            "config_hash": config_hash({k: v for k, v in data.items() if k != "hydra"}),
            "seed": data.get("seed"),
            "complete": False,
            "status": "failed",
            "error": message,
            **run_command(),
            "versions": package_versions(),
            "files": sorted(p.name for p in run_dir.iterdir() if not p.name.startswith(".")),
        },
    )


def refuse_linked_job_dir(run_dir: Path) -> None:
    """A job directory or its ``.hydra/`` planted as a symbolic link is refused (RunFileError, one
    line): every record of the job is written inside the sweep directory, never through a link."""
    from ..runs.rundir import RunFileError

    for directory in (Path(run_dir), Path(run_dir) / ".hydra"):
        if directory.is_symlink():
            raise RunFileError(
                directory, "is a symbolic link (refused: a job's records are written inside the sweep directory)")


def write_overrides(run_dir: Path, overrides: list[str] | None = None) -> None:
    """Write the job's ``.hydra/overrides.yaml`` (Hydra's list of the job's overrides,
    ``HydraConfig``'s ``overrides.task`` unless ``overrides`` are given) when Hydra did not (a
    sweep's jobs run with ``hydra.output_subdir: null``: ``compose._as_sweep_job``)."""
    import yaml
    from hydra.core.hydra_config import HydraConfig

    from ..runs.outputs import atomic_write_bytes

    refuse_linked_job_dir(run_dir)
    path = Path(run_dir) / ".hydra" / "overrides.yaml"
    if path.exists() or path.is_symlink() or (overrides is None and not HydraConfig.initialized()):
        return
    if overrides is None:
        overrides = [str(o) for o in HydraConfig.get().overrides.task]
    atomic_write_bytes(path, yaml.safe_dump(overrides, default_flow_style=False, sort_keys=False).encode())


def failure_reason(exc: BaseException) -> str:
    """One word for why a job could not run: the exception's own ``reason`` when it has one
    (e.g. ``needs-leader``), else ``invalid`` for a configuration the schema rejects, else ``failed``."""
    from ..core.errors import ConfigError

    reason = getattr(exc, "reason", None)
    if isinstance(reason, str) and reason and not any(c.isspace() for c in reason):
        return reason
    return "invalid" if isinstance(exc, ConfigError) else "failed"


def completed_metrics(run_dir: Path, data: dict[str, Any]) -> dict[str, Any] | None:
    """The metrics of a job already complete for this exact config (resume), else None.

    Complete means: the manifest says so for the same config hash, and every file it lists that
    a resume relies on loads (``metrics.json`` a mapping, ``trajectory.npz`` whole, checked by
    :mod:`swarmscene.runs.rundir`). Before the job runs (again), what a killed attempt left behind goes:
    a stale ``error.json`` and its temporary files (``.*.tmp``).
    """
    run_dir = Path(run_dir)
    refuse_linked_job_dir(run_dir)
    remove_temporaries(run_dir)
    if complete_problem(run_dir, config_hash(data)) is None:
        from ..runs.rundir import RunDir

        return RunDir(run_dir).metrics()
    if (run_dir / ERROR_FILE).is_file() or (run_dir / ERROR_FILE).is_symlink():
        (run_dir / ERROR_FILE).unlink()
    return None


def complete_problem(run_dir: Path, expected_hash: str | None = None) -> str | None:
    """None when the run directory holds a complete run (for ``expected_hash``, when given),
    else why not, in one line (a damaged file names itself)."""
    from ..runs.rundir import RunDir, RunFileError

    try:
        run = RunDir(run_dir)
        if not run.has(MANIFEST):
            return "no manifest (the job did not finish)"
        manifest = run.manifest()
        if manifest.get("complete") is not True:
            return "not complete"
        if expected_hash is not None and manifest.get("config_hash") != expected_hash:
            return "another config"
        run.metrics()
        files = manifest.get("files")
        if (isinstance(files, list) and "trajectory.npz" in files) or run.has("trajectory.npz"):
            run.check_trajectory()
    except RunFileError as exc:
        return str(exc)
    return None


def remove_temporaries(run_dir: Path) -> None:
    """Remove the temporary files (``.<name>.<random>.tmp``) an interrupted write left in a run
    directory and its ``.hydra/`` (a link is removed as a link, never followed)."""
    for folder in (Path(run_dir), Path(run_dir) / ".hydra"):
        if folder.is_symlink() or not folder.is_dir():
            continue
        for path in folder.glob(".*.tmp"):
            if path.is_symlink() or path.is_file():
                path.unlink(missing_ok=True)


# -- one sweep per directory --------------------------------------------------------------------
class SweepLock:
    """The sweep directory's lock (``.sweep.lock``, ``flock``): one sweep at a time.

    Held by the process that launches the jobs from before the first job until the sweep ends (or
    the process does: the kernel drops a dead process's lock, so a killed sweep never leaves the
    directory locked). Released, the lock file is removed, and so is the directory when the lock
    made it and nothing else was written (a sweep refused before its first job leaves nothing).
    """

    ATTEMPTS = 3

    def __init__(self, sweep_dir: Path) -> None:
        self.sweep_dir = Path(sweep_dir)
        self.path = self.sweep_dir / LOCK_FILE
        self.fd: int | None = None
        self.made_dir = False

    def acquire(self) -> SweepLock:
        """Take the lock (making the directory if need be); a ConfigError names the directory when
        another sweep holds it or its lock file cannot be opened."""
        from ..core.errors import ConfigError

        self.made_dir = not self.sweep_dir.exists()
        ensure_writable(self.sweep_dir)
        for _ in range(self.ATTEMPTS):
            if self._try():
                return self
        raise ConfigError([f"hydra.sweep.dir: {self.path}: could not be locked (it keeps being replaced)"])

    def _try(self) -> bool:
        """True once locked; False when the file was replaced under us (a released lock removes
        its file: the one we locked must still be the one at the path)."""
        import fcntl

        from ..core.errors import ConfigError

        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise ConfigError([f"hydra.sweep.dir: {self.path}: cannot be opened ({exc.strerror or exc})"]) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip()
            os.close(fd)
            raise ConfigError([
                f"hydra.sweep.dir: {self.sweep_dir} is in use by another sweep"
                + (f" (pid {holder})" if holder.isdigit() else "")
                + ": wait for it to end, or choose another hydra.sweep.dir"
            ]) from None
        try:
            same = os.stat(self.path, follow_symlinks=False).st_ino == os.fstat(fd).st_ino
        except OSError:
            same = False
        if not same:
            os.close(fd)
            return False
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        self.fd = fd
        return True

    def release(self) -> None:
        """Remove the lock file (ours only) and unlock; remove the directory if the lock made it and
        it holds nothing else. A second call does nothing."""
        if self.fd is None:
            return
        try:  # while still held: a waiting opener sees it replaced; only our own file, though
            if os.stat(self.path, follow_symlinks=False).st_ino == os.fstat(self.fd).st_ino:
                self.path.unlink()
        except FileNotFoundError:  # removed by hand meanwhile (another sweep may hold a new one)
            pass
        os.close(self.fd)  # closing drops the flock
        self.fd = None
        if self.made_dir:
            try:
                self.sweep_dir.rmdir()  # only when empty: nothing was launched into it
            except OSError:
                pass


def ensure_writable(sweep_dir: Path) -> None:
    """Create the sweep directory; ConfigError (one line naming it) when it cannot be written."""
    from ..core.errors import ConfigError

    sweep_dir = Path(sweep_dir)
    try:
        if sweep_dir.is_symlink():
            raise ConfigError([f"hydra.sweep.dir: {sweep_dir} is a symbolic link (refused: give the directory itself)"])
        sweep_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError([f"hydra.sweep.dir: {sweep_dir} cannot be created ({exc.strerror or exc})"]) from None
    if not sweep_dir.is_dir():
        raise ConfigError([f"hydra.sweep.dir: {sweep_dir} is not a directory"])
    if not os.access(sweep_dir, os.W_OK | os.X_OK):
        raise ConfigError([f"hydra.sweep.dir: {sweep_dir} is not writable (read-only): choose another hydra.sweep.dir"])


def read_grid(sweep_dir: Path) -> dict[str, Any] | None:
    """``sweep.json`` checked (``grid``: list of text, ``jobs``: list of lists of text), or None
    when there is none; ConfigError (one line naming the file) when it is damaged."""
    from ..core.errors import ConfigError
    from ..runs.rundir import RunFileError, read_json

    path = Path(sweep_dir) / SWEEP_FILE
    if not path.exists() and not path.is_symlink():
        return None
    try:
        record = read_json(path)
        grid, jobs = record.get("grid"), record.get("jobs")
        if not isinstance(grid, list) or not all(isinstance(g, str) for g in grid):
            raise RunFileError(path, "'grid' should be a list of overrides")
        if not isinstance(jobs, list) or not all(
            isinstance(j, list) and all(isinstance(o, str) for o in j) for j in jobs
        ):
            raise RunFileError(path, "'jobs' should be a list of override lists")
    except RunFileError as exc:
        raise ConfigError([
            f"{exc} (the sweep's record is damaged: restore it, or delete the directory to start over)"
        ]) from None
    return record


def check_grid_owner(sweep_dir: Path, grid: list[str], jobs: list[list[str]]) -> None:
    """Raise ConfigError (one line) when ``sweep_dir`` holds the jobs of another grid.

    The same grid (the same overrides for every job, display options aside) may run again: that
    resumes it. A directory without ``sweep.json`` (written before it existed) is judged by its
    jobs' own overrides.
    """
    from ..core.errors import ConfigError

    sweep_dir = Path(sweep_dir)
    if _is_run(sweep_dir):  # a single run's directory: its jobs would hide among its files, the summary its alone
        raise ConfigError([
            f"hydra.sweep.dir: {sweep_dir} is a run's directory ({MANIFEST} or .hydra/overrides.yaml in it), "
            "not a sweep's: choose another hydra.sweep.dir"
        ])
    recorded = read_grid(sweep_dir)
    if recorded is not None:
        if _same_jobs(recorded["jobs"], jobs):
            return
        there, here = _difference(recorded["grid"], grid)
    else:
        clash = _first_foreign_job(sweep_dir, jobs)
        if clash is None:
            return
        there, here = clash
    raise ConfigError([
        f"hydra.sweep.dir: {sweep_dir} holds another sweep ({there}; this one: {here}): "
        "choose another hydra.sweep.dir, or delete that directory to start over"
    ])


def record_grid(sweep_dir: Path, grid: list[str], jobs: list[list[str]]) -> None:
    """Write ``sweep.json``: the grid as given and every job's overrides (job ``i`` is ``jobs[i]``)."""
    sweep_dir = Path(sweep_dir)
    ensure_writable(sweep_dir)
    atomic_write_json(sweep_dir / SWEEP_FILE, {"grid": list(grid), "jobs": [list(j) for j in jobs]})


def identity(overrides: list[str]) -> list[str]:
    """A job's overrides as they define it: spelled as typed, display options left out."""
    return [_shown(str(o)) for o in overrides if _override_key(str(o)) not in DISPLAY_KEYS]


def _same_jobs(old: Any, new: list[list[str]] | None) -> bool:
    """The same jobs, ``++a.b=v`` and ``a.b=v`` counting as one (the command line's spelling of a
    plain value has changed before; the config hash still tells a changed job)."""
    if not isinstance(old, list) or new is None or len(old) != len(new):
        return False
    return all(identity(a) == identity(b) for a, b in zip(old, new, strict=True))  # lengths checked above


def _override_key(override: str) -> str:
    return override.partition("=")[0].lstrip("+~")


def _difference(old: list[str], new: list[str]) -> tuple[str, str]:
    """The grid entries that differ, as ("there", "here") texts."""
    before = {_override_key(o): _shown(o) for o in old if _override_key(o) not in DISPLAY_KEYS}
    after = {_override_key(o): _shown(o) for o in new if _override_key(o) not in DISPLAY_KEYS}
    keys = [k for k in dict.fromkeys([*before, *after]) if before.get(k) != after.get(k)]
    if not keys:  # the same grid text expanded into other jobs (another version of Hydra)
        return "a different job list", "the grid " + " ".join(after.values())
    return (
        " ".join(before.get(k, f"no {k}") for k in keys),
        " ".join(after.get(k, f"no {k}") for k in keys),
    )


def _shown(override: str) -> str:
    """An override as the user wrote it: the command line spells plain values ``++a.b=v``."""
    return override[2:] if override.startswith("++") else override


def _first_foreign_job(sweep_dir: Path, jobs: list[list[str]]) -> tuple[str, str] | None:
    """The first job directory whose overrides are not this grid's job of the same number."""
    from ..runs.rundir import RunDir, RunFileError

    if not sweep_dir.is_dir():
        return None
    for run_dir in job_dirs(sweep_dir):
        if not run_dir.name.isdigit() or not (run_dir / ".hydra" / "overrides.yaml").is_file():
            continue
        index = int(run_dir.name)
        try:
            old = RunDir(run_dir).overrides()
        except RunFileError as exc:
            return (str(exc), f"job {index}")
        new = jobs[index] if index < len(jobs) else None
        if not _same_jobs([old], [new] if new is not None else None):
            was = f"job {index}: {' '.join(map(_shown, old)) or 'no overrides'}"
            if new is None:
                return (was, f"{len(jobs)} jobs")
            return (was, f"job {index}: {' '.join(map(_shown, new)) or 'no overrides'}")
    return None


def job_dirs(directory: Path) -> list[Path]:
    """The run directories in ``directory``: itself when it is a run, else its job subfolders.
    Links are not followed: a link planted where a job's folder goes (a number) is listed, so the
    table shows that job as damaged (:func:`swarmscene.sweeps.tables.job_row`), never read."""
    directory = Path(directory)
    if _is_run(directory):
        return [directory]
    found = (
        [p for p in directory.iterdir() if (not p.is_symlink() and p.is_dir() and _is_run(p))
         or (p.is_symlink() and p.name.isdigit())]  # a job's place taken by a link: listed, never read
        if directory.is_dir() else []
    )
    return sorted(found, key=lambda p: (0, int(p.name), "") if p.name.isdigit() else (1, 0, p.name))


def _is_run(path: Path) -> bool:
    return (path / MANIFEST).is_file() or (path / ".hydra" / "overrides.yaml").is_file()
