"""A sweep's tidy tables: one row per job, and the grouped summary with its intervals.

When a multirun ends (:mod:`swarmscene.sweeps.callback`) or ``swarmscene-report DIR`` runs
(:mod:`swarmscene.sweeps.report`), the sweep directory gets:

    summary.csv      one row per job: job, status, error, reason, seed, one column per overridden
                     key, the overrides as typed, the config hash, then every metric (dotted keys);
                     every ``violations.*`` column is present in every table (empty first time and
                     ``[]`` agents for a condition a complete run never violated; both empty for
                     the keep-out ellipsoid of a run that did not set ``safety.keep_out``)
    summary.parquet  the same table, when pyarrow is importable
    summary.md       rows grouped by the swept parameters other than the seed: runs, failures,
                     success rate with its 95 % (Wilson) interval, and per metric the mean with its
                     95 % interval (:func:`~swarmscene.sweeps.stats.mean_interval`: Student t, or the
                     percentile bootstrap for a quantity that cannot be negative, ``lower_bound``)

A job's status is ``complete`` (manifest complete and its files load), ``incomplete``
(interrupted), ``failed`` (``error.json``: the exception that ended it), ``unfinished`` (no
manifest: killed hard) or ``damaged`` (a file that does not load: its one-line problem is the
row's error). A sweep in which a job did not complete ends with exit status 1 (:func:`exit_status`;
``++hydra.callbacks.swarmscene_summary.allow_failed=true`` keeps 0).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

from ..runs.outputs import atomic_write_bytes
from .records import ERROR_FILE, MANIFEST, complete_problem, job_dirs
from .stats import lower_bound, mean_interval, wilson

EXIT_FAILED_JOBS = 1
BASE_COLUMNS = ("job", "status", "error", "reason", "seed")
TAIL_COLUMNS = ("overrides", "config_hash")
VIOLATION_CONDITIONS = ("separation", "clearance", "connectivity", "keep_out")
"""The monitor's conditions (core/monitors.py): each has a column pair in every table."""
OPT_IN_CONDITIONS = {"keep_out": "keep_out_conflicts"}
"""Conditions a scenario may leave unchecked, and the metric that is null when it did: such a
run's cells stay empty (not checked), not ``[]`` agents (checked, never violated)."""
VIOLATION_COLUMNS = tuple(f"violations.{c}.{f}" for c in VIOLATION_CONDITIONS for f in ("first_time", "agents"))


def parse_value(text: str) -> Any:
    """An override's value as a number when it reads as one (for sorting and plotting)."""
    try:
        number = float(text)
    except ValueError:
        return text
    return int(number) if number.is_integer() and "." not in text and "e" not in text.lower() else number


def job_row(run_dir: Path, root: Path | None = None) -> dict[str, Any]:
    """One table row: identity, status, error, swept values and every metric of a run directory.

    Every file is read through :mod:`swarmscene.runs.rundir`: a job whose files do not load (a garbage
    ``metrics.json``, a truncated trajectory) is ``damaged``, with the file's one-line problem as
    its error, never ``complete``.
    """
    from ..runs.rundir import RunDir, RunFileError

    if Path(run_dir).is_symlink():  # planted where a job's folder goes: reported, never read
        name = str(Path(run_dir).relative_to(root)) if root is not None else Path(run_dir).name
        return {"job": name, "status": "damaged", "reason": "damaged", "seed": None, "overrides": "",
                "config_hash": None, "error": f"{run_dir}: is a symbolic link (refused: not read)"}
    run = RunDir(run_dir)
    damage: list[str] = []

    def read(name: str, reader: Any, default: Any) -> Any:
        if not run.has(name):
            return default
        try:
            return reader()
        except RunFileError as exc:
            damage.append(str(exc))
            return default

    overrides = read(".hydra/overrides.yaml", run.overrides, [])
    params = {}
    for item in overrides:
        key, _, value = item.lstrip("+~").partition("=")
        params[key] = parse_value(value)
    manifest = read(MANIFEST, run.manifest, {})
    error = read(ERROR_FILE, run.error, None)
    metrics = read("metrics.json", run.metrics, {}) if error is None else {}
    if error is not None:
        status = "failed"
    elif damage:
        status = "damaged"
    elif not manifest:
        status = "unfinished"
    elif manifest.get("complete") is True:
        problem = complete_problem(run.path)
        status = "complete" if problem is None else "damaged"
        damage += [problem] if problem else []
    else:
        status = "incomplete"
    seed = manifest.get("seed", params.get("seed"))
    if seed is None and run.has("config.yaml"):
        seed = read("config.yaml", run.config, {}).get("seed")
    row: dict[str, Any] = {
        "job": str(run.path.relative_to(root)) if root is not None and run.path != root else run.path.name,
        "status": status,
        "error": error.get("error") if error else (damage[0] if damage else None),
        "reason": _reason(status, error),
        "seed": seed,
    }
    for key, value in params.items():
        if key != "seed":
            row[key] = value
    row["overrides"] = " ".join(overrides)
    row["config_hash"] = manifest.get("config_hash")
    if status == "damaged":
        metrics = {}
    for key, value in metrics.items():
        column = f"metric.{key}" if key in row else key
        row[column] = json.dumps(value) if isinstance(value, (list, dict)) else value
    if status == "complete":  # a condition never violated: an empty first time, no agents
        for condition in VIOLATION_CONDITIONS:
            if condition in OPT_IN_CONDITIONS and metrics.get(OPT_IN_CONDITIONS[condition]) is None:
                continue
            row.setdefault(f"violations.{condition}.first_time", None)
            row.setdefault(f"violations.{condition}.agents", "[]")
    return row


def _reason(status: str, error: dict[str, Any] | None) -> str | None:
    """One word for a job that did not complete (records written before ``reason`` existed: from
    the exception type)."""
    if status == "complete":
        return None
    if status != "failed" or error is None:
        return {"incomplete": "interrupted"}.get(status, status)
    if error.get("reason"):
        return str(error["reason"])
    return "invalid" if error.get("type") == "ConfigError" else "failed"


def collect_rows(directory: Path) -> list[dict[str, Any]]:
    """A row (:func:`job_row`) for each job directory of a sweep directory, in job order."""
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
    """The table's columns: identity and status, the overridden keys, then the metrics, sorted."""
    params = param_columns(rows)
    fixed = set(BASE_COLUMNS) | set(TAIL_COLUMNS) | set(params)
    metrics = sorted(({k for row in rows for k in row} | set(VIOLATION_COLUMNS)) - fixed)
    return [*BASE_COLUMNS, *params, *TAIL_COLUMNS, *metrics]


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float) and not math.isfinite(value):
        return ""
    return value


def csv_text(rows: list[dict[str, Any]]) -> str:
    """``summary.csv``: one line per job, an empty cell for a missing or non-finite value."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns(rows), extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(v) for k, v in row.items()})
    return buffer.getvalue()


def load_table_libraries() -> None:
    """Import, in a background thread while the jobs run (the sweeper calls it at its first
    launch, once the grid is checked), what these tables import at the sweep's end (pyarrow, which
    imports pandas at its first array, in :func:`parquet_bytes`; ``scipy.special`` in the
    intervals): ~0.4 s that would otherwise come
    after the last job, serial. The main thread then finds them imported (or waits on the import
    lock for the one still being imported); a failure here only means the tables import it
    themselves."""
    import threading

    def load() -> None:
        try:
            import pyarrow

            pyarrow.array([0])
            import scipy.special  # noqa: F401
        except Exception:  # pyarrow is an extra; the tables do without it
            pass

    threading.Thread(target=load, name="swarmscene-table-libraries", daemon=True).start()


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
    return sorted(out.values(),
                  key=lambda g: tuple((isinstance(v, str), str(v) if isinstance(v, str) else v or 0) for v in g[0]))


@lru_cache(maxsize=1)
def renamed_metrics() -> frozenset[str]:
    """The old keys of metrics a registered plugin renamed (its ``RENAMED_METRICS``): metrics.json
    and summary.csv keep them for one release, the grouped tables show the new key only."""
    from ..builtins import BUILTIN_PLUGINS
    from ..core.registry import make_plugin_manager

    _, registry = make_plugin_manager(BUILTIN_PLUGINS)
    return frozenset(old for classes in registry.classes.values() for cls in classes.values()
                     for old in getattr(cls, "RENAMED_METRICS", {}))


def metric_names(rows: list[dict[str, Any]]) -> tuple[list[str], list[str]]:
    """(rate metrics: booleans, numeric metrics) over the table's metric columns (a renamed key's
    old name left out)."""
    rates: set[str] = set()
    numbers: set[str] = set()
    fixed = {*BASE_COLUMNS, *TAIL_COLUMNS, *param_columns(rows), *renamed_metrics()}
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
    return ", ".join(f"{k}={v}" for k, v in zip(by, values, strict=True) if v is not None) or "all jobs"


# The outcome of a run, in the overview and the methods table: safety first, then the mission.
SAFETY_CONDITIONS = ("separation", "clearance", "keep_out")
# A group is deterministic when its runs of different seeds agree on all of these to the bit.
OUTCOME_KEYS = ("success", "min_separation", "min_clearance", "duration", "steps", "collisions")


def first_violation_time(row: dict[str, Any]) -> float | None:
    """The first time a safety condition (separation, clearance or, when set, the keep-out
    ellipsoid) was violated, s; None if never."""
    recorded = [row.get(f"violations.{c}.first_time") for c in SAFETY_CONDITIONS]
    times = [t for t in recorded if _is_number(t)]
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


def mean_cell(values: Iterable[float | None], unit: str = "", bounded: bool = False) -> str:
    """``mean [95 % CI]`` of the values (:func:`~swarmscene.sweeps.stats.mean_interval`: the
    percentile bootstrap with ``bounded``), or what stands in for the interval when there is none."""
    x = [float(v) for v in values if v is not None and np.isfinite(v)]
    mean, low, high, n = mean_interval(x, bounded=bounded)
    if n == 0:
        return "n/a"
    if n == 1:
        return f"{_fmt(mean)}{unit} (one run)"
    if _identical(x):
        return f"{_fmt(mean)}{unit} (identical in {n} runs)"
    return f"{_fmt(mean)}{unit} [{_fmt(low)}, {_fmt(high)}]"


def success_cell(done: list[dict[str, Any]]) -> str:
    """The success rate of a group's runs with its Wilson 95 % interval (none when deterministic)."""
    flags = [r["success"] for r in done if isinstance(r.get("success"), bool)]
    if not flags:
        return "n/a"
    rate = sum(flags) / len(flags)
    if deterministic(done):
        return f"{rate:.2f} (deterministic)"
    lo, hi = wilson(sum(flags), len(flags))
    return f"{rate:.2f} [{lo:.2f}, {hi:.2f}]"


def violation_cell(done: list[dict[str, Any]]) -> str:
    """How many of a group's runs violated a safety condition, and the mean first time, s."""
    times = [first_violation_time(r) for r in done]
    hit = [t for t in times if t is not None]
    if not done:
        return "n/a"
    if not hit:
        return f"none in {len(done)}"
    return f"{len(hit)}/{len(done)}: " + mean_cell(hit, " s", bounded=True)


def completion_cell(done: list[dict[str, Any]]) -> str:
    """How many of a group's runs completed the mission, and their mean completion time, s."""
    times = [completion_time(r) for r in done]
    reached = [t for t in times if t is not None]
    if not done:
        return "n/a"
    if not reached:
        return f"not complete in {len(done)}"
    share = "" if len(reached) == len(done) else f"{len(reached)}/{len(done)}: "
    return share + mean_cell(reached, " s", bounded=True)


OVERVIEW = (
    "success rate (95 % CI)", "min separation, m", "min clearance, m", "first safety violation",
    "completion time",
)


def overview_cells(done: list[dict[str, Any]]) -> list[str]:
    """The overview's outcome columns for one group's complete runs (see OVERVIEW)."""
    return [
        success_cell(done),
        mean_cell((r.get("min_separation") for r in done if _is_number(r.get("min_separation"))),
                  bounded=lower_bound("min_separation") is not None),
        mean_cell((r.get("min_clearance") for r in done if _is_number(r.get("min_clearance"))),
                  bounded=lower_bound("min_clearance") is not None),
        violation_cell(done),
        completion_cell(done),
    ]


def markdown(rows: list[dict[str, Any]], title: str) -> str:
    """The short grouped report (see the module docstring)."""
    by = swept_parameters(rows)
    rates, numbers = metric_names(rows)
    statuses = ("complete", "incomplete", "failed", "unfinished", "damaged")
    counts = {s: sum(r["status"] == s for r in rows) for s in statuses}
    seeds = sorted({r.get("seed") for r in rows if r.get("seed") is not None}, key=str)
    grouped = groups(rows, by)
    fixed = [_label(by, values) for values, members in grouped
             if deterministic([r for r in members if r["status"] == "complete"])]
    lines = [
        f"# Sweep summary: {title}",
        "",
        f"{len(rows)} jobs: " + ", ".join(f"{n} {s}" for s, n in counts.items() if n) + ". "
        + (f"Grouped by {', '.join(by)}" if by else "One group")
        + f"; {len(seeds)} seed(s). Means and 95 % confidence intervals over the complete runs of "
        "each group (Student t; the percentile bootstrap for quantities that cannot be negative, "
        "so no interval reaches below zero); rates with 95 % Wilson intervals. The first safety "
        "violation is the earliest time separation, clearance or the keep-out ellipsoid (when set) was "
        "violated, over the runs that "
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
    failures = [r for r in rows if r["status"] in ("failed", "incomplete", "unfinished", "damaged")]
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
            mean, low, high, n = mean_interval(sample, bounded=lower_bound(name) is not None)
            if n:
                if n == 1:
                    ci = "n/a (one run)"
                elif _identical(sample):
                    ci = f"none: identical in all {n} runs"
                else:
                    ci = f"[{_fmt(low)}, {_fmt(high)}]"
                lines.append(f"| {name} | {_fmt(mean)} | {ci} | {n} |")
    return "\n".join(lines) + "\n"


def _is_number(value: Any) -> TypeGuard[float]:
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
    counts = {s: sum(r["status"] == s for r in rows) for s in ("failed", "incomplete", "unfinished", "damaged")}
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
