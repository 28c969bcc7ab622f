"""The files a scored sweep leaves, and the reference results shipped with the package.

In ``<sweep dir>/suite/`` (:func:`write_results`):

* ``scores.csv``: one row per scored run (suite, version, task, family, method, seed, raw score,
  normalised score, passed, success, run directory);
* ``unscored.csv``: the runs that were not scored, with why;
* ``marl_eval.json``: the per-run JSON that marl-eval and rliable pipelines read
  (``{env: {task: {method: {"run_<seed>": {"step_0": {...}, "absolute_metrics": {...}}}}}}``, the
  environment named ``swarmscene-bench-<version>``; metrics ``normalised_score``, ``score`` and
  ``passed``, each a one-element list);
* ``results.json``: the suite, version and frozen hash, the command, and every statistic of
  :mod:`.stats`;
* ``leaderboard.md``: the tables (:mod:`.page`).

The reference results of the built-in methods (``reference_<version>.csv`` beside this module) are
the ``scores.csv`` of ``swarmscene --multirun +sweep=suite_v1``; a sweep of other methods is shown
beside them (:func:`with_reference`).
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from importlib.resources import files
from pathlib import Path
from typing import Any

from ..runs.outputs import atomic_write_bytes, atomic_write_json, run_command
from .definition import SUITE, frozen

COLUMNS = ("suite", "version", "task", "family", "method", "seed", "raw", "normalised", "passed", "success", "run")
"""The columns of ``scores.csv``."""


def rows_to_csv(rows: Sequence[dict[str, Any]], columns: Sequence[str] = COLUMNS) -> bytes:
    """The rows as CSV text (header first), in the order given."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: row.get(k) for k in columns})
    return out.getvalue().encode()


def read_scores(text: str) -> list[dict[str, Any]]:
    """``scores.csv`` back into rows with their types (seed int, scores float, flags bool)."""
    rows = []
    for row in csv.DictReader(io.StringIO(text)):
        rows.append({**row, "seed": int(row["seed"]), "raw": float(row["raw"]),
                     "normalised": float(row["normalised"]), "passed": row["passed"] == "True",
                     "success": row["success"] == "True"})
    return rows


def reference_rows(version: str) -> list[dict[str, Any]]:
    """The shipped reference scores of ``version`` (empty when none is shipped)."""
    path = files(__package__).joinpath(f"reference_{version}.csv")
    return read_scores(path.read_text()) if path.is_file() else []


def with_reference(rows: Sequence[dict[str, Any]], version: str) -> list[dict[str, Any]]:
    """``rows`` with the reference rows of every method they do not hold (a method scored in this
    sweep replaces its reference rows)."""
    mine = {r["method"] for r in rows}
    return [*rows, *(r for r in reference_rows(version) if r["method"] not in mine)]


def marl_eval(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """marl-eval's nested JSON of the rows (see the module docstring)."""
    out: dict[str, Any] = {}
    for r in sorted(rows, key=lambda r: (r["version"], r["task"], r["method"], r["seed"])):
        env = out.setdefault(f"{SUITE}-{r['version']}", {})
        runs = env.setdefault(r["task"], {}).setdefault(r["method"], {})
        values = {"normalised_score": [r["normalised"]], "score": [r["raw"]], "passed": [float(r["passed"])]}
        runs[f"run_{r['seed']}"] = {"step_0": {"step_count": 0, **values}, "absolute_metrics": values}
    return out


def write_results(out_dir: Path, rows: Sequence[dict[str, Any]], unscored: Sequence[dict[str, Any]],
                  version: str, summary: dict[str, Any]) -> None:
    """Write the files of the module docstring into ``out_dir`` (atomically, each)."""
    from .page import leaderboard_markdown

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    record = frozen(version)
    atomic_write_bytes(out_dir / "scores.csv", rows_to_csv(rows))
    atomic_write_bytes(out_dir / "unscored.csv", rows_to_csv(unscored, ("run", "reason")))
    atomic_write_json(out_dir / "marl_eval.json", marl_eval(rows))
    results = {"suite": SUITE, "version": version, "sha256": record["sha256"], "command": run_command()["command"],
               **summary}
    atomic_write_json(out_dir / "results.json", results)
    atomic_write_bytes(out_dir / "leaderboard.md", leaderboard_markdown(results, record).encode())


def dumps(data: Any) -> str:
    """JSON as the results files write it."""
    return json.dumps(data, indent=1, sort_keys=True)
