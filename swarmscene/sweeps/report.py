"""``swarmscene-report``: rebuild a sweep's (or a run's) tables, plot a metric against a parameter.

    swarmscene-report multirun/cem_k                                   # summary.csv/.parquet/.md
    swarmscene-report multirun/indoor_corridor --plot indoor.success --against environment.width
    swarmscene-report outputs/default/2026-...  --run-plots --rerun    # a run's pictures, replay
    swarmscene-report multirun/methods --methods                       # scenario x method table

``--plot METRIC --against PARAM`` writes ``METRIC_vs_PARAM.png`` into the directory: the mean of
the metric over each value of the parameter (complete runs only) with its 95 % confidence interval
as error bars (Student t for numbers, the percentile bootstrap for quantities that cannot be
negative, Wilson for booleans, which are shown as rates), one line per combination of the other
swept parameters. The seed is never a line: runs of all seeds are pooled.

``--methods`` writes ``methods.md``: one row per scenario (the combination of the swept parameters
other than the method and the seed), one column per method (``--method-key``, default
``avoidance``), each cell the success rate, the worst minimum separation and the median completion
time (:func:`methods_table`); a combination that could not run shows why in one word.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path
from typing import Any

import numpy as np

from . import tables
from .records import job_dirs
from .stats import lower_bound, mean_interval, wilson


def metric_against(rows: list[dict[str, Any]], metric: str, param: str) -> dict[str, Any]:
    """The data of a metric-versus-parameter plot.

    Returns ``{"x": [values], "lines": {label: (mean, lower, upper)}, "rate": bool}``: x sorted, one
    line per combination of the other swept parameters, NaN where a value has no complete run.
    """
    if not rows:
        raise ValueError("no jobs found")
    if param not in {k for row in rows for k in row}:
        raise ValueError(f"{param!r} is not a column (parameters: {', '.join(tables.param_columns(rows)) or 'none'})")
    done = [r for r in rows if r["status"] == "complete"]
    values = [r.get(metric) for r in done if r.get(metric) is not None]
    if not values:
        raise ValueError(f"{metric!r}: no complete run has this metric")
    rate = all(isinstance(v, bool) for v in values)
    bounded = lower_bound(metric) is not None
    x = sorted({r.get(param) for r in rows}, key=_order)
    others = [k for k in tables.swept_parameters(rows) if k not in (param, "seed")]
    if len(x) == 1 and others:  # one category, the sweep's real axis drawn as overlapping lines
        raise ValueError(f"{param!r} takes one value in this sweep ({x[0]}): plot against one that varies "
                         f"({', '.join(others)})")
    lines: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for key, members in tables.groups(done, others):
        label = ", ".join(f"{k}={v}" for k, v in zip(others, key, strict=True)) or metric  # a value per key
        stats = np.full((3, len(x)), np.nan)
        for j, xv in enumerate(x):
            sample: list[Any] = [r.get(metric) for r in members if r.get(param) == xv and r.get(metric) is not None]
            if not sample:
                continue
            if rate:
                lo, hi = wilson(sum(sample), len(sample))
                stats[:, j] = (sum(sample) / len(sample), lo, hi)
            else:
                mean, low, high, _ = mean_interval([float(v) for v in sample], bounded=bounded)
                if not np.isfinite(low):  # one run: no interval
                    low = high = mean
                stats[:, j] = (mean, low, high)
        lines[label] = (stats[0], stats[1], stats[2])
    return {"x": x, "lines": lines, "rate": rate}


def _order(value: Any) -> tuple[int, Any]:
    """Numbers first (by value), then text, then missing values."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (0, value)
    return (1, str(value)) if value is not None else (2, "")


def plot_metric(rows: list[dict[str, Any]], metric: str, param: str, title: str = "") -> Any:
    """A matplotlib Figure of :func:`metric_against` (error bars: 95 % CI)."""
    from matplotlib.figure import Figure

    data = metric_against(rows, metric, param)
    x = data["x"]
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x)
    pos = np.asarray(x, dtype=float) if numeric else np.arange(len(x), dtype=float)
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    for label, (mean, lo, hi) in data["lines"].items():
        yerr = np.clip([mean - lo, hi - mean], 0.0, None)  # rounding may put a bound a hair inside
        ax.errorbar(pos, mean, yerr=yerr, marker="o", capsize=3, label=label)
    if not numeric:
        ax.set_xticks(pos, [str(v) for v in x], rotation=20, ha="right")
    ax.set_xlabel(param)
    ax.set_ylabel(f"{metric} (rate)" if data["rate"] else metric)
    if data["rate"]:
        ax.set_ylim(-0.05, 1.05)
    ax.set_title(title or f"{metric} against {param} (mean, 95 % CI)")
    if len(data["lines"]) > 1:
        ax.legend(fontsize=8)
    return fig


def methods_table(rows: list[dict[str, Any]], method_key: str = "avoidance") -> str:
    """The scenario x method table (markdown) of a sweep's rows.

    Each cell: success rate over the combination's jobs (a job that failed counts as no success),
    the worst (smallest) minimum separation over its complete runs, and the median completion time
    over the runs that completed the mission; ``(k failed)`` when some of its jobs failed, and
    ``det.`` when every seed gave the same run (the seed changes nothing there). A combination with
    no complete run shows its jobs' one-word reason (``invalid``, ``failed``, a plugin's own word
    such as ``needs-leader``; the most common when they differ) or ``not-run`` when the grid has no
    such job: never a blank.
    """
    if not rows:
        raise ValueError("no jobs found")
    if method_key not in {k for row in rows for k in row}:
        parameters = ", ".join(tables.param_columns(rows)) or "none"
        raise ValueError(f"{method_key!r} is not a column (parameters: {parameters})")
    case_keys = [k for k in tables.swept_parameters(rows) if k != method_key]
    methods = list(dict.fromkeys(r.get(method_key) for r in rows))
    cases: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        cases.setdefault(_case_label(row, case_keys), []).append(row)
    header = " / ".join(case_keys) if case_keys else "scenario"
    lines = [
        f"| {header} | " + " | ".join(str(m) for m in methods) + " |",
        "|---|" + "---|" * len(methods),
    ]
    for label, members in cases.items():
        cells = [_method_cell([r for r in members if r.get(method_key) == m]) for m in methods]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    legend = (
        "Each cell: success rate of the jobs · worst minimum separation over the complete runs, m · "
        "median completion time, s (runs that completed the mission; 'not complete' when none did). "
        "(k failed): jobs of the cell that did not complete; det.: every seed gave the same run. "
        "A word instead: why the combination could not run (its jobs' error records)."
    )
    return legend + "\n\n" + "\n".join(lines) + "\n"


def _case_label(row: dict[str, Any], keys: list[str]) -> str:
    values = [str(row[k]) for k in keys if row.get(k) is not None]
    if values:
        return " / ".join(values)
    return str(row.get("scenario") or "all jobs")


def _method_cell(members: list[dict[str, Any]]) -> str:
    if not members:
        return "not-run"
    done = [r for r in members if r["status"] == "complete"]
    if not done:
        reasons = [r.get("reason") or r["status"] for r in members]
        return max(dict.fromkeys(reasons), key=reasons.count)
    flags = [r.get("success") is True for r in members]
    separations = [float(r["min_separation"]) for r in done if tables._is_number(r.get("min_separation"))]
    times = [t for t in (tables.completion_time(r) for r in done) if t is not None]
    parts = [
        f"{100 * sum(flags) / len(flags):.0f} %",
        f"{min(separations):.2f} m" if separations else "n/a",
        f"{float(np.median(times)):.1f} s" if times else "not complete",
    ]
    text = " · ".join(parts)
    failed = len(members) - len(done)
    if failed:
        text += f" ({failed} failed)"
    if tables.deterministic(done):
        text += " det."
    return text


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in name)


def main(argv: list[str] | None = None) -> int:
    """The ``swarmscene-report`` command (module docstring); returns its exit status."""
    parser = argparse.ArgumentParser(
        prog="swarmscene-report",
        description="Rebuild summary.csv, summary.parquet and summary.md of a sweep or run directory; "
        "plot a metric against a swept parameter.",
    )
    parser.add_argument("directory", type=Path, help="a sweep directory (multirun/...) or a run directory")
    parser.add_argument("--plot", metavar="METRIC", help="metric to plot, e.g. success or indoor.success")
    parser.add_argument("--against", metavar="PARAM", help="swept parameter for the x axis, e.g. environment")
    parser.add_argument("--out", type=Path, help="where to write the plot (default: DIR/METRIC_vs_PARAM.png)")
    parser.add_argument("--run-plots", action="store_true", help="redraw each run's pictures (plots extra)")
    parser.add_argument("--animation", action="store_true", help="with --run-plots: also the animation")
    parser.add_argument("--rerun", action="store_true", help="write each run's replay.rrd (rerun extra)")
    parser.add_argument("--methods", action="store_true", help="write methods.md: the scenario x method table")
    parser.add_argument("--method-key", default="avoidance", metavar="PARAM",
                        help="the swept parameter that names the method (default: avoidance)")
    args = parser.parse_args(argv)
    if bool(args.plot) != bool(args.against):
        parser.error("--plot and --against go together")
    directory: Path = args.directory
    if directory.is_symlink():  # its summary files would land wherever the link points
        parser.error(f"{directory}: a symbolic link (refused: give the directory itself)")
    if not directory.is_dir():
        parser.error(f"{directory}: not a directory")
    rows = tables.write_summary(directory)
    if not rows:
        print(f"swarmscene-report: {directory}: no run directories found", file=sys.stderr)
        return 1
    print(f"swarmscene-report: {len(rows)} jobs -> {directory / 'summary.csv'}, {directory / 'summary.md'}")
    for row in rows:  # the table marks them; the console names them, with the file and its problem
        if row["status"] == "damaged":
            print(f"swarmscene-report: job {row['job']} damaged, left out of the statistics: {row['error']}",
                  file=sys.stderr)
    if args.plot:
        try:
            title = f"{directory.name}: {args.plot} against {args.against}"
            fig = plot_metric(rows, args.plot, args.against, title=title)
        except ValueError as exc:
            print(f"swarmscene-report: {exc}", file=sys.stderr)
            return 2
        out = args.out or directory / f"{_safe(args.plot)}_vs_{_safe(args.against)}.png"
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=110)
        from ..runs.outputs import atomic_write_bytes

        atomic_write_bytes(out, buffer.getvalue())
        print(f"swarmscene-report: plot -> {out}")
    if args.methods:
        try:
            table = methods_table(rows, args.method_key)
        except ValueError as exc:
            print(f"swarmscene-report: {exc}", file=sys.stderr)
            return 2
        from ..runs.outputs import atomic_write_bytes

        atomic_write_bytes(directory / "methods.md", table.encode())
        print(table, end="")
        print(f"swarmscene-report: methods table -> {directory / 'methods.md'}")
    if args.run_plots or args.rerun:
        return _redraw_runs(directory, args.run_plots, args.animation, args.rerun)
    return 0


def _redraw_runs(directory: Path, plots: bool, animation: bool, rerun: bool) -> int:
    """Each run's pictures (and replay): every run skipped is named with why, and the last line
    counts what was made; status 1 when nothing was (every run skipped, or none to draw)."""
    from ..runs.rundir import RunFileError

    made, skipped = 0, 0
    runs = job_dirs(directory)
    for run_dir in runs:
        if not (run_dir / "trajectory.npz").is_file():
            print(f"swarmscene-report: {run_dir}: no trajectory.npz (skipped)", file=sys.stderr)
            skipped += 1
            continue
        try:
            if plots:
                from ..views.plots import write_run_plots

                write_run_plots(run_dir, plots=True, animation=animation)
            if rerun:
                from ..views.replay import export_rerun

                export_rerun(run_dir)
        except RunFileError as exc:  # a damaged run: named, skipped, the others drawn
            print(f"swarmscene-report: {exc} (skipped)", file=sys.stderr)
            skipped += 1
            continue
        made += 1
    what = " and ".join(w for w, asked in (("pictures", plots), ("replays", rerun)) if asked)
    line = f"swarmscene-report: run {what} written for {made} of {len(runs)} runs" + (
        f" ({skipped} skipped, named above)" if skipped else "")
    print(line, file=sys.stdout if made else sys.stderr)
    return 0 if made else 1


def entry() -> None:
    """Console script ``swarmscene-report``."""
    sys.exit(main())


if __name__ == "__main__":
    entry()
