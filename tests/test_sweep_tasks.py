"""Launcher tasks of several jobs (swarmscene.sweeps.chunks, ``hydra.sweeper.jobs_per_task``): how a
batch is cut into tasks, and a task's jobs equal to the same jobs launched one by one (run
directories, numbers, trajectories, metrics) under the basic and joblib launchers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from swarmscene.sweeps import chunks, task

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
TIMING = {"wall_time", "realtime_factor", "step_ms_median", "cem.step_ms_median"}


def config(n_jobs=None, chdir=False, callbacks=("swarmscene.sweeps.callback.SweepSummary",),
           subdir="${hydra.job.num}"):
    launcher = {} if n_jobs is None else {"n_jobs": n_jobs}
    return OmegaConf.create({"hydra": {
        "job": {"chdir": chdir}, "launcher": launcher, "sweep": {"dir": "sw", "subdir": subdir},
        "callbacks": {f"c{i}": {"_target_": target} for i, target in enumerate(callbacks)}}})


def launcher(name):
    return type(name, (), {})()


def test_tasks_carry_each_jobs_overrides_and_number_and_split_back():
    jobs = [["seed=0"], ["seed=1", "avoidance.K=2"], ["seed=2"], ["seed=3"], ["seed=4"]]
    got = chunks.tasks(jobs, 1, 5, 3)
    assert got == [["seed=1", "avoidance.K=2", "::job=1", "seed=2", "::job=2", "seed=3", "::job=3"],
                   ["seed=4", "::job=4"]]
    assert [chunks.split(t) for t in got] == [[(1, ["seed=1", "avoidance.K=2"]), (2, ["seed=2"]), (3, ["seed=3"])],
                                              [(4, ["seed=4"])]]
    assert chunks.tasks(jobs, 0, 2, 1) == [["seed=0"], ["seed=1", "avoidance.K=2"]]  # Hydra's own launch
    assert chunks.split(["seed=0"]) is None and chunks.split([]) is None


def test_jobs_per_task_auto_keeps_four_tasks_per_worker_and_falls_back_to_one_job():
    joblib = launcher("JoblibLauncher")
    assert chunks.jobs_per_task("auto", joblib, config(n_jobs=2), 200) == 25
    assert chunks.jobs_per_task("auto", joblib, config(n_jobs=2), 5) == 1
    assert chunks.jobs_per_task("auto", joblib, config(n_jobs=-1), 200, cores=4) == 13  # all 4 cores
    assert chunks.jobs_per_task("auto", joblib, config(n_jobs=2), 10_000) == chunks.MAX_PER_TASK
    assert chunks.jobs_per_task("auto", launcher("BasicLauncher"), config(), 100) == 64
    assert chunks.jobs_per_task("auto", launcher("BasicLauncher"), config(), 7) == 7
    assert chunks.jobs_per_task(5, joblib, config(n_jobs=2), 200) == 5
    assert chunks.jobs_per_task(500, joblib, config(n_jobs=2), 3) == 3
    # where a task cannot stand for its jobs: one job a task
    mlflow = ("swarmscene.sweeps.callback.SweepSummary", "swarmscene.sweeps.mlflow_callback.MLflowCallback")
    assert chunks.refusal(launcher("SlurmLauncher"), config()) == "launcher SlurmLauncher"
    assert chunks.refusal(joblib, config(callbacks=mlflow)) == "job callbacks"
    # a callback with only the sweep's hooks (the falsifier's) keeps no job to run_job; one that
    # cannot be imported here does
    falsify = ("swarmscene.sweeps.callback.SweepSummary", "swarmscene.tools.falsify.WorstCase")
    assert chunks.refusal(joblib, config(callbacks=falsify)) is None
    assert chunks.refusal(joblib, config(callbacks=("not_a_module.Callback",))) == "job callbacks"
    assert chunks.refusal(joblib, config(chdir=True)) == "hydra.job.chdir"
    assert chunks.refusal(joblib, config(subdir="${hydra:job.num}")) == "hydra.sweep.subdir"
    assert chunks.refusal(joblib, config()) is None
    for refused in (config(callbacks=mlflow), config(chdir=True)):
        assert chunks.jobs_per_task("auto", joblib, refused, 200) == 1
        assert chunks.jobs_per_task(8, joblib, refused, 200) == 1  # a setting cannot force it


DESCRIBED = "description=job ${hydra:job.num} id ${hydra:job.id}"


def sweep(where: Path, *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    proc = subprocess.run([*EXE, "--multirun", "clock.duration=0.3", "seed=0,1,2,3,4", *args,
                           f"hydra.sweep.dir={where}"], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return proc


def job_record(job: Path) -> dict:
    metrics = {k: v for k, v in json.loads((job / "metrics.json").read_text()).items() if k not in TIMING}
    manifest = json.loads((job / "manifest.json").read_text())
    return {"config": (job / "config.yaml").read_text(), "overrides": (job / ".hydra" / "overrides.yaml").read_text(),
            "trajectory": (job / "trajectory.npz").read_bytes(), "metrics": metrics,
            "manifest": {k: manifest[k] for k in ("complete", "config_hash", "seed", "scenario")},
            "command": [a for a in manifest["command"] if "jobs_per_task" not in a and "sweep.dir" not in a]}


JOBLIB = ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"]


@pytest.mark.parametrize("launch, described", [([], True), (JOBLIB, True), ([], False), (JOBLIB, False)],
                         ids=["basic-hydra-read", "joblib-hydra-read", "basic-lean", "joblib-lean"])
def test_a_task_of_several_jobs_writes_what_the_jobs_launched_alone_write(tmp_path, launch, described):
    """Tasks of 2 jobs ([0, 1], [2, 3], [4]) against one job a task: every run directory the same
    (config, overrides, trajectory bit for bit, metrics, manifest), each job numbered as itself.
    A config that reads ``${hydra:...}`` is composed whole for each job; one that does not takes the
    lean path (one ``hydra`` node per composition, loader.load_task_job)."""
    extra = [DESCRIBED] if described else ["description=lean"]
    sweep(tmp_path / "tasks", *launch, *extra, "hydra/sweeper=swarmscene", "hydra.sweeper.jobs_per_task=2")
    sweep(tmp_path / "alone", *launch, *extra, "hydra/sweeper=swarmscene", "hydra.sweeper.jobs_per_task=1")
    for n in range(5):
        task, alone = job_record(tmp_path / "tasks" / str(n)), job_record(tmp_path / "alone" / str(n))
        assert task == alone, n
        if described:
            description = OmegaConf.create(task["config"]).description
            assert description.startswith(f"job {n} id ") and description.endswith(str(n))
            assert DESCRIBED in task["command"]  # as typed, not as the first job resolved it
        assert f"- seed={n}" in task["overrides"].splitlines()
    assert sorted(p.name for p in (tmp_path / "tasks").iterdir() if p.is_dir()) == ["0", "1", "2", "3", "4"]
    summary = (tmp_path / "tasks" / "summary.csv").read_text().splitlines()
    assert len(summary) == 6 and all(",complete," in line for line in summary[1:])


def test_jobs_per_task_is_checked_in_one_line(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    proc = subprocess.run([*EXE, "--multirun", "seed=0,1", "hydra/sweeper=swarmscene", "hydra.sweeper.jobs_per_task=0",
                           f"hydra.sweep.dir={tmp_path / 'sw'}"], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode != 0
    assert "hydra.sweeper.jobs_per_task: must be auto or an integer >= 1 (got 0)" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("described, lean", [(False, 2), (True, 0)])
def test_a_tasks_later_jobs_take_the_lean_path_unless_the_config_reads_hydra(tmp_path, monkeypatch, capsys,
                                                                             described, lean):
    from swarmscene import cli

    calls = []
    as_lean = task._as_lean_job
    seen = []  # the task's payload is no longer in the environment a job (and its subprocesses) sees
    monkeypatch.setattr(task, "_as_lean_job",
                        lambda *a: calls.append(a[2]) or seen.append(os.environ.get(chunks.CHUNK_ENV)) or as_lean(*a))
    extra = [DESCRIBED] if described else ["description=lean"]
    monkeypatch.setattr(sys, "argv", ["swarmscene", "--multirun", "clock.duration=0.2", "seed=0,1,2", *extra,
                                      "hydra/sweeper=swarmscene", "hydra.sweeper.jobs_per_task=3", f"hydra.sweep.dir={tmp_path / 'sw'}"])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    try:
        cli.main()
    except SystemExit as exc:
        assert not exc.code
    assert calls == [1, 2][:lean] and seen == [""] * lean
    assert chunks.CHUNK_ENV not in os.environ  # Hydra removed it after the task
    assert "3 jobs, all complete" in capsys.readouterr().err
