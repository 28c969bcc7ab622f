"""The MLflow callback: a sweep logged to a local SQLite store is read back with MLflow's own
client (params = the effective config, metrics = metrics.json, artifacts = the run directory)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import mlflow
import pytest
import yaml

from swarmscene.sweeps.mlflow_callback import MAX_PARAM_LENGTH, MlflowLogger, metrics_of, params_of
from swarmscene.sweeps.records import record_failure

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]


@pytest.fixture(scope="module")
def logged_sweep(tmp_path_factory) -> tuple[Path, str]:
    """Two jobs (two avoidance methods, 0.5 s each) logged by +hydra/callbacks=mlflow."""
    root = tmp_path_factory.mktemp("mlflow")
    uri = f"sqlite:///{root}/mlflow.db"
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "MLFLOW_TRACKING_URI")}
    proc = subprocess.run(
        [*EXE, "--multirun", "avoidance=potential,none", "clock.duration=0.5", "hydra/callbacks=mlflow",
         f"hydra.callbacks.mlflow.tracking_uri={uri}", f"hydra.sweep.dir={root}/sweep"],
        cwd=root, capture_output=True, text=True, env=env, timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "could not log" not in proc.stderr, proc.stderr
    return root / "sweep", uri


def test_a_sweep_is_read_back_with_mlflows_client(logged_sweep):
    sweep, uri = logged_sweep
    client = mlflow.MlflowClient(uri)
    experiment = client.get_experiment_by_name("default")  # the scenario's name
    runs = client.search_runs([experiment.experiment_id], order_by=["tags.`swarmscene.job` ASC"])
    assert [r.info.run_name for r in runs] == ["default/0", "default/1"]
    assert [r.info.status for r in runs] == ["FINISHED", "FINISHED"]
    for job, run in enumerate(runs):
        run_dir = sweep / str(job)
        config = yaml.safe_load((run_dir / "config.yaml").read_text())
        metrics = json.loads((run_dir / "metrics.json").read_text())
        assert run.data.params["avoidance.name"] == ["potential", "none"][job]
        assert run.data.params["clock.duration"] == "0.5"
        assert run.data.params["formation.waypoints"] == json.dumps(config["formation"]["waypoints"])
        assert run.data.params == params_of(config)[0]  # every key of the effective config
        assert run.data.metrics == metrics_of(metrics)
        assert run.data.metrics["min_separation"] == metrics["min_separation"]
        assert run.data.metrics["steps"] == 5.0
        overrides = yaml.safe_load((run_dir / ".hydra" / "overrides.yaml").read_text())
        assert run.data.tags["swarmscene.overrides"] == " ".join(overrides)
        assert f"avoidance={['potential', 'none'][job]}" in overrides
        artifacts = {f.path for f in client.list_artifacts(run.info.run_id)}
        assert artifacts == {p.name for p in run_dir.iterdir() if p.is_file() and not p.name.startswith(".")}
        assert {"config.yaml", "metrics.json", "manifest.json", "trajectory.npz"} <= artifacts
    # the artifacts sit beside the database, not in whichever directory the jobs ran
    assert Path(runs[0].info.artifact_uri.removeprefix("file://")).is_relative_to(sweep.parent / "mlruns")


def test_a_failed_job_is_logged_failed_with_its_error(tmp_path, default_data):
    run_dir = tmp_path / "3"
    run_dir.mkdir()
    record_failure(run_dir, ValueError("the policy diverged"), default_data)
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    run_id = MlflowLogger(tracking_uri=uri, experiment="failures").log_job(run_dir, ["seed=3"], "3")
    run = mlflow.MlflowClient(uri).get_run(run_id)
    assert run.info.status == "FAILED"
    assert run.data.tags["swarmscene.error"] == "ValueError: the policy diverged"
    assert run.data.metrics == {} and run.data.params == {}  # no config.yaml or metrics were written


def test_params_flatten_and_leave_long_values_to_config_yaml():
    config = {"hydra": {"x": 1}, "seed": 2, "clock": {"duration": 0.5}, "swarm": {"start": {
        "positions": [[float(i), 0.0, 1.0] for i in range(100)]}}, "output": {"objective": []}}
    params, long = params_of(config)
    assert params == {"seed": "2", "clock.duration": "0.5", "output.objective": "[]"}
    assert long == ["swarm.start.positions"] and len(json.dumps(config["swarm"]["start"]["positions"])) > MAX_PARAM_LENGTH
    assert metrics_of({"success": True, "min_clearance": None, "steps": 5, "stop_reason": "duration",
                       "violations.separation.agents": [1, 2], "x": float("inf")}) == {"success": 1.0, "steps": 5.0}
