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

from .core.outputs import atomic_write_bytes, atomic_write_json, config_hash, package_versions

ERROR_FILE = "error.json"
MANIFEST = "manifest.json"
BASE_COLUMNS = ("job", "status", "error", "seed")
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


# -- statistics ---------------------------------------------------------------------------------
def mean_ci(values: Iterable[float], level: float = 0.95) -> tuple[float, float, int]:
    """Mean and half-width of its Student-t confidence interval (NaN half-width for n < 2)."""
    # The t quantile from scipy.special: importing scipy.stats costs ~0.5 s, serial at a sweep's end.
    from scipy.special import stdtrit

    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    n = len(x)
    if n == 0:
        return math.nan, math.nan, 0
    if n == 1:
        return float(x[0]), math.nan, 1
    half = stdtrit(n - 1, 0.5 + level / 2) * x.std(ddof=1) / math.sqrt(n)
    return float(x.mean()), float(half), n


def wilson(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate (well behaved at 0 and 1, unlike Wald)."""
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    lower = 0.0 if successes == 0 else max(0.0, centre - half)  # exact at the ends (no rounding)
    upper = 1.0 if successes == n else min(1.0, centre + half)
    return lower, upper


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
    return ", ".join(f"{k}={v}" for k, v in zip(by, values)) if by else "all jobs"


def markdown(rows: list[dict[str, Any]], title: str) -> str:
    """The short grouped report (see the module docstring)."""
    by = swept_parameters(rows)
    rates, numbers = metric_names(rows)
    counts = {s: sum(r["status"] == s for r in rows) for s in ("complete", "incomplete", "failed", "unfinished")}
    seeds = sorted({r.get("seed") for r in rows if r.get("seed") is not None})
    lines = [
        f"# Sweep summary: {title}",
        "",
        f"{len(rows)} jobs: " + ", ".join(f"{n} {s}" for s, n in counts.items() if n) + ". "
        + (f"Grouped by {', '.join(by)}" if by else "One group")
        + f"; {len(seeds)} seed(s). Means and 95 % confidence intervals (Student t) over "
        "the complete runs of each group; rates with 95 % Wilson intervals.",
        "",
        "## Overview",
        "",
        "| " + " | ".join([*by, "runs", "complete", "failed", "success rate (95 % CI)"]) + " |",
        "|" + "---|" * (len(by) + 4),
    ]
    grouped = groups(rows, by)
    for values, members in grouped:
        done = [r for r in members if r["status"] == "complete"]
        failed = sum(r["status"] == "failed" for r in members)
        lines.append("| " + " | ".join([*map(str, values), str(len(members)), str(len(done)), str(failed), _rate_text(done, "success")]) + " |")
    failures = [r for r in rows if r["status"] in ("failed", "incomplete", "unfinished")]
    if failures:
        lines += ["", "## Jobs that did not complete", "", "| job | status | overrides | error |", "|---|---|---|---|"]
        for r in failures:
            error = (r.get("error") or "").replace("|", "\\|")
            lines.append(f"| {r['job']} | {r['status']} | {r.get('overrides', '')} | {error} |")
    for values, members in grouped:
        done = [r for r in members if r["status"] == "complete"]
        lines += ["", f"## {_label(by, values)}", "", "| metric | mean | 95 % CI | n |", "|---|---|---|---|"]
        for name in rates:
            flags = [r[name] for r in done if isinstance(r.get(name), bool)]
            if flags:
                lo, hi = wilson(sum(flags), len(flags))
                lines.append(f"| {name} (rate) | {_fmt(sum(flags) / len(flags))} | [{_fmt(lo)}, {_fmt(hi)}] | {len(flags)} |")
        for name in numbers:
            mean, half, n = mean_ci(r.get(name) for r in done if _is_number(r.get(name)))
            if n:
                ci = f"[{_fmt(mean - half)}, {_fmt(mean + half)}]" if np.isfinite(half) else "n/a (one run)"
                lines.append(f"| {name} | {_fmt(mean)} | {ci} | {n} |")
    return "\n".join(lines) + "\n"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _rate_text(done: list[dict[str, Any]], name: str) -> str:
    flags = [r[name] for r in done if isinstance(r.get(name), bool)]
    if not flags:
        return "n/a"
    lo, hi = wilson(sum(flags), len(flags))
    return f"{sum(flags) / len(flags):.2f} [{lo:.2f}, {hi:.2f}]"


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


# -- the Hydra callback -------------------------------------------------------------------------
try:
    from hydra.experimental.callback import Callback as _Callback
except ImportError:  # pragma: no cover - hydra-core is a dependency
    _Callback = object


class SweepSummary(_Callback):
    """Hydra callback: when a multirun ends, write the sweep directory's tables."""

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        try:
            rows = write_summary(sweep_dir)
        except Exception as exc:  # a table problem must not hide the jobs' own outputs
            print(f"swarmscene: could not write the sweep summary: {exc}", file=sys.stderr)
            return
        failed = sum(r["status"] == "failed" for r in rows)
        note = f", {failed} failed" if failed else ""
        print(f"swarmscene: {len(rows)} jobs{note}; summary in {sweep_dir / 'summary.md'}", file=sys.stderr)
