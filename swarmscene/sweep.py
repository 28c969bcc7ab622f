"""Sweeps as first-class results: job records, resume, and the sweep's tidy tables.

A sweep directory (Hydra's ``hydra.sweep.dir``) holds one run directory per job. When a multirun
ends, :class:`SweepSummary` (``hydra.callbacks.swarmscene_summary`` in the primary config) writes:

    summary.csv      one row per job: job, status, error, seed, one column per overridden key,
                     the overrides as typed, the config hash, then every metric (dotted keys)
    summary.parquet  the same table, when pyarrow is importable
    summary.md       rows grouped by the swept parameters other than the seed: runs, failures,
                     success rate with its 95 % (Wilson) interval, and per metric the mean with
                     its 95 % Student-t confidence interval over the group's complete runs

A job's status is ``complete`` (manifest complete), ``incomplete`` (interrupted), ``failed``
(``error.json``: the exception that ended it) or ``unfinished`` (no manifest: killed hard).
``swarmscene-report DIR`` (:mod:`swarmscene.report`) rebuilds the same files from any directory.

A sweep directory belongs to one grid: ``sweep.json`` records every job's overrides when the sweep
is launched (:func:`record_grid`), and a launch of another grid into it is refused with one line
(:func:`check_grid_owner`). A sweep in which a job did not complete ends with exit status 1
(:func:`sweep_exit_status`; ``++hydra.callbacks.swarmscene_summary.allow_failed=true`` keeps 0).
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
import traceback
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from .sweeps.stats import mean_ci, wilson  # noqa: F401  (re-exported: tables and reports use them)
from .core.outputs import atomic_write_bytes, atomic_write_json, config_hash, package_versions

ERROR_FILE = "error.json"
MANIFEST = "manifest.json"
SWEEP_FILE = "sweep.json"
EXIT_FAILED_JOBS = 1
BASE_COLUMNS = ("job", "status", "error", "reason", "seed")
TAIL_COLUMNS = ("overrides", "config_hash")


# -- one job ------------------------------------------------------------------------------------
def record_failure(run_dir: Path, exc: BaseException, data: dict[str, Any]) -> None:
    """Write ``error.json`` and a manifest with status ``failed`` for a job that raised."""
    from .core.errors import ConfigError

    run_dir = Path(run_dir)
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
            "command": sys.argv,
            "versions": package_versions(),
            "files": sorted(p.name for p in run_dir.iterdir() if not p.name.startswith(".")),
        },
    )


def failure_reason(exc: BaseException) -> str:
    """One word for why a job could not run: the exception's own ``reason`` when it has one
    (e.g. ``needs-leader``), else ``invalid`` for a configuration the schema rejects, else ``failed``."""
    from .core.errors import ConfigError

    reason = getattr(exc, "reason", None)
    if isinstance(reason, str) and reason and not any(c.isspace() for c in reason):
        return reason
    return "invalid" if isinstance(exc, ConfigError) else "failed"


def completed_metrics(run_dir: Path, data: dict[str, Any]) -> dict[str, Any] | None:
    """The metrics of a job already complete for this exact config (resume), else None.

    A stale ``error.json`` of an earlier failed attempt is removed when the job will run again.
    """
    run_dir = Path(run_dir)
    manifest = _read_json(run_dir / MANIFEST)
    metrics = _read_json(run_dir / "metrics.json")
    if manifest and manifest.get("complete") is True and manifest.get("config_hash") == config_hash(data):
        if metrics is not None:
            return metrics
    (run_dir / ERROR_FILE).unlink(missing_ok=True)
    return None


def _read_json(path: Path) -> Any:
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


# -- one grid per sweep directory ---------------------------------------------------------------
def check_grid_owner(sweep_dir: Path, grid: list[str], jobs: list[list[str]]) -> None:
    """Raise ConfigError (one line) when ``sweep_dir`` holds the jobs of another grid.

    The same grid (the same overrides for every job) may run again: that resumes it. A directory
    without ``sweep.json`` (written before it existed) is judged by its jobs' own overrides.
    """
    from .core.errors import ConfigError

    sweep_dir = Path(sweep_dir)
    recorded = _read_json(sweep_dir / SWEEP_FILE)
    if isinstance(recorded, dict):
        if _same_jobs(recorded.get("jobs"), jobs):
            return
        there, here = _difference(recorded.get("grid") or [], grid)
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
    sweep_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_json(sweep_dir / SWEEP_FILE, {"grid": list(grid), "jobs": [list(j) for j in jobs]})


def _same_jobs(old: Any, new: list[list[str]] | None) -> bool:
    """The same jobs, ``++a.b=v`` and ``a.b=v`` counting as one (the command line's spelling of a
    plain value has changed before; the config hash still tells a changed job)."""
    if not isinstance(old, list) or new is None or len(old) != len(new):
        return False
    return all([_shown(str(o)) for o in a] == [_shown(o) for o in b] for a, b in zip(old, new))


def _override_key(override: str) -> str:
    return override.partition("=")[0].lstrip("+~")


def _difference(old: list[str], new: list[str]) -> tuple[str, str]:
    """The grid entries that differ, as ("there", "here") texts."""
    before = {_override_key(o): _shown(o) for o in old}
    after = {_override_key(o): _shown(o) for o in new}
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
    import yaml

    if not sweep_dir.is_dir():
        return None
    for run_dir in job_dirs(sweep_dir):
        overrides_file = run_dir / ".hydra" / "overrides.yaml"
        if not run_dir.name.isdigit() or not overrides_file.is_file():
            continue
        old = [str(o) for o in (yaml.safe_load(overrides_file.read_text()) or [])]
        index = int(run_dir.name)
        new = jobs[index] if index < len(jobs) else None
        if not _same_jobs([old], [new] if new is not None else None):
            return (
                f"job {index}: {' '.join(map(_shown, old)) or 'no overrides'}",
                f"job {index}: {' '.join(map(_shown, new)) or 'no overrides'}" if new is not None else f"{len(jobs)} jobs",
            )
    return None


# -- the table ----------------------------------------------------------------------------------
def job_dirs(directory: Path) -> list[Path]:
    """The run directories in ``directory``: itself when it is a run, else its job subfolders."""
    directory = Path(directory)
    if _is_run(directory):
        return [directory]
    found = [p for p in directory.iterdir() if p.is_dir() and _is_run(p)] if directory.is_dir() else []
    return sorted(found, key=lambda p: (0, int(p.name), "") if p.name.isdigit() else (1, 0, p.name))


def _is_run(path: Path) -> bool:
    return (path / MANIFEST).is_file() or (path / ".hydra" / "overrides.yaml").is_file()


def parse_value(text: str) -> Any:
    """An override's value as a number when it reads as one (for sorting and plotting)."""
    try:
        number = float(text)
    except ValueError:
        return text
    return int(number) if number.is_integer() and "." not in text and "e" not in text.lower() else number


def job_row(run_dir: Path, root: Path | None = None) -> dict[str, Any]:
    """One table row: identity, status, error, swept values and every metric of a run directory."""
    import yaml

    run_dir = Path(run_dir)
    overrides: list[str] = []
    over_file = run_dir / ".hydra" / "overrides.yaml"
    if over_file.is_file():
        overrides = [str(o) for o in (yaml.safe_load(over_file.read_text()) or [])]
    params = {}
    for item in overrides:
        key, _, value = item.lstrip("+~").partition("=")
        params[key] = parse_value(value)
    manifest = _read_json(run_dir / MANIFEST) or {}
    error = _read_json(run_dir / ERROR_FILE)
    if error is not None:
        status = "failed"
    elif not manifest:
        status = "unfinished"
    else:
        status = "complete" if manifest.get("complete") else "incomplete"
    seed = manifest.get("seed", params.get("seed"))
    if seed is None:
        config = run_dir / "config.yaml"
        seed = (yaml.safe_load(config.read_text()) or {}).get("seed") if config.is_file() else None
    row: dict[str, Any] = {
        "job": str(run_dir.relative_to(root)) if root is not None and run_dir != root else run_dir.name,
        "status": status,
        "error": error.get("error") if error else None,
        "reason": _reason(status, error),
        "seed": seed,
    }
    for key, value in params.items():
        if key != "seed":
            row[key] = value
    row["overrides"] = " ".join(overrides)
    row["config_hash"] = manifest.get("config_hash")
    metrics = _read_json(run_dir / "metrics.json") or {} if status != "failed" else {}
    for key, value in metrics.items():
        column = f"metric.{key}" if key in row else key
        row[column] = json.dumps(value) if isinstance(value, (list, dict)) else value
    return row


def _reason(status: str, error: dict[str, Any] | None) -> str | None:
    """One word for a job that did not complete (records written before ``reason`` existed: from
    the exception type)."""
    if status == "complete":
        return None
    if status != "failed":
        return {"incomplete": "interrupted"}.get(status, status)
    if error.get("reason"):
        return str(error["reason"])
    return "invalid" if error.get("type") == "ConfigError" else "failed"


def collect_rows(directory: Path) -> list[dict[str, Any]]:
    directory = Path(directory)
    return [job_row(d, directory) for d in job_dirs(directory)]


def param_columns(rows: list[dict[str, Any]]) -> list[str]:
    """Overridden keys (from every job's overrides), in first-seen order, seed excluded."""
    seen: dict[str, None] = {}
    for row in rows:
        for item in row.get("overrides", "").split():
            key = item.lstrip("+~").partition("=")[0]
            if key != "seed":
                seen.setdefault(key, None)
    return list(seen)


def swept_parameters(rows: list[dict[str, Any]]) -> list[str]:
    """Overridden keys whose value differs between jobs (the seed left out)."""
    return [k for k in param_columns(rows) if len({_key(row.get(k)) for row in rows}) > 1]


def columns(rows: list[dict[str, Any]]) -> list[str]:
    params = param_columns(rows)
    fixed = set(BASE_COLUMNS) | set(TAIL_COLUMNS) | set(params)
    metrics = sorted({k for row in rows for k in row} - fixed)
    return [*BASE_COLUMNS, *params, *TAIL_COLUMNS, *metrics]


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float) and not math.isfinite(value):
        return ""
    return value


def csv_text(rows: list[dict[str, Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns(rows), extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(v) for k, v in row.items()})
    return buffer.getvalue()


def parquet_bytes(rows: list[dict[str, Any]]) -> bytes | None:
    """The table as Parquet, or None when pyarrow is not importable."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return None
    arrays = {}
    for name in columns(rows):
        values = [row.get(name) for row in rows]
        try:
            arrays[name] = pa.array(values)
        except (pa.ArrowInvalid, pa.ArrowTypeError):  # mixed types: keep them readable as text
            arrays[name] = pa.array([None if v is None else str(v) for v in values], type=pa.string())
    buffer = io.BytesIO()
    pq.write_table(pa.table(arrays), buffer)
    return buffer.getvalue()


# -- statistics: swarmscene.sweeps.stats ---------------------------------------------------------


def _key(value: Any) -> Any:
    return json.dumps(value, sort_keys=True, default=str)


def groups(rows: list[dict[str, Any]], by: list[str]) -> list[tuple[tuple[Any, ...], list[dict[str, Any]]]]:
    """Rows grouped by the values of ``by``, groups sorted by those values."""
    out: dict[str, tuple[tuple[Any, ...], list[dict[str, Any]]]] = {}
    for row in rows:
        values = tuple(row.get(k) for k in by)
        out.setdefault(_key(values), (values, []))[1].append(row)
    return sorted(out.values(), key=lambda g: tuple((isinstance(v, str), str(v) if isinstance(v, str) else v or 0) for v in g[0]))


def metric_names(rows: list[dict[str, Any]]) -> tuple[list[str], list[str]]:
    """(rate metrics: booleans, numeric metrics) over the table's metric columns."""
    rates: set[str] = set()
    numbers: set[str] = set()
    fixed = {*BASE_COLUMNS, *TAIL_COLUMNS, *param_columns(rows)}
    for row in rows:
        for key, value in row.items():
            if key in fixed or value is None:
                continue
            if isinstance(value, bool):
                rates.add(key)
            elif isinstance(value, (int, float)):
                numbers.add(key)
    numbers -= rates
    ordered_rates = sorted(rates, key=lambda k: (k != "success", k))
    return ordered_rates, sorted(numbers)


def _fmt(value: float) -> str:
    if value is None or not np.isfinite(value):
        return "n/a"
    return f"{value:.4g}"


def _label(by: list[str], values: tuple[Any, ...]) -> str:
    """``k=v, ...`` of a group; a key its jobs do not set (another case of the sweep) is left out."""
    return ", ".join(f"{k}={v}" for k, v in zip(by, values) if v is not None) or "all jobs"


# The outcome of a run, in the overview and the methods table: safety first, then the mission.
SAFETY_CONDITIONS = ("separation", "clearance")
# A group is deterministic when its runs of different seeds agree on all of these to the bit.
OUTCOME_KEYS = ("success", "min_separation", "min_clearance", "duration", "steps", "collisions")


def first_violation_time(row: dict[str, Any]) -> float | None:
    """The first time a safety condition (separation or clearance) was violated, s; None if never."""
    times = [row.get(f"violations.{c}.first_time") for c in SAFETY_CONDITIONS]
    times = [t for t in times if _is_number(t)]
    return float(min(times)) if times else None


def completion_time(row: dict[str, Any]) -> float | None:
    """When the mission was complete (the run stopped on completion), s; None if it never was."""
    if _is_number(row.get("completion_time")):
        return float(row["completion_time"])
    if row.get("stop_reason") == "complete" and _is_number(row.get("duration")):
        return float(row["duration"])
    return None


def deterministic(done: list[dict[str, Any]]) -> bool:
    """True when runs of at least two different seeds gave the same outcome to the bit: the seed
    changes nothing here, so the runs are one sample repeated and no interval is meaningful."""
    seeds = {_key(r.get("seed")) for r in done}
    if len(done) < 2 or len(seeds) < 2:
        return False
    return all(len({_key(r.get(k)) for r in done}) == 1 for k in OUTCOME_KEYS)


def _identical(values: list[float]) -> bool:
    return len(values) >= 2 and len(set(values)) == 1


def mean_cell(values: Iterable[float | None], unit: str = "") -> str:
    """``mean [95 % CI]`` of the values, or what stands in for the interval when there is none."""
    x = [float(v) for v in values if v is not None and np.isfinite(v)]
    mean, half, n = mean_ci(x)
    if n == 0:
        return "n/a"
    if n == 1:
        return f"{_fmt(mean)}{unit} (one run)"
    if _identical(x):
        return f"{_fmt(mean)}{unit} (identical in {n} runs)"
    return f"{_fmt(mean)}{unit} [{_fmt(mean - half)}, {_fmt(mean + half)}]"


def success_cell(done: list[dict[str, Any]]) -> str:
    flags = [r["success"] for r in done if isinstance(r.get("success"), bool)]
    if not flags:
        return "n/a"
    rate = sum(flags) / len(flags)
    if deterministic(done):
        return f"{rate:.2f} (deterministic)"
    lo, hi = wilson(sum(flags), len(flags))
    return f"{rate:.2f} [{lo:.2f}, {hi:.2f}]"


def violation_cell(done: list[dict[str, Any]]) -> str:
    times = [first_violation_time(r) for r in done]
    hit = [t for t in times if t is not None]
    if not done:
        return "n/a"
    if not hit:
        return f"none in {len(done)}"
    return f"{len(hit)}/{len(done)}: " + mean_cell(hit, " s")


def completion_cell(done: list[dict[str, Any]]) -> str:
    times = [completion_time(r) for r in done]
    reached = [t for t in times if t is not None]
    if not done:
        return "n/a"
    if not reached:
        return f"not complete in {len(done)}"
    share = "" if len(reached) == len(done) else f"{len(reached)}/{len(done)}: "
    return share + mean_cell(reached, " s")


OVERVIEW = (
    "success rate (95 % CI)", "min separation, m", "min clearance, m", "first safety violation",
    "completion time",
)


def overview_cells(done: list[dict[str, Any]]) -> list[str]:
    """The overview's outcome columns for one group's complete runs (see OVERVIEW)."""
    return [
        success_cell(done),
        mean_cell(r.get("min_separation") for r in done if _is_number(r.get("min_separation"))),
        mean_cell(r.get("min_clearance") for r in done if _is_number(r.get("min_clearance"))),
        violation_cell(done),
        completion_cell(done),
    ]


def markdown(rows: list[dict[str, Any]], title: str) -> str:
    """The short grouped report (see the module docstring)."""
    by = swept_parameters(rows)
    rates, numbers = metric_names(rows)
    counts = {s: sum(r["status"] == s for r in rows) for s in ("complete", "incomplete", "failed", "unfinished")}
    seeds = sorted({r.get("seed") for r in rows if r.get("seed") is not None}, key=str)
    grouped = groups(rows, by)
    fixed = [_label(by, values) for values, members in grouped
             if deterministic([r for r in members if r["status"] == "complete"])]
    lines = [
        f"# Sweep summary: {title}",
        "",
        f"{len(rows)} jobs: " + ", ".join(f"{n} {s}" for s, n in counts.items() if n) + ". "
        + (f"Grouped by {', '.join(by)}" if by else "One group")
        + f"; {len(seeds)} seed(s). Means and 95 % confidence intervals (Student t) over "
        "the complete runs of each group; rates with 95 % Wilson intervals. The first safety "
        "violation is the earliest time separation or clearance was violated, over the runs that "
        "violated one; the completion time is over the runs that completed the mission.",
        "",
    ]
    if fixed:
        lines += [
            "Deterministic (every seed gave the same run, so the seed changes nothing there and no "
            "interval is shown): " + "; ".join(fixed) + ".",
            "",
        ]
    lines += [
        "## Overview",
        "",
        "| " + " | ".join([*by, "runs", "complete", "failed", *OVERVIEW]) + " |",
        "|" + "---|" * (len(by) + 3 + len(OVERVIEW)),
    ]
    for values, members in grouped:
        done = [r for r in members if r["status"] == "complete"]
        failed = sum(r["status"] == "failed" for r in members)
        shown = ["-" if v is None else str(v) for v in values]  # "-": not set in these jobs
        cells = [*shown, str(len(members)), str(len(done)), str(failed), *overview_cells(done)]
        lines.append("| " + " | ".join(cells) + " |")
    failures = [r for r in rows if r["status"] in ("failed", "incomplete", "unfinished")]
    if failures:
        lines += ["", "## Jobs that did not complete", "", "| job | status | overrides | error |", "|---|---|---|---|"]
        for r in failures:
            error = (r.get("error") or "").replace("|", "\\|")
            lines.append(f"| {r['job']} | {r['status']} | {r.get('overrides', '')} | {error} |")
    for values, members in grouped:
        done = [r for r in members if r["status"] == "complete"]
        fixed_group = deterministic(done)
        lines += ["", f"## {_label(by, values)}", "", "| metric | mean | 95 % CI | n |", "|---|---|---|---|"]
        for name in rates:
            flags = [r[name] for r in done if isinstance(r.get(name), bool)]
            if flags:
                if fixed_group:
                    ci = "none: deterministic"
                else:
                    lo, hi = wilson(sum(flags), len(flags))
                    ci = f"[{_fmt(lo)}, {_fmt(hi)}]"
                lines.append(f"| {name} (rate) | {_fmt(sum(flags) / len(flags))} | {ci} | {len(flags)} |")
        for name in numbers:
            sample = [float(r[name]) for r in done if _is_number(r.get(name)) and np.isfinite(r[name])]
            mean, half, n = mean_ci(sample)
            if n:
                if n == 1:
                    ci = "n/a (one run)"
                elif _identical(sample):
                    ci = f"none: identical in all {n} runs"
                else:
                    ci = f"[{_fmt(mean - half)}, {_fmt(mean + half)}]"
                lines.append(f"| {name} | {_fmt(mean)} | {ci} | {n} |")
    return "\n".join(lines) + "\n"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def write_summary(directory: Path) -> list[dict[str, Any]]:
    """Write summary.csv, summary.parquet (with pyarrow) and summary.md into ``directory``."""
    directory = Path(directory)
    rows = collect_rows(directory)
    atomic_write_bytes(directory / "summary.csv", csv_text(rows).encode())
    parquet = parquet_bytes(rows)
    if parquet is not None:
        atomic_write_bytes(directory / "summary.parquet", parquet)
    atomic_write_bytes(directory / "summary.md", markdown(rows, str(directory)).encode())
    return rows


# -- the end of a sweep ---------------------------------------------------------------------------
def outcome_line(rows: list[dict[str, Any]]) -> str:
    """``4 jobs, all complete`` or ``1 of 4 jobs failed`` (with the other statuses when any)."""
    if rows and all(r["status"] == "complete" for r in rows):
        return f"{len(rows)} jobs, all complete"
    counts = {s: sum(r["status"] == s for r in rows) for s in ("failed", "incomplete", "unfinished")}
    missing = sum(counts.values())
    if missing == counts["failed"]:
        return f"{missing} of {len(rows)} jobs failed"
    detail = ", ".join(f"{n} {s}" for s, n in counts.items() if n)
    return f"{missing} of {len(rows)} jobs did not complete ({detail})"


def exit_status(rows: list[dict[str, Any]], allow_failed: bool = False) -> int:
    """The process status a sweep ends with: 1 when a job did not complete (or none ran), else 0."""
    if allow_failed:
        return 0
    return EXIT_FAILED_JOBS if not rows or any(r["status"] != "complete" for r in rows) else 0


def sweep_exit_status(sweep_dir: Path, allow_failed: bool = False) -> int:
    """:func:`exit_status` of the jobs found in ``sweep_dir``."""
    return exit_status(collect_rows(Path(sweep_dir)), allow_failed)


def _stop(lines: list[str], status: int) -> None:
    """Print the lines as the command line does and end the process (a Hydra callback's ordinary
    exception would only become a warning)."""
    for line in lines:
        print(f"swarmscene: {line}", file=sys.stderr)
    raise SystemExit(status)


# -- the Hydra callback -------------------------------------------------------------------------
try:
    from hydra.experimental.callback import Callback as _Callback
except ImportError:  # pragma: no cover - hydra-core is a dependency
    _Callback = object

BASIC_SWEEPER = "hydra._internal.core_plugins.basic_sweeper.BasicSweeper"


class SweepSummary(_Callback):
    """Hydra callback of every multirun (``hydra.callbacks.swarmscene_summary``).

    At the start, for Hydra's basic sweeper, it makes the checks that swarmscene's sweeper makes
    itself (the directory's grid, every distinct override validated: see
    ``hydra_plugins.swarmscene_sweeper``): a problem ends the process with status 2 and one line.
    At the end it writes the sweep directory's tables, prints how many jobs failed, and ends the
    process with status 1 when a job did not complete, unless ``allow_failed`` is true.

    While the jobs run it shows their progress (jobs done of the total, failures so far, time left;
    ``summary.SweepProgress``), whatever the launcher.

    Args:
        allow_failed: keep exit status 0 when jobs failed (the summary still counts them).
        progress: ``auto`` (on a terminal), ``on`` or ``off``: the sweep's progress line.
    """

    def __init__(self, allow_failed: bool = False, progress: str = "auto") -> None:
        self.allow_failed = bool(allow_failed)
        if progress not in ("auto", "on", "off"):
            _stop([f"hydra.callbacks.swarmscene_summary.progress: must be auto, on or off (got {progress!r})"], 2)
        self.progress_mode = progress
        self.progress: Any = None

    def __getstate__(self) -> dict[str, Any]:
        # Launchers pickle the callbacks with each job; the watcher thread stays in this process.
        return {**self.__dict__, "progress": None}

    def on_multirun_start(self, config: Any, **kwargs: Any) -> None:
        self._check_basic_sweep(config)
        from .summary import SweepProgress

        self.progress = SweepProgress.maybe(Path(config.hydra.sweep.dir), self.progress_mode)

    def _check_basic_sweep(self, config: Any) -> None:
        if config.hydra.sweeper.get("_target_") != BASIC_SWEEPER:
            return  # swarmscene's sweeper checks for itself; other sweepers have no grid
        from hydra.core.global_hydra import GlobalHydra
        from hydra.core.override_parser.overrides_parser import OverridesParser
        from omegaconf import OmegaConf

        from hydra_plugins.swarmscene_sweeper import expand, prepare

        from .core.errors import ConfigError

        loader = GlobalHydra.instance().config_loader()
        params = OmegaConf.to_container(config.hydra.sweeper.params) if config.hydra.sweeper.get("params") else {}
        arguments = list(OmegaConf.to_container(config.hydra.overrides.task, resolve=False))
        try:
            grid, jobs = expand(params, arguments, OverridesParser.create(config_loader=loader), plain_params=False)
            prepare(loader, config, Path(config.hydra.sweep.dir), grid, jobs)
        except ConfigError as exc:
            _stop(exc.lines, 2)

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        if self.progress is not None:
            self.progress.stop()
        sweep_dir = Path(config.hydra.sweep.dir)
        try:
            rows = write_summary(sweep_dir)
        except Exception as exc:  # a table problem must not hide the jobs' own outputs
            print(f"swarmscene: could not write the sweep summary: {exc}", file=sys.stderr)
            return
        status = exit_status(rows, self.allow_failed)
        kept = " (allow_failed: exit status 0)" if self.allow_failed and exit_status(rows) else ""
        print(f"swarmscene: {outcome_line(rows)}{kept}; summary in {sweep_dir / 'summary.md'}", file=sys.stderr)
        if status:
            raise SystemExit(status)
