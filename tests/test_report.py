"""The sweep summary's outcome columns and its honesty about seeds that change nothing, and the
scenario x method table (issue 14): one row per scenario, one column per method, a one-word reason
where a combination could not run."""

from __future__ import annotations

import csv
import io
import os
import subprocess
import sys

import pytest

from swarmscene.sweeps import records, report
from swarmscene.sweeps import tables as sweep

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]


def row(job, scenario, method, seed, *, status="complete", success=True, sep=1.0, clear=None,
        duration=20.0, stop="complete", sep_violation=None, clear_violation=None, reason=None):
    r = {"job": str(job), "status": status, "error": None if status == "complete" else "boom",
         "reason": reason, "seed": seed, "scenario": scenario, "avoidance": method,
         "overrides": f"scenario={scenario} avoidance={method} seed={seed}", "config_hash": None}
    if status == "complete":
        r.update(success=success, min_separation=sep, min_clearance=clear, duration=duration, steps=int(duration * 10),
                 collisions=0, stop_reason=stop)
        if sep_violation is not None:
            r["violations.separation.first_time"] = sep_violation
        if clear_violation is not None:
            r["violations.clearance.first_time"] = clear_violation
    return r


def test_a_group_whose_seeds_change_nothing_shows_no_interval():
    same = [row(i, "a", "cem", i, sep=0.7, duration=24.0) for i in range(3)]
    varied = [row(3 + i, "a", "orca", i, sep=s, duration=d, success=ok)
              for i, (s, d, ok) in enumerate([(0.6, 20.0, True), (0.8, 22.0, True), (0.7, 30.0, False)])]
    assert sweep.deterministic(same) and not sweep.deterministic(varied)
    assert not sweep.deterministic(same[:1])  # one run: no evidence either way
    md = sweep.markdown(same + varied, "t")
    assert "Deterministic (every seed gave the same run, so the seed changes nothing there and no interval is shown): avoidance=cem." in md
    overview = {line.split(" | ")[0]: line for line in md.splitlines() if line.startswith("| cem |") or line.startswith("| orca |")}
    assert overview["| cem"] == (
        "| cem | 3 | 3 | 0 | 1.00 (deterministic) | 0.7 (identical in 3 runs) | n/a | none in 3 | 24 s (identical in 3 runs) |"
    )
    lo, hi = sweep.wilson(2, 3)
    # A separation cannot be negative: its interval is the percentile bootstrap, inside [0.6, 0.8].
    _, low, high, _ = sweep.mean_interval([0.6, 0.8, 0.7], bounded=True)
    assert low == pytest.approx(0.6) and high == pytest.approx(0.8)
    assert overview["| orca"].startswith(
        f"| orca | 3 | 3 | 0 | 0.67 [{lo:.2f}, {hi:.2f}] | 0.7 [{sweep._fmt(low)}, {sweep._fmt(high)}] |"
    )
    section = md.split("## avoidance=cem")[1].split("## ")[0]
    assert "| success (rate) | 1 | none: deterministic | 3 |" in section
    assert "| min_separation | 0.7 | none: identical in all 3 runs | 3 |" in section


def test_first_violation_and_completion_columns():
    runs = [
        row(0, "a", "none", 0, sep_violation=4.0, clear_violation=3.0, stop="duration"),
        row(1, "a", "none", 1, sep_violation=6.0, duration=31.0),
        row(2, "a", "none", 2, duration=25.0),
    ]
    assert [sweep.first_violation_time(r) for r in runs] == [3.0, 6.0, None]  # the earliest condition
    assert [sweep.completion_time(r) for r in runs] == [None, 31.0, 25.0]
    # Times cannot be negative: bootstrap intervals, whose ends are means of the observed values.
    assert sweep.violation_cell(runs) == "2/3: 4.5 s [3, 6]"
    assert sweep.completion_cell(runs) == "2/3: 28 s [25, 31]"
    assert sweep.violation_cell(runs[2:]) == "none in 1"
    assert sweep.completion_cell(runs[:1]) == "not complete in 1"


def test_keep_out_columns_say_whether_a_run_checked_it(tmp_path):
    """Every table has the keep-out column pair (core/monitors.py's conditions); a run that did not
    set safety.keep_out leaves both cells empty, one that held it has no agents, one that broke it
    its first time, which the first safety violation counts."""
    from swarmscene import api

    base = ["clock.duration=0.5", "output.summary=false"]
    for job, extra in enumerate([[], ["safety.keep_out=[0.12,0.12,0.3]"], ["safety.keep_out=[2.0,2.0,0.5]"]]):
        api.run([*base, *extra], output_dir=tmp_path / str(job))
    rows = sweep.collect_rows(tmp_path)
    assert {"violations.keep_out.first_time", "violations.keep_out.agents"} <= set(sweep.columns(rows))
    assert "violations.keep_out.agents" not in rows[0] and rows[0].get("keep_out_conflicts") is None
    assert (rows[1]["violations.keep_out.first_time"], rows[1]["violations.keep_out.agents"]) == (None, "[]")
    assert rows[2]["violations.keep_out.first_time"] == 0.1 and rows[2]["keep_out_conflicts"] > 0
    assert [sweep.first_violation_time(r) for r in rows] == [None, None, 0.1]
    cells = list(csv.DictReader(io.StringIO(sweep.csv_text(rows))))
    assert [c["violations.keep_out.agents"] for c in cells[:2]] == ["", "[]"]


def test_methods_table_cells_and_one_word_reasons():
    rows = [
        row(0, "cem_six_vehicle", "cem", 0, sep=1.36, duration=24.0),
        row(1, "cem_six_vehicle", "cem", 1, sep=1.35, duration=26.0),
        row(2, "cem_six_vehicle", "none", 0, success=False, sep=0.01, stop="duration"),
        row(3, "cem_six_vehicle", "none", 1, status="failed", reason="failed"),
        row(4, "vrb_airshow", "cem", 0, status="failed", reason="needs-leader"),
        row(5, "vrb_airshow", "cem", 1, status="failed", reason="needs-leader"),
        row(6, "vrb_airshow", "none", 0, status="failed", reason="invalid"),
    ]
    table = report.methods_table(rows)
    lines = table.splitlines()
    assert lines[2:] == [
        "| scenario | cem | none |",
        "|---|---|---|",
        "| cem_six_vehicle | 100 % · 1.35 m · 25.0 s | 0 % · 0.01 m · not complete (1 failed) |",
        "| vrb_airshow | needs-leader | invalid |",
    ]
    # a combination absent from the grid is named too, never blank
    assert report.methods_table(rows[:6]).splitlines()[-1] == "| vrb_airshow | needs-leader | not-run |"
    with pytest.raises(ValueError, match="'controller' is not a column"):
        report.methods_table(rows, "controller")


def test_failure_reason_words():
    from swarmscene.core.errors import ConfigError

    class NeedsLeader(RuntimeError):
        reason = "needs-leader"

    assert records.failure_reason(ConfigError(["avoidance.K: must be >= 1 (got 0)"])) == "invalid"
    assert records.failure_reason(FloatingPointError("nan")) == "failed"
    assert records.failure_reason(NeedsLeader("cem needs a leader")) == "needs-leader"


def test_comparing_methods_from_the_command_line(tmp_path):
    """The natural command groups the summary by method, and the report renders the table."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    proc = subprocess.run(
        [*EXE, "-m", "scenario=cem_six_vehicle", "avoidance=cem,potential,none", "seed=0,1", "clock.duration=3.0",
         f"hydra.sweep.dir={tmp_path}/sw"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    sw = tmp_path / "sw"
    with open(sw / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["avoidance"], r["seed"]) for r in rows] == [
        (m, s) for m in ("cem", "potential", "none") for s in ("0", "1")
    ]
    md = (sw / "summary.md").read_text()
    assert "Grouped by avoidance;" in md
    header = "| avoidance | runs | complete | failed | " + " | ".join(sweep.OVERVIEW) + " |"
    assert header in md
    for method in ("cem", "potential", "none"):
        assert f"\n| {method} | 2 | 2 | 0 | " in md
    assert report.main([str(sw), "--methods"]) == 0
    table = (sw / "methods.md").read_text().splitlines()
    assert table[2] == "| scenario | cem | potential | none |"
    cells = [c.strip() for c in table[4].strip("|").split("|")]
    assert cells[0] == "cem_six_vehicle"
    for method, cell in zip(("cem", "potential", "none"), cells[1:], strict=True):
        group = [r for r in rows if r["avoidance"] == method]
        worst = min(float(r["min_separation"]) for r in group)
        success = sum(r["success"] == "True" for r in group) / 2
        assert cell.startswith(f"{100 * success:.0f} % · {worst:.2f} m · ")


def test_a_key_one_case_does_not_set_is_left_out_of_its_label():
    a = [row(i, "outdoor_square", "cem", i, sep=1.3 + i / 10) for i in range(2)]
    b = [row(2 + i, "indoor_corridor", "cem", i, sep=0.3 + i / 10) for i in range(2)]
    for r in b:
        r["environment"] = "indoor_corridor_w070"
        r["overrides"] += " environment=indoor_corridor_w070"
    md = sweep.markdown(a + b, "t")
    assert "## scenario=outdoor_square" in md and "## scenario=indoor_corridor, environment=indoor_corridor_w070" in md
    assert "| outdoor_square | - | 2 | 2 | 0 |" in md  # the scenario's own environment: not set by the job
    assert report.methods_table(a + b).splitlines()[2:] == [
        "| scenario / environment | cem |",
        "|---|---|",
        "| outdoor_square | 100 % · 1.30 m · 20.0 s |",
        "| indoor_corridor / indoor_corridor_w070 | 100 % · 0.30 m · 20.0 s |",
    ]


def _short_runs(sweep_dir, count):
    import shutil

    from swarmscene import api

    api.run(["clock.duration=0.5", "output.summary=false"], output_dir=sweep_dir / "0")
    for k in range(1, count):
        shutil.copytree(sweep_dir / "0", sweep_dir / str(k))


def test_the_console_names_each_damaged_job_and_what_the_pictures_skipped(tmp_path, capsys):
    """The table marks a damaged job: the console names it too, with the file. --run-plots says
    which runs it skipped and why, and counts what it drew, never "written" for what it could not read."""
    sweep_dir = tmp_path / "sw"
    _short_runs(sweep_dir, 3)
    (sweep_dir / "1" / "metrics.json").write_text("{not json")
    (sweep_dir / "2" / "trajectory.npz").unlink()
    assert report.main([str(sweep_dir), "--run-plots"]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert lines[0].startswith(f"swarmscene-report: job 1 damaged, left out of the statistics: {sweep_dir / '1' / 'metrics.json'}: ")
    assert f"swarmscene-report: {sweep_dir / '2'}: no trajectory.npz (skipped)" in lines
    assert any(line.startswith(f"swarmscene-report: {sweep_dir / '1' / 'metrics.json'}") and line.endswith("(skipped)")
               for line in lines), lines
    assert out.splitlines()[-1] == "swarmscene-report: run pictures written for 1 of 3 runs (2 skipped, named above)"
    assert (sweep_dir / "0" / "trajectory.png").is_file() or any((sweep_dir / "0").glob("*.png"))
    assert not any((sweep_dir / "1").glob("*.png"))


def test_run_pictures_that_draw_nothing_exit_non_zero(tmp_path, capsys):
    sweep_dir = tmp_path / "sw"
    _short_runs(sweep_dir, 1)
    (sweep_dir / "0" / "trajectory.npz").write_bytes(b"PK\x03\x04 truncated")
    assert report.main([str(sweep_dir), "--run-plots"]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == "swarmscene-report: run pictures written for 0 of 1 runs (1 skipped, named above)"


def test_plotting_against_a_parameter_with_one_value_is_refused_naming_those_that_vary():
    """docs/sweeps.md's corridor example plotted `--against environment`, which the preset holds at
    one value while it sweeps environment.width: one category and five overlapping lines."""
    rows = [{"job": str(k), "status": "complete", "seed": k % 2, "environment": "indoor_corridor",
             "environment.width": [0.5, 0.6, 0.7][k // 2], "indoor.success": bool(k % 3),
             "overrides": f"environment=indoor_corridor environment.width={[0.5, 0.6, 0.7][k // 2]} seed={k % 2}"}
            for k in range(6)]
    with pytest.raises(ValueError, match=r"^'environment' takes one value in this sweep \(indoor_corridor\): "
                                         r"plot against one that varies \(environment.width\)$"):
        report.metric_against(rows, "indoor.success", "environment")
    data = report.metric_against(rows, "indoor.success", "environment.width")
    assert data["x"] == [0.5, 0.6, 0.7] and list(data["lines"]) == ["indoor.success"]
