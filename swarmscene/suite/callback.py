"""The Hydra callback of ``+sweep=suite_v1`` (``hydra.callbacks.swarmscene_suite``): when the
sweep ends, its runs are scored against their tasks and the results written to
``<sweep dir>/suite/`` (:mod:`.results`), beside the shipped reference results of the methods
the sweep did not run, so a new method appears next to the built-ins."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback


def score_and_write(sweep_dir: Path, version: str, reference: bool, aggregate_reps: int | None = None) -> str:
    """Score ``sweep_dir``, write ``<sweep_dir>/suite/``; the line that says what was written."""
    from . import stats
    from .results import with_reference, write_results
    from .score import score_sweep

    stats.require_rliable()
    sweep_dir = Path(sweep_dir)
    if sweep_dir.is_symlink():
        raise ValueError(f"{sweep_dir}: a symbolic link (give the sweep directory itself)")
    if not sweep_dir.is_dir():
        raise ValueError(f"{sweep_dir}: not a sweep directory")
    scored, unscored = score_sweep(sweep_dir)
    if not scored and not unscored:
        raise ValueError(f"{sweep_dir}: no run in it to score (is it the sweep's directory?)")
    rows = [s.row() for s in scored if s.version == version]
    mine = sorted({r["method"] for r in rows})
    if reference:
        rows = with_reference(rows, version)
    if not rows:
        raise ValueError(f"{sweep_dir}: no run of a {version} task to score ({len(unscored)} unscored)")
    summary = stats.summarize(rows, aggregate_reps=aggregate_reps or stats.AGGREGATE_REPS)
    out = sweep_dir / "suite"
    if out.is_symlink() or (out.exists() and not out.is_dir()):  # the results land inside the sweep, never elsewhere
        raise ValueError(f"{out}: not a directory of the sweep (a link or a file is refused: remove it)")
    write_results(out, rows, [u.__dict__ for u in unscored], version, summary)
    shown = sorted({r["method"] for r in rows})
    extra = f" (reference: {', '.join(m for m in shown if m not in mine)})" if set(shown) - set(mine) else ""
    return (f"swarmscene-bench {version}: {len(scored)} runs scored of {', '.join(mine) or 'no method'}{extra}, "
            f"{len(unscored)} not scored; leaderboard in {out / 'leaderboard.md'}")


class SuiteResults(Callback):
    """Score a suite sweep when it ends (docs/suite.md).

    Args:
        version: the suite version whose tasks are scored (v1).
        reference: show the shipped reference results of the methods this sweep did not run.
    """

    def __init__(self, version: str = "v1", reference: bool = True) -> None:
        self.version = version
        self.reference = bool(reference)

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        """Score the sweep directory and write its results; a problem is one line, never a traceback
        (the runs' own outputs stay)."""
        sweep_dir = Path(config.hydra.sweep.dir)
        try:
            line = score_and_write(sweep_dir, self.version, self.reference)
        except Exception as exc:
            print(f"swarmscene: could not score the suite sweep {sweep_dir}: {exc}", file=sys.stderr)
            return
        print(f"swarmscene: {line}", file=sys.stderr)
