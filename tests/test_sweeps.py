"""Sweeps: one grid per sweep directory, every distinct override validated before any job, failed
jobs recorded and the rest run, a non-zero exit status when jobs failed, resume by config hash,
tidy tables with means and confidence intervals (none where the seed changes nothing), identical
metrics whichever launcher ran them (basic, joblib, Ray on a local head, whatever an earlier Ray
run left in the home directory), the report command, and Ctrl-C leaving outputs marked incomplete."""

from __future__ import annotations

import csv
import json
import math
import os
import re
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

from swarmscene import cli
from swarmscene.sweeps import job as job_module
from swarmscene.sweeps import records, report, stats, tables

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
# Wall-clock figures differ between any two runs; everything else must match exactly.
TIMING = {"wall_time", "realtime_factor", "step_ms_median"}
FAST = ["+sweep=fast", "clock.duration=4.0"]


def swarmscene(*args: str, cwd: Path, env: dict | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    """The command line in a subprocess; ``env``: the complete environment (default: this one's)."""
    full_env = dict(os.environ if env is None else env)
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
    mean, half, n = stats.mean_ci([1.0, 2.0, 3.0])
    # t_{0.975, 2} = 4.302653; s = 1; half = t s / sqrt(3)
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    mean, half, n = stats.mean_ci([5.0])
    assert mean == 5.0 and n == 1 and math.isnan(half)
    assert stats.mean_ci([None, float("nan"), 2.0, 4.0])[2] == 2


def test_wilson_interval_known_values():
    # 0 of n: the upper bound is z^2 / (n + z^2) in closed form; n of n mirrors it; 5 of 10 is
    # symmetric about 0.5 with the tabulated lower bound 0.2366.
    z2 = 1.959963984540054**2
    assert stats.wilson(0, 2) == pytest.approx((0.0, z2 / (2 + z2)), abs=1e-12)
    assert stats.wilson(2, 2) == pytest.approx((2 / (2 + z2), 1.0), abs=1e-12)
    lo, hi = stats.wilson(5, 10)
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
    # The default scenario has no randomness: both seeds give the same run, and the summary says so
    # instead of presenting a zero-width interval.
    group = [r for r in rows if r["formation.speed"] == "2.0"]
    assert group[0]["min_separation"] == group[1]["min_separation"]
    assert "Deterministic (every seed gave the same run" in md
    section = md.split("## formation.speed=2.0")[1]
    line = next(line for line in section.splitlines() if line.startswith("| min_separation |"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert float(cells[1]) == pytest.approx(float(group[0]["min_separation"]), rel=1e-3)
    assert cells[2:] == ["none: identical in all 2 runs", "2"]
    overview = md.split("## Overview")[1].split("\n## ")[0]
    assert "| 2.0 | 2 | 2 | 0 | 0.00 (deterministic) |" in overview


def test_an_invalid_value_stops_the_sweep_before_any_job_naming_key_and_job(tmp_path):
    """The plain command line (Hydra's basic sweeper) and swarmscene's sweeper check every distinct
    value, numbers included, with the engine's schema before launching anything."""
    for sweeper in ([], ["hydra/sweeper=swarmscene"]):
        proc = swarmscene("--multirun", "scenario=cem_six_vehicle", "avoidance.K=1,0", "seed=0,1", *sweeper,
                          f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.splitlines() == ["swarmscene: job 2 (avoidance.K=0): avoidance.K: must be >= 1 (got 0)"]
        assert not (tmp_path / "sw").exists()  # nothing launched, nothing written


def test_recorded_invalid_jobs_and_failed_jobs_set_the_exit_status(tmp_path):
    # on_invalid=record: K = 0 is rejected by the CEM schema in its job (recorded), K = 1 runs.
    args = ["--multirun", "scenario=cem_six_vehicle", "avoidance.K=0,1", "clock.duration=0.5",
            "hydra/sweeper=swarmscene", "hydra.sweeper.on_invalid=record"]
    proc = swarmscene(*args, f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    err = proc.stderr.splitlines()
    assert err[0] == "swarmscene: job 0 (avoidance.K=0) will fail (on_invalid=record: it is recorded): avoidance.K: must be >= 1 (got 0)"
    assert "swarmscene: job 0 failed: avoidance.K: must be >= 1 (got 0)" in err
    assert err[-1] == f"swarmscene: 1 of 2 jobs failed; summary in {tmp_path}/sw/summary.md"
    rows = read_csv(tmp_path / "sw" / "summary.csv")
    assert [(r["avoidance.K"], r["status"], r["reason"]) for r in rows] == [("0", "failed", "invalid"), ("1", "complete", "")]
    assert rows[0]["error"] == "avoidance.K: must be >= 1 (got 0)"
    assert rows[1]["error"] == "" and rows[1]["min_separation"] != ""
    job = tmp_path / "sw" / "0"
    manifest = json.loads((job / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["complete"] is False
    error = json.loads((job / "error.json").read_text())
    assert (error["type"], error["reason"]) == ("ConfigError", "invalid")
    md = (tmp_path / "sw" / "summary.md").read_text()
    assert "## Jobs that did not complete" in md and "avoidance.K: must be >= 1 (got 0)" in md
    assert tables.sweep_exit_status(tmp_path / "sw") == 1 and tables.sweep_exit_status(tmp_path / "sw", allow_failed=True) == 0
    # Every job failing is a failure too; allow_failed keeps status 0 and still says how many failed.
    proc = swarmscene(*args[:2], "avoidance.K=0", *args[3:], "seed=0,1", f"hydra.sweep.dir={tmp_path}/all", cwd=tmp_path)
    assert proc.returncode == 1 and proc.stderr.splitlines()[-1].startswith("swarmscene: 2 of 2 jobs failed;")
    proc = swarmscene(*args, "++hydra.callbacks.swarmscene_summary.allow_failed=true", f"hydra.sweep.dir={tmp_path}/ok", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines()[-1] == (
        f"swarmscene: 1 of 2 jobs failed (allow_failed: exit status 0); summary in {tmp_path}/ok/summary.md"
    )


def test_runtime_exception_in_one_job_does_not_stop_the_others(tmp_path, monkeypatch):
    """A plugin raising mid-run (here: non-finite numbers in seed 1) fails only its own job, and
    its record names the plugin, its method and the time."""
    from swarmscene.plugins.formation.static_shape import StaticShape

    original = StaticShape.setpoints

    def setpoints(self, world, sensing):
        if self.seed_one and world.t >= 0.5:
            raise FloatingPointError("non-finite setpoint for agent 3")
        return original(self, world, sensing)

    init = StaticShape.__init__

    def remember_seed(self, params, ctx):
        init(self, params, ctx)
        self.seed_one = ctx.rng.bit_generator.seed_seq.entropy == 1  # the run's `seed`

    monkeypatch.setattr(StaticShape, "setpoints", setpoints)
    monkeypatch.setattr(StaticShape, "__init__", remember_seed)
    monkeypatch.setattr(sys, "argv", ["swarmscene", "--multirun", "seed=0,1,2", "clock.duration=2.0",
                                      f"hydra.sweep.dir={tmp_path}/sw"])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    assert exit_info.value.code == 1  # one job failed: the sweep's status says so
    rows = read_csv(tmp_path / "sw" / "summary.csv")
    assert [(r["seed"], r["status"]) for r in rows] == [("0", "complete"), ("1", "failed"), ("2", "complete")]
    assert rows[1]["error"] == ("RunFailed: formation 'static_shape' raised in setpoints at t = 0.5 s: "
                                "FloatingPointError: non-finite setpoint for agent 3")
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
    # A job whose config changed (here its recorded hash, as after an edit of a preset) runs again.
    manifest = json.loads((sw / "2" / "manifest.json").read_text())
    (sw / "2" / "manifest.json").write_text(json.dumps({**manifest, "config_hash": "0" * 64}))
    proc = swarmscene(*args, cwd=tmp_path)
    assert proc.returncode == 0 and "job 2 already complete" not in proc.stderr
    assert stamp("2") != after["2"] and stamp("0") == before["0"]


def test_a_sweep_directory_belongs_to_one_grid(tmp_path):
    """The issue's case: the fast preset (a fixed directory, multirun/sweep_fast) run again with
    another grid is refused with one line and leaves the first sweep as it was; the same grid
    resumes it."""
    fast = ["+sweep=fast", "clock.duration=1.0"]
    assert swarmscene(*fast, cwd=tmp_path).returncode == 0
    sw = tmp_path / "multirun" / "sweep_fast"
    recorded = json.loads((sw / "sweep.json").read_text())
    # the preset's plain values are read as the command line reads them (++: set, default or not)
    assert recorded["jobs"][1] == ["++formation.speed=1.0", "seed=1", "+sweep=fast", "++clock.duration=1.0"]
    files = {p: p.stat().st_mtime_ns for p in sw.rglob("*") if p.is_file()}
    proc = swarmscene(*fast, "seed=0", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        "swarmscene: hydra.sweep.dir: multirun/sweep_fast holds another sweep (seed=0,1; this one: seed=0): "
        "choose another hydra.sweep.dir, or delete that directory to start over"
    ]
    assert {p: p.stat().st_mtime_ns for p in sw.rglob("*") if p.is_file()} == files  # nothing touched
    # A changed fixed override is another sweep too (its jobs would differ).
    proc = swarmscene("+sweep=fast", "clock.duration=2.0", cwd=tmp_path)
    assert proc.returncode == 2 and "(clock.duration=1.0; this one: clock.duration=2.0)" in proc.stderr
    # The same grid resumes, whichever launcher runs it.
    proc = swarmscene(*fast, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("already complete (same config hash): skipped") == 4
    assert [(r["formation.speed"], r["seed"]) for r in read_csv(sw / "summary.csv")] == [
        ("1.0", "0"), ("1.0", "1"), ("2.0", "0"), ("2.0", "1")
    ]


def test_a_directory_without_a_grid_record_is_judged_by_its_jobs(tmp_path):
    """Sweep directories written before sweep.json: the jobs' own overrides decide."""
    from swarmscene.core.errors import ConfigError

    for index, overrides in enumerate(["- seed=0\n", "- seed=1\n"]):
        (tmp_path / str(index) / ".hydra").mkdir(parents=True)
        (tmp_path / str(index) / ".hydra" / "overrides.yaml").write_text(overrides)
    records.check_grid_owner(tmp_path, ["seed=0,1,2"], [["seed=0"], ["seed=1"], ["seed=2"]])  # a superset: resumes
    with pytest.raises(ConfigError) as info:
        records.check_grid_owner(tmp_path, ["avoidance.K=1,2"], [["avoidance.K=1"], ["avoidance.K=2"]])
    assert info.value.lines == [
        f"hydra.sweep.dir: {tmp_path} holds another sweep (job 0: seed=0; this one: job 0: avoidance.K=1): "
        "choose another hydra.sweep.dir, or delete that directory to start over"
    ]
    with pytest.raises(ConfigError, match=r"\(job 1: seed=1; this one: 1 jobs\)"):
        records.check_grid_owner(tmp_path, ["seed=0"], [["seed=0"]])


# -- launchers ----------------------------------------------------------------------------------
PROGRESS = "hydra.callbacks.swarmscene_summary.progress=on"  # the sweep's progress line, not on a terminal


def progress_counts(stderr: str) -> list[str]:
    """The sweep progress lines' 'k/n jobs done, f failed' texts, in order."""
    return re.findall(r"(\d+/\d+ jobs done, \d+ failed)", stderr)


def test_joblib_launcher_gives_identical_metrics(basic_sweep, tmp_path):
    proc = swarmscene(*FAST, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={tmp_path}/sw",
                      PROGRESS, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Joblib.Parallel" in proc.stdout + proc.stderr  # it really was the joblib launcher
    total = len(read_csv(basic_sweep / "summary.csv"))
    assert progress_counts(proc.stderr)[-1] == f"{total}/{total} jobs done, 0 failed"  # jobs ran in workers
    assert comparable(read_csv(tmp_path / "sw" / "summary.csv")) == comparable(read_csv(basic_sweep / "summary.csv"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(params=["token", "disabled"])
def ray_cluster(request, ray_env):
    """A local Ray head on 127.0.0.1 started by the recipe of docs/sweeps.md (``RAY_AUTH_MODE`` set
    explicitly on the head and the client), in a home that an earlier local Ray run has left its
    ``~/.ray/auth_token`` in; yields (address, the client's environment)."""
    env = {**ray_env, "RAY_AUTH_MODE": request.param}
    ray_bin = Path(sys.executable).with_name("ray")
    temp_dir = tempfile.mkdtemp(prefix="ray")  # short: Ray's socket paths have a length limit
    head, port = None, None
    try:
        for _ in range(3):  # a head can lose a race for a port it was given free: try another
            head, port = _start_head(ray_bin, env, temp_dir)
            if head is not None:
                break
        assert head is not None, "no ray head started in 3 attempts"
        yield f"127.0.0.1:{port}", env
    finally:
        if head is not None:
            _stop_head(head)
        shutil.rmtree(temp_dir, ignore_errors=True)


def _start_head(ray_bin: Path, env: dict, temp_dir: str) -> tuple[subprocess.Popen | None, int]:
    """``ray start --head --block`` on a free port; the process once the port answers, or None
    (after stopping what it left) when it exited first."""
    port = _free_port()
    head = subprocess.Popen(
        [str(ray_bin), "start", "--head", "--block", f"--port={port}", "--num-cpus=2", "--include-dashboard=false",
         "--disable-usage-stats", f"--temp-dir={temp_dir}"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return head, port
        if head.poll() is not None:
            _stop_head(head)
            return None, port
        time.sleep(0.5)
    _stop_head(head)
    return None, port


def _stop_head(head: subprocess.Popen) -> None:
    """The head's own process group (ours only): SIGTERM lets `ray start --block` stop its services;
    whatever of the group is still there after a few seconds is killed."""
    for sig, wait in ((signal.SIGTERM, 8), (signal.SIGKILL, None)):
        try:
            os.killpg(head.pid, sig)
        except ProcessLookupError:
            break  # the group is gone already
        try:
            head.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            pass
    head.wait()


def test_ray_launcher_on_a_local_head_gives_identical_metrics(basic_sweep, tmp_path, ray_cluster):
    """The documented cluster recipe, in token mode and with authentication disabled, after an
    earlier local Ray run (its token in the home directory)."""
    address, env = ray_cluster
    proc = swarmscene(
        *FAST, "hydra/launcher=ray", f"hydra.launcher.ray.init.address={address}",
        "+hydra.launcher.ray.init.object_store_memory=null", f"hydra.sweep.dir={tmp_path}/sw", PROGRESS,
        cwd=tmp_path, env=env,
    )
    assert proc.returncode == 0, proc.stderr
    assert f"Connecting to existing Ray cluster at address: {address}" in proc.stdout + proc.stderr
    total = len(read_csv(basic_sweep / "summary.csv"))
    assert progress_counts(proc.stderr)[-1] == f"{total}/{total} jobs done, 0 failed"
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
    rows = tables.collect_rows(copy)
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
    assert [r["status"] for r in tables.collect_rows(run)] == ["incomplete"]


# -- presets ------------------------------------------------------------------------------------
def _grid(preset: str) -> dict[str, list[str]]:
    import yaml

    data = yaml.safe_load((Path(tables.__file__).parents[2] / "scenarios" / "sweep" / f"{preset}.yaml").read_text())
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
        overrides = [f"+sweep={preset}", *(f"{k}={v}" for k, v in zip(keys, combo, strict=True))]
        api.load(overrides)


def test_methods_preset_is_every_paper_scenario_times_every_method():
    """Issue 14's comparison: 5 scenarios (cases: the corridor at 0.7 m) x every built-in avoidance
    method (the learned-policy adapter aside: it is no method of its own) x 10 seeds, every
    scenario x method combination composing and validating."""
    import yaml
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from swarmscene import api
    from swarmscene.sweeps.grid import expand

    data = yaml.safe_load((Path(tables.__file__).parents[2] / "scenarios" / "sweep" / "methods.yaml").read_text())
    sweeper = data["hydra"]["sweeper"]
    assert sweeper["on_invalid"] == "record" and data["hydra"]["callbacks"]["swarmscene_summary"]["allow_failed"] is True
    _, jobs = expand(sweeper["params"], ["+sweep=methods"], OverridesParser.create(), sweeper["cases"])
    methods = ["cem", "orca", "cbf", "potential", "potential_barrier", "apf_navigation", "none"]
    assert set(methods) == set(api.plugins()[1].names("avoidance")) - {"policy"}
    cases = [["scenario=cem_six_vehicle"], ["scenario=outdoor_square"],
             ["scenario=indoor_corridor", "environment=indoor_corridor_w070"], ["scenario=vrb_airshow"], ["scenario=swap"]]
    assert jobs == [[*case, f"avoidance={m}", f"seed={s}", "+sweep=methods"] for case in cases for m in methods for s in range(10)]
    _, registry = api.plugins()
    for case in cases:
        for method in methods:
            scenario = api.load(api.compose(["+sweep=methods", *case, f"avoidance={method}"]), registry)
            assert scenario.data["avoidance"]["name"] == method


def test_indoor_corridor_preset_is_the_thesis_grid():
    grid = _grid("indoor_corridor")
    assert grid["scenario"] == ["indoor_corridor"]
    assert grid["environment"] == ["indoor_corridor"]
    assert grid["environment.width"] == ["0.5", "0.6", "0.7", "0.8", "0.9"]
    assert grid["seed"] == [str(s) for s in range(30)]
    from swarmscene import api

    for width in grid["environment.width"]:  # the generator gives the shipped map of that width
        swept = api.load(["+sweep=indoor_corridor", "scenario=indoor_corridor", "environment=indoor_corridor",
                          f"environment.width={width}", "seed=29"])
        shipped = api.load(["scenario=indoor_corridor", f"environment=indoor_corridor_w0{width[-1]}0", "seed=29"])
        assert [g.wkt for g in swept.obstacles] == [g.wkt for g in shipped.obstacles]
        assert (swept.initial_positions == shipped.initial_positions).all()


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
    assert (lo[1], hi[1]) == pytest.approx(stats.wilson(1, 2))
    numbers = report.metric_against(rows, "duration", "environment")
    ((mean, lo, hi),) = numbers["lines"].values()
    # A duration cannot be negative: the bounded interval (percentile bootstrap), not Student t.
    assert list(mean) == [20.0, 12.0] and (lo[1], hi[1]) == pytest.approx(stats.mean_interval([10.0, 14.0], bounded=True)[1:3])
    assert (lo[1], hi[1]) == pytest.approx((10.0, 14.0))
    # Rates of exactly 0 and 1 draw (error bars never negative) with the parameter as tick labels.
    rows.append(row("4", "w090", 0, "complete", True, 9.0))
    ax = report.plot_metric(rows, "success", "environment").axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["w050", "w070", "w090"]
    assert ax.get_ylabel() == "success (rate)"


def test_summary_callback_is_configured_and_leaves_other_flags_alone(tmp_path):
    proc = swarmscene("--cfg", "hydra", cwd=tmp_path)
    assert proc.returncode == 0 and "_target_: swarmscene.sweeps.callback.SweepSummary" in proc.stdout
    proc = swarmscene("avoidance=none", "--cfg", "job", "--resolve", cwd=tmp_path)
    assert proc.returncode == 0 and "name: none" in proc.stdout


# -- up-front validation ------------------------------------------------------------------------
def test_sweeper_checks_each_distinct_override_once_numbers_included():
    from swarmscene.sweeps.grid import jobs_to_validate

    batch = [[f"environment={env}", f"seed={seed}", "avoidance.K=2"] for env in ("a", "b", "c") for seed in range(30)]
    chosen = jobs_to_validate(batch)
    # the first job with all its overrides, then the first job of every other value (each seed too)
    assert chosen[0] == (0, batch[0])
    assert chosen[1:30] == [(s, [f"seed={s}"]) for s in range(1, 30)]
    assert chosen[30:] == [(30, ["environment=b"]), (60, ["environment=c"])]
    assert jobs_to_validate([]) == []


def test_grid_expansion_matches_hydras_basic_sweeper_and_crosses_cases():
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from swarmscene.sweeps.grid import expand

    parser = OverridesParser.create()
    params = {"avoidance": "cem,none", "seed": "range(0,3)"}
    arguments = ["+sweep=x", "seed=5,6"]  # the command line replaces a params entry in place
    grid, jobs = expand(params, arguments, parser, plain_params=False)
    (hydras,) = BasicSweeper.split_arguments(parser.parse_overrides(["avoidance=cem,none", "seed=range(0,3)", *arguments]), None)
    assert jobs == hydras and grid == ["avoidance=cem,none", "seed=5,6", "+sweep=x"]
    cases = [["scenario=a"], ["scenario=b", "environment=w070"]]
    grid, jobs = expand(params, [], parser, cases=cases, plain_params=False)
    assert len(jobs) == 2 * 2 * 3 and grid[0] == "cases=scenario=a | scenario=b environment=w070"
    assert jobs[6] == ["scenario=b", "environment=w070", "avoidance=cem", "seed=0"]
    # a key of the cases given on the command line replaces the cases
    assert expand(params, ["scenario=c"], parser, cases=cases, plain_params=False)[1][0] == ["avoidance=cem", "seed=0", "scenario=c"]
    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        expand({}, ["++avoidance.K=interval(1,5)"], parser)
    assert info.value.lines == [
        "avoidance.K: a grid sweep takes a list of values (a,b,c / range / choice / glob), not an interval "
        "(got 'avoidance.K=interval(1,5)'): use an optimising sweeper"
    ]


def test_plain_values_are_set_as_hydra_sets_them():
    """The check's shortcut (a plain value set in the composed data) gives the data Hydra's own
    application of the override to a copy of the composed config gives."""
    from hydra import compose, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    from swarmscene.sweeps.grid import JobCheck

    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"):
        master = compose("config", overrides=["+sweep=cem_k"], return_hydra_config=True)
        check = JobCheck(GlobalHydra.instance().config_loader(), master)
        jobs = [
            ["scenario=cem_six_vehicle", "++avoidance.K=5", "seed=17"],
            ["scenario=cem_six_vehicle", "++avoidance.new_key=0.5", "++clock.duration=3"],
            ["scenario=cem_six_vehicle", "avoidance.K=0", "events.0.at=4.0"],
        ]
        fast = [check.data(job) for job in jobs]
        groups = ("scenario=cem_six_vehicle",)
        cfg, plain = check.composed[groups]
        assert plain is not None  # the shortcut was taken
        check.composed[groups] = (cfg, None)  # now the way Hydra does it
        assert [check.data(job) for job in jobs] == fast
    assert (fast[0]["avoidance"]["K"], fast[0]["seed"], fast[1]["clock"]["duration"]) == (5, 17, 3)
    assert fast[2]["events"][0]["at"] == 4.0  # a list element: Hydra's path (the shortcut sets mappings)


@pytest.mark.parametrize("mode", ["each_value", "all"])
def test_a_bad_override_anywhere_in_the_sweep_fails_before_any_job(tmp_path, mode):
    proc = swarmscene("--multirun", "scenario=indoor_corridor", "environment=indoor_corridor_w070,no_such_map",
                      "seed=0,1", "hydra/sweeper=swarmscene", f"hydra.sweeper.validate={mode}",
                      f"hydra.sweep.dir={tmp_path}/sweep", cwd=tmp_path)
    assert proc.returncode == 2
    label = "job 2 (environment=no_such_map)" if mode == "each_value" else "job 2 (environment=no_such_map seed=0)"
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(f"swarmscene: {label}: environment: unknown option 'no_such_map' (valid: ")
    assert not (tmp_path / "sweep").exists()  # no job ran


def test_an_unknown_validation_mode_is_one_line(tmp_path):
    proc = swarmscene("--multirun", "seed=0,1", "hydra/sweeper=swarmscene", "hydra.sweeper.validate=bogus",
                      f"hydra.sweep.dir={tmp_path}/s", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "swarmscene: hydra.sweeper.validate: must be one of ('each_value', 'all') (got 'bogus')"
    ]


def _sweeper_choice(overrides: list[str]) -> str:
    from hydra import compose, initialize_config_module

    from swarmscene.composition.searchpath import register_search_path

    register_search_path()
    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"):
        cfg = compose("config", overrides=overrides, return_hydra_config=True)
    return cfg.hydra.runtime.choices["hydra/sweeper"]


@pytest.mark.parametrize("preset", ["cem_k", "failure_time", "fast", "indoor_corridor", "methods"])
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


def test_sweep_progress_counts_failed_jobs_and_is_quiet_off_a_terminal(tmp_path):
    """A job that fails is counted as it fails; with the default (auto) and no terminal, the sweep
    prints no progress line at all."""
    proc = swarmscene("-m", "clock.duration=1.0", "swarm.leader=0,7", f"hydra.sweep.dir={tmp_path}/sw", PROGRESS,
                      "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "hydra.sweeper.on_invalid=record",
                      "hydra/sweeper=swarmscene", cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr  # one job failed
    assert progress_counts(proc.stderr)[-1] == "2/2 jobs done, 1 failed"
    quiet = swarmscene("-m", "clock.duration=1.0", "seed=0,1", f"hydra.sweep.dir={tmp_path}/quiet", cwd=tmp_path)
    assert quiet.returncode == 0 and progress_counts(quiet.stderr) == []


def test_an_interpolated_value_follows_each_jobs_seed(tmp_path):
    """docs/faults_and_maps.md: `environment.seed='${seed}'` varies the map with the run's seed; the
    grid's check set the text '${seed}' itself, unresolved, and refused every job."""
    import yaml

    proc = swarmscene("--multirun", "environment=obstacle_field", "environment.seed=${seed}", "seed=3,4",
                      "clock.duration=0.2", "output.trajectory=false", f"hydra.sweep.dir={tmp_path}/m", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    configs = [yaml.safe_load((tmp_path / "m" / job / "config.yaml").read_text()) for job in ("0", "1")]
    assert [(c["seed"], c["environment"]["seed"]) for c in configs] == [(3, 3), (4, 4)]


def test_a_full_disk_while_the_records_are_written_names_the_file(tmp_path, monkeypatch):
    """ENOSPC names no file; the sweep's records said "No space left on device" and nothing else."""
    import errno

    from swarmscene.runs import outputs

    real_fdopen = outputs.os.fdopen

    class Full:
        def __init__(self, fd, mode):
            self.fh = real_fdopen(fd, mode)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.fh.close()

        def write(self, data):
            raise OSError(errno.ENOSPC, "No space left on device")

    job = tmp_path / "sw" / "0"
    job.mkdir(parents=True)
    monkeypatch.setattr(outputs.os, "fdopen", Full)
    with pytest.raises(OSError) as full:
        outputs.atomic_write_json(job / "error.json", {"error": "x"})
    assert full.value.filename == str(job / "error.json") and full.value.errno == errno.ENOSPC
    assert job_module.error_lines(full.value) == [f"{job / 'error.json'}: cannot be written (No space left on device)"]
    assert list(job.iterdir()) == []  # no temporary file left behind


@pytest.mark.parametrize(("group", "option", "extra"), [
    ("hydra/launcher", "joblib", "joblib"), ("hydra/launcher", "ray", "ray"),
    ("hydra/launcher", "submitit_slurm", "submitit"), ("hydra/sweeper", "optuna", "optuna"),
])
def test_a_launcher_whose_extra_is_missing_gives_the_install_line(group, option, extra):
    """Without the extra, Hydra has no such option: the line read "unknown option 'joblib'"."""
    from hydra.errors import MissingConfigException

    from swarmscene.composition.hydra_errors import hydra_error_line

    exc = MissingConfigException(f"In 'hydra/config': Could not find '{group}/{option}'",
                                 missing_cfg_file=f"{group}/{option}", options=["basic", "pool"])
    assert hydra_error_line(exc) == (f"{group}={option} needs the {extra!r} extra (Hydra's {option} plugin is not "
                                     f"installed): pip install 'swarmscene[{extra}]'")
    unknown = MissingConfigException(f"In 'hydra/config': Could not find '{group}/nope'",
                                     missing_cfg_file=f"{group}/nope", options=["basic", "pool"])
    assert hydra_error_line(unknown) == f"{group.replace('/', '.')}: unknown option 'nope' (valid: basic, pool)"


def test_an_interpolation_error_with_no_message_still_names_its_key_and_why():
    """A resolver that raises with no message gave "key: cannot resolve the value: KeyError raised
    while resolving interpolation: " and nothing after it."""
    from omegaconf import OmegaConf
    from omegaconf.errors import InterpolationResolutionError

    from swarmscene.composition.hydra_errors import resolution_error_line

    OmegaConf.register_new_resolver("swarmscene_test_silent", lambda: (_ for _ in ()).throw(KeyError()), replace=True)
    cfg = OmegaConf.create({"name": "${swarmscene_test_silent:}"})
    with pytest.raises(InterpolationResolutionError) as err:
        OmegaConf.to_container(cfg, resolve=True)
    line = resolution_error_line(err.value)
    assert line == ("name: cannot resolve the value: KeyError raised while resolving interpolation (the resolver "
                    "gave no message)")
    silent = InterpolationResolutionError("")
    silent.full_key = "environment.seed"
    assert resolution_error_line(silent) == "environment.seed: cannot resolve the value: InterpolationResolutionError (no message)"
