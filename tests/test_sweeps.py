"""Sweeps: failed jobs recorded and the rest run, resume by config hash, tidy tables with means and
confidence intervals, identical metrics whichever launcher ran them (basic, joblib, Ray on a local
head), the report command, and Ctrl-C leaving outputs marked incomplete."""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from swarmscene import cli, report, sweep

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
# Wall-clock figures differ between any two runs; everything else must match exactly.
TIMING = {"wall_time", "realtime_factor", "step_ms_median"}
FAST = ["+sweep=fast", "clock.duration=4.0"]


def swarmscene(*args: str, cwd: Path, env: dict | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    full_env = {**os.environ, **(env or {})}
    full_env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run([*EXE, *args], cwd=cwd, capture_output=True, text=True, env=full_env, timeout=timeout)


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def comparable(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in row.items() if k not in TIMING} for row in rows]


@pytest.fixture(scope="module")
def basic_sweep(tmp_path_factory) -> Path:
    """The fast preset (2 speeds x 2 seeds) with the basic launcher."""
    root = tmp_path_factory.mktemp("basic")
    proc = swarmscene(*FAST, f"hydra.sweep.dir={root}/sweep", cwd=root)
    assert proc.returncode == 0, proc.stderr
    return root / "sweep"


# -- statistics ---------------------------------------------------------------------------------
def test_mean_ci_is_student_t():
    mean, half, n = sweep.mean_ci([1.0, 2.0, 3.0])
    # t_{0.975, 2} = 4.302653; s = 1; half = t s / sqrt(3)
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    mean, half, n = sweep.mean_ci([5.0])
    assert mean == 5.0 and n == 1 and math.isnan(half)
    assert sweep.mean_ci([None, float("nan"), 2.0, 4.0])[2] == 2


def test_wilson_interval_known_values():
    # 0 of n: the upper bound is z^2 / (n + z^2) in closed form; n of n mirrors it; 5 of 10 is
    # symmetric about 0.5 with the tabulated lower bound 0.2366.
    z2 = 1.959963984540054**2
    assert sweep.wilson(0, 2) == pytest.approx((0.0, z2 / (2 + z2)), abs=1e-12)
    assert sweep.wilson(2, 2) == pytest.approx((2 / (2 + z2), 1.0), abs=1e-12)
    lo, hi = sweep.wilson(5, 10)
    assert lo == pytest.approx(1 - hi) and lo == pytest.approx(0.2366, abs=1e-4)


# -- tables -------------------------------------------------------------------------------------
def test_sweep_writes_tidy_table_and_grouped_summary(basic_sweep):
    rows = read_csv(basic_sweep / "summary.csv")
    assert len(rows) == 4
    assert [r["job"] for r in rows] == ["0", "1", "2", "3"]
    assert {r["status"] for r in rows} == {"complete"}
    assert {(r["formation.speed"], r["seed"]) for r in rows} == {("1.0", "0"), ("1.0", "1"), ("2.0", "0"), ("2.0", "1")}
    for key in ("min_separation", "min_clearance", "collisions", "success", "duration", "overrides", "config_hash", "error"):
        assert key in rows[0]
    assert all(r["duration"] == "4.0" for r in rows)
    import pyarrow.parquet as pq

    table = pq.read_table(basic_sweep / "summary.parquet")
    assert table.num_rows == 4 and "min_separation" in table.column_names
    # summary.md: grouped by the swept parameter other than the seed, mean and 95 % CI per metric
    md = (basic_sweep / "summary.md").read_text()
    assert "Grouped by formation.speed" in md
    assert "## formation.speed=1.0" in md and "## formation.speed=2.0" in md
    assert "| metric | mean | 95 % CI | n |" in md
    assert "| success (rate) |" in md
    group = [r for r in rows if r["formation.speed"] == "2.0"]
    values = [float(r["min_separation"]) for r in group]
    mean, half, _ = sweep.mean_ci(values)
    section = md.split("## formation.speed=2.0")[1]
    line = next(line for line in section.splitlines() if line.startswith("| min_separation |"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert float(cells[1]) == pytest.approx(mean, rel=1e-3)
    lo, hi = (float(v) for v in cells[2].strip("[]").split(","))
    assert (lo, hi) == pytest.approx((mean - half, mean + half), rel=1e-3, abs=1e-6)
    assert cells[3] == "2"


def test_failing_job_is_recorded_and_the_sweep_goes_on(tmp_path):
    # K = 0 is rejected by the CEM schema (a job error), K = 1 and K = 2 run.
    proc = swarmscene(
        "--multirun", "scenario=cem_six_vehicle", "avoidance.K=0,1,2", "clock.duration=3.0",
        f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert "job 0 failed: avoidance.K: must be >= 1 (got 0)" in proc.stderr
    rows = read_csv(tmp_path / "sw" / "summary.csv")
    assert [(r["avoidance.K"], r["status"]) for r in rows] == [("0", "failed"), ("1", "complete"), ("2", "complete")]
    assert rows[0]["error"] == "avoidance.K: must be >= 1 (got 0)"
    assert rows[1]["error"] == "" and rows[1]["min_separation"] != ""
    job = tmp_path / "sw" / "0"
    manifest = json.loads((job / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["complete"] is False
    assert json.loads((job / "error.json").read_text())["type"] == "ConfigError"
    md = (tmp_path / "sw" / "summary.md").read_text()
    assert "## Jobs that did not complete" in md and "avoidance.K: must be >= 1 (got 0)" in md


def test_runtime_exception_in_one_job_does_not_stop_the_others(tmp_path, monkeypatch):
    """A plugin raising mid-run (here: non-finite numbers in seed 1) fails only its own job."""
    from swarmscene.core.simulation import Simulation

    original = Simulation.step

    def step(self):
        if self.config.seed == 1 and self.step_count == 5:
            raise FloatingPointError("non-finite setpoint for agent 3")
        original(self)

    monkeypatch.setattr(Simulation, "step", step)
    monkeypatch.setattr(sys, "argv", ["swarmscene", "--multirun", "seed=0,1,2", "clock.duration=2.0",
                                      f"hydra.sweep.dir={tmp_path}/sw"])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    cli.main()
    rows = read_csv(tmp_path / "sw" / "summary.csv")
    assert [(r["seed"], r["status"]) for r in rows] == [("0", "complete"), ("1", "failed"), ("2", "complete")]
    assert rows[1]["error"] == "FloatingPointError: non-finite setpoint for agent 3"
    error = json.loads((tmp_path / "sw" / "1" / "error.json").read_text())
    assert "Traceback" in error["traceback"] and "FloatingPointError" in error["traceback"]


def test_resume_skips_jobs_complete_for_the_same_config_hash(tmp_path):
    args = ["--multirun", "seed=0,1,2", "clock.duration=2.0", f"hydra.sweep.dir={tmp_path}/sw"]
    assert swarmscene(*args, cwd=tmp_path).returncode == 0
    sw = tmp_path / "sw"
    def stamp(job):  # atomic writes replace the file: a rewritten file has a new inode
        st = (sw / job / "metrics.json").stat()
        return st.st_ino, st.st_mtime_ns

    before = {j: stamp(j) for j in ("0", "1", "2")}
    (sw / "1" / "manifest.json").unlink()  # job 1 was interrupted before its manifest
    proc = swarmscene(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "job 0 already complete (same config hash): skipped" in proc.stderr
    assert "job 2 already complete (same config hash): skipped" in proc.stderr
    assert "job 1 already complete" not in proc.stderr
    after = {j: stamp(j) for j in ("0", "1", "2")}
    assert after["0"] == before["0"] and after["2"] == before["2"]  # untouched
    assert after["1"] != before["1"]  # ran again
    assert {r["status"] for r in read_csv(sw / "summary.csv")} == {"complete"}
    # A different config (here the duration) has a different hash: nothing is skipped.
    proc = swarmscene("--multirun", "seed=0,1,2", "clock.duration=2.5", f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 0 and "skipped" not in proc.stderr
    assert {r["duration"] for r in read_csv(sw / "summary.csv")} == {"2.5"}


# -- launchers ----------------------------------------------------------------------------------
def test_joblib_launcher_gives_identical_metrics(basic_sweep, tmp_path):
    proc = swarmscene(*FAST, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Joblib.Parallel" in proc.stdout + proc.stderr  # it really was the joblib launcher
    assert comparable(read_csv(tmp_path / "sw" / "summary.csv")) == comparable(read_csv(basic_sweep / "summary.csv"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


RAY_ENV = {
    # Keep every Ray service on the loopback interface (Linux defaults to the host's address).
    "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",
    "RAY_USAGE_STATS_ENABLED": "0",
}


@pytest.fixture
def ray_head():
    """A local Ray head on 127.0.0.1, started for this test and stopped after it."""
    ray_bin = Path(sys.executable).with_name("ray")
    port = _free_port()
    temp_dir = tempfile.mkdtemp(prefix="ray")  # short: Ray's socket paths have a length limit
    env = {**os.environ, **RAY_ENV}
    head = subprocess.Popen(
        [str(ray_bin), "start", "--head", "--block", f"--port={port}", "--num-cpus=2", "--include-dashboard=false",
         "--disable-usage-stats", f"--temp-dir={temp_dir}"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            assert head.poll() is None, "ray head exited"
            time.sleep(0.5)
        yield f"127.0.0.1:{port}"
    finally:
        # The head's own process group (ours only): SIGTERM lets `ray start --block` stop its
        # services; whatever of the group is still there after a few seconds is killed.
        os.killpg(head.pid, signal.SIGTERM)
        try:
            head.wait(timeout=8)
        except subprocess.TimeoutExpired:
            pass
        try:
            os.killpg(head.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        head.wait()
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_ray_launcher_on_a_local_head_gives_identical_metrics(basic_sweep, tmp_path, ray_head):
    proc = swarmscene(
        *FAST, "hydra/launcher=ray", f"hydra.launcher.ray.init.address={ray_head}",
        "+hydra.launcher.ray.init.object_store_memory=null", f"hydra.sweep.dir={tmp_path}/sw",
        cwd=tmp_path, env=RAY_ENV,
    )
    assert proc.returncode == 0, proc.stderr
    assert f"Connecting to existing Ray cluster at address: {ray_head}" in proc.stdout + proc.stderr
    assert comparable(read_csv(tmp_path / "sw" / "summary.csv")) == comparable(read_csv(basic_sweep / "summary.csv"))


# -- report -------------------------------------------------------------------------------------
def test_report_rebuilds_tables_and_plots_metric_against_parameter(basic_sweep, tmp_path):
    copy = tmp_path / "sweep"
    shutil.copytree(basic_sweep, copy)
    expected_csv = (copy / "summary.csv").read_text()
    expected_md = (copy / "summary.md").read_text()
    for name in ("summary.csv", "summary.md", "summary.parquet"):
        (copy / name).unlink()
    assert report.main([str(copy), "--plot", "min_separation", "--against", "formation.speed"]) == 0
    assert (copy / "summary.csv").read_text() == expected_csv
    assert (copy / "summary.md").read_text() == expected_md.replace(str(basic_sweep), str(copy))
    assert (copy / "summary.parquet").is_file()
    assert (copy / "min_separation_vs_formation.speed.png").stat().st_size > 1000
    rows = sweep.collect_rows(copy)
    fig = report.plot_metric(rows, "min_separation", "formation.speed")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "formation.speed" and ax.get_ylabel() == "min_separation"
    data = report.metric_against(rows, "success", "formation.speed")
    assert data["x"] == [1.0, 2.0] and data["rate"] is True
    # One run directory works too: a one-row table.
    assert report.main([str(copy / "0")]) == 0
    assert len(read_csv(copy / "0" / "summary.csv")) == 1


def test_report_rejects_unknown_parameter(basic_sweep, tmp_path, capsys):
    copy = tmp_path / "sweep"
    shutil.copytree(basic_sweep, copy)
    assert report.main([str(copy), "--plot", "min_separation", "--against", "nope"]) == 2
    assert "'nope' is not a column" in capsys.readouterr().err


# -- Ctrl-C -------------------------------------------------------------------------------------
def test_ctrl_c_writes_outputs_marked_incomplete_and_exits_130(tmp_path):
    run = tmp_path / "run"
    env = {**os.environ}
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.Popen(
        [*EXE, "clock.duration=20000", "termination.on_complete=false", "output.progress=on", f"hydra.run.dir={run}"],
        cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    # The progress line (shown after 2 s of simulating) proves the run is inside its loop.
    seen: list[str] = []
    reader = threading.Thread(target=lambda: seen.extend(iter(lambda: proc.stderr.read(1), "")), daemon=True)
    reader.start()
    deadline = time.monotonic() + 90
    while "x real time" not in "".join(seen) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)
    assert "x real time" in "".join(seen), "".join(seen)
    proc.send_signal(signal.SIGINT)
    out = proc.stdout.read()
    proc.wait(timeout=60)
    reader.join(timeout=10)
    err = "".join(seen)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted at t =" in err
    assert "stopped by interrupted" in out  # the summary of what ran
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["complete"] is False
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["stop_reason"] == "interrupted" and 0 < metrics["duration"] < 20000
    import numpy as np

    traj = np.load(run / "trajectory.npz")
    assert traj["t"][-1] == pytest.approx(metrics["duration"], abs=0.11)
    assert [r["status"] for r in sweep.collect_rows(run)] == ["incomplete"]


# -- presets ------------------------------------------------------------------------------------
def _grid(preset: str) -> dict[str, list[str]]:
    import yaml

    data = yaml.safe_load((Path(sweep.__file__).parents[1] / "scenarios" / "sweep" / f"{preset}.yaml").read_text())
    assert data["hydra"]["mode"] == "MULTIRUN"
    params = data["hydra"]["sweeper"]["params"]
    out = {}
    for key, value in params.items():
        text = str(value)
        if text.startswith("range("):
            lo, hi = (int(v) for v in text[6:-1].split(","))
            out[key] = [str(v) for v in range(lo, hi)]
        else:
            out[key] = text.split(",")
    return out


@pytest.mark.parametrize(
    ("preset", "expected"),
    [
        ("cem_k", {"scenario": ["cem_six_vehicle"], "avoidance.K": ["1", "2", "5"]}),
        ("failure_time", {"scenario": ["cem_six_vehicle"], "events.0.at": ["1.0", "2.0", "4.0", "8.0"]}),
        ("fast", {"formation.speed": ["1.0", "2.0"], "seed": ["0", "1"]}),
    ],
)
def test_sweep_presets_grid_and_every_job_validates(preset, expected):
    from swarmscene import api

    grid = _grid(preset)
    assert grid == expected
    keys = list(grid)
    import itertools

    for combo in itertools.product(*grid.values()):
        overrides = [f"+sweep={preset}", *(f"{k}={v}" for k, v in zip(keys, combo))]
        api.load(overrides)


def test_indoor_corridor_preset_is_the_thesis_grid():
    grid = _grid("indoor_corridor")
    assert grid["scenario"] == ["indoor_corridor"]
    assert grid["environment"] == [f"indoor_corridor_w0{w}0" for w in (5, 6, 7, 8, 9)]
    assert grid["seed"] == [str(s) for s in range(30)]
    from swarmscene import api

    for env in grid["environment"]:
        api.load(["+sweep=indoor_corridor", "scenario=indoor_corridor", f"environment={env}", "seed=29"])


def test_metric_against_pools_seeds_skips_failures_and_uses_wilson_for_rates():
    def row(job, width, seed, status, success, t):
        return {"job": job, "status": status, "error": None, "seed": seed, "environment": width,
                "overrides": f"environment={width} seed={seed}", "config_hash": None,
                **({} if status == "failed" else {"success": success, "duration": t})}

    rows = [
        row("0", "w070", 0, "complete", True, 10.0), row("1", "w070", 1, "complete", False, 14.0),
        row("2", "w050", 0, "complete", False, 20.0), row("3", "w050", 1, "failed", None, None),
    ]
    data = report.metric_against(rows, "success", "environment")
    assert data["x"] == ["w050", "w070"] and data["rate"] is True
    ((mean, lo, hi),) = data["lines"].values()
    assert list(mean) == [0.0, 0.5]  # the failed job counts in neither numerator nor denominator
    assert (lo[1], hi[1]) == pytest.approx(sweep.wilson(1, 2))
    numbers = report.metric_against(rows, "duration", "environment")
    ((mean, lo, hi),) = numbers["lines"].values()
    assert list(mean) == [20.0, 12.0] and hi[1] - mean[1] == pytest.approx(sweep.mean_ci([10.0, 14.0])[1])
    # Rates of exactly 0 and 1 draw (error bars never negative) with the parameter as tick labels.
    rows.append(row("4", "w090", 0, "complete", True, 9.0))
    ax = report.plot_metric(rows, "success", "environment").axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["w050", "w070", "w090"]
    assert ax.get_ylabel() == "success (rate)"


def test_summary_callback_is_configured_and_leaves_other_flags_alone(tmp_path):
    proc = swarmscene("--cfg", "hydra", cwd=tmp_path)
    assert proc.returncode == 0 and "_target_: swarmscene.sweep.SweepSummary" in proc.stdout
    proc = swarmscene("avoidance=none", "--cfg", "job", "--resolve", cwd=tmp_path)
    assert proc.returncode == 0 and "name: none" in proc.stdout


# -- up-front validation ------------------------------------------------------------------------
def test_sweeper_composes_one_job_per_distinct_override_up_front():
    from hydra_plugins.swarmscene_sweeper import jobs_to_validate

    batch = [[f"environment={env}", f"seed={seed}", "avoidance.K=2"] for env in ("a", "b", "c") for seed in range(30)]
    assert jobs_to_validate(batch) == [batch[0], batch[30], batch[60]]
    # non-numeric values are each composed once; a numeric value counts as its key only
    batch = [["formation=x", "clock.duration=4.0"], ["formation=x", "clock.duration=8"], ["formation=y", "clock.duration=4.0"]]
    assert jobs_to_validate(batch) == [batch[0], batch[2]]
    assert jobs_to_validate([]) == []


@pytest.mark.parametrize("mode", ["each_value", "all"])
def test_a_bad_override_anywhere_in_the_sweep_fails_before_any_job(tmp_path, mode):
    proc = swarmscene("--multirun", "scenario=indoor_corridor", "environment=indoor_corridor_w070,no_such_map",
                      "seed=0,1", "hydra/sweeper=swarmscene", f"hydra.sweeper.validate={mode}",
                      f"hydra.sweep.dir={tmp_path}/sweep", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1].startswith("swarmscene: environment: unknown option 'no_such_map'")
    assert not any(p.is_dir() for p in (tmp_path / "sweep").iterdir())  # no job ran


def test_an_unknown_validation_mode_is_one_line(tmp_path):
    proc = swarmscene("--multirun", "seed=0,1", "hydra/sweeper=swarmscene", "hydra.sweeper.validate=bogus",
                      f"hydra.sweep.dir={tmp_path}/s", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "swarmscene: hydra.sweeper.validate: must be one of ('each_value', 'all') (got 'bogus')"
    ]


def _sweeper_choice(overrides: list[str]) -> str:
    from hydra import compose, initialize_config_module

    from swarmscene.searchpath import register_search_path

    register_search_path()
    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"):
        cfg = compose("config", overrides=overrides, return_hydra_config=True)
    return cfg.hydra.runtime.choices["hydra/sweeper"]


@pytest.mark.parametrize("preset", ["cem_k", "failure_time", "fast", "indoor_corridor"])
def test_grid_presets_use_swarmscenes_sweeper(preset):
    assert _sweeper_choice([f"+sweep={preset}"]) == "swarmscene"


def test_the_tuning_preset_keeps_its_optuna_sweeper():
    """Nothing may pin the sweeper above the presets: Hydra keeps the first override of a group."""
    from hydra.errors import MissingConfigException

    try:
        choice = _sweeper_choice(["+sweep=tune_indoor"])
    except MissingConfigException as exc:  # the optuna extra is not installed here
        assert "hydra/sweeper/optuna" in str(exc)
    else:
        assert choice == "optuna"
