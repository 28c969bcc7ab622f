"""Experiment tracking in MLflow: a Hydra callback logging every job of a run or sweep (``mlflow`` extra).

    swarmscene --multirun scenario=cem_six_vehicle avoidance=cem,potential seed=0,1,2 hydra/callbacks=mlflow
    mlflow ui                      # in the same directory: compare methods and seeds

When a job ends, :class:`MlflowLogger` opens one MLflow run for it in a local store (no server:
SQLite by default, ``sqlite:///mlflow.db`` in the working directory, MLflow's own default) and logs:

    params      the job's effective configuration (the run directory's ``config.yaml``, every
                default resolved) flattened to dotted keys; lists as JSON; a value longer than
                ``MAX_PARAM_LENGTH`` characters (an explicit start of 1,000 agents) is left to
                ``config.yaml`` and its key listed in the tag ``swarmscene.long_params``
    metrics     every number of ``metrics.json`` (booleans as 0 / 1)
    tags        the Hydra overrides, the job number, the stop reason, the config hash and status
    artifacts   the run directory's files (``config.yaml``, ``metrics.json``, ``manifest.json``,
                ``trajectory.npz``, plots...), unless ``artifacts`` is false

The run is named ``<scenario name>/<job number>`` inside the experiment ``experiment`` (default:
the scenario's ``name``); a failed job (``error.json``) is logged with status FAILED and its error.
Options, as keys of the callback node (``hydra.callbacks.mlflow.tracking_uri=...``): see
:class:`MlflowLogger`. Artifacts of a SQLite store go beside its database file (``mlruns/``).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

try:
    from hydra.experimental.callback import Callback as _Callback
except ImportError:  # pragma: no cover - hydra-core is a dependency
    _Callback = object  # type: ignore[misc,assignment]  # a plain base when hydra is absent

MAX_PARAM_LENGTH = 500
"""Longest parameter value logged as such (MLflow allows 6,000; longer lists belong to config.yaml)."""


def flatten(data: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts as one level of dotted keys (``{"clock": {"duration": 3}}`` -> ``clock.duration``)."""
    out: dict[str, Any] = {}
    if isinstance(data, dict):
        for key, value in data.items():
            out.update(flatten(value, f"{prefix}{key}."))
    else:
        out[prefix[:-1]] = data
    return out


def params_of(config: dict[str, Any]) -> tuple[dict[str, str], list[str]]:
    """MLflow params from an effective config, and the keys left out for their length."""
    params, long = {}, []
    for key, value in flatten({k: v for k, v in config.items() if k != "hydra"}).items():
        text = value if isinstance(value, str) else json.dumps(value)
        if len(text) > MAX_PARAM_LENGTH:
            long.append(key)
        else:
            params[key] = text
    return params, long


def metrics_of(metrics: dict[str, Any]) -> dict[str, float]:
    """The numbers of ``metrics.json`` (booleans as 0 / 1; text, lists and nulls are not metrics)."""
    out = {}
    for key, value in metrics.items():
        if isinstance(value, bool):
            out[key] = float(value)
        elif isinstance(value, (int, float)) and math.isfinite(value):
            out[key] = float(value)
    return out


def _read(path: Path) -> Any:
    import yaml

    try:
        text = path.read_text()
    except OSError:
        return None
    return json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)


class MlflowLogger(_Callback):
    """Hydra callback logging each finished job to MLflow.

    Args:
        tracking_uri: MLflow tracking URI; null: ``MLFLOW_TRACKING_URI`` when set, else
            ``sqlite:///mlflow.db`` (a file in the working directory, which ``mlflow ui`` opens).
        experiment: experiment name; null: the scenario's ``name``.
        artifacts: log the run directory's files as the run's artifacts.
    """

    def __init__(self, tracking_uri: str | None = None, experiment: str | None = None, artifacts: bool = True) -> None:
        self.tracking_uri = tracking_uri
        self.experiment = experiment
        self.artifacts = artifacts

    def on_job_end(self, config: Any, job_return: Any, **kwargs: Any) -> None:
        """Log the finished job to MLflow; a tracking failure is reported and never fails the job."""
        run_dir = Path(config.hydra.runtime.output_dir)
        try:
            self.log_job(run_dir, list(job_return.overrides or []), str(config.hydra.job.get("num", "0")))
        except Exception as exc:  # tracking must never lose the job's own outputs
            print(f"swarmscene: could not log job {run_dir.name} to MLflow: {type(exc).__name__}: {exc}",
                  file=sys.stderr)

    def log_job(self, run_dir: Path, overrides: list[str], job: str) -> str:
        """Log one run directory as an MLflow run; returns the run id."""
        from mlflow import MlflowClient
        from mlflow.entities import Metric, Param, RunTag
        from mlflow.utils.time import get_current_time_millis

        config = _read(run_dir / "config.yaml") or {}
        metrics = _read(run_dir / "metrics.json") or {}
        manifest = _read(run_dir / "manifest.json") or {}
        error = _read(run_dir / "error.json")
        client = MlflowClient(self.tracking_uri)
        experiment_id = self._experiment(client, self.experiment or str(config.get("name", "swarmscene")))
        params, long = params_of(config)
        tags = {
            "swarmscene.overrides": " ".join(overrides),
            "swarmscene.job": job,
            "swarmscene.run_dir": str(run_dir.resolve()),
            "swarmscene.config_hash": str(manifest.get("config_hash", "")),
            "swarmscene.stop_reason": str(metrics.get("stop_reason", "")),
        }
        if long:
            tags["swarmscene.long_params"] = ", ".join(long)
        if error:
            tags["swarmscene.error"] = str(error.get("error", ""))[:5000]
        run = client.create_run(experiment_id, run_name=f"{config.get('name', 'run')}/{job}", tags=tags)
        run_id = run.info.run_id
        now = get_current_time_millis()
        client.log_batch(
            run_id,
            metrics=[Metric(k, v, now, 0) for k, v in metrics_of(metrics).items()],
            params=[Param(k, v) for k, v in params.items()],
            tags=[RunTag(k, v) for k, v in tags.items()],
        )
        if self.artifacts:
            for path in sorted(run_dir.iterdir()):
                if path.is_file() and not path.name.startswith("."):
                    client.log_artifact(run_id, str(path))
        status = "FAILED" if error or manifest.get("status") == "failed" else (
            "FINISHED" if manifest.get("complete") else "KILLED")
        client.set_terminated(run_id, status=status)
        return run_id

    def _experiment(self, client: Any, name: str) -> str:
        found = client.get_experiment_by_name(name)
        if found is not None:
            return found.experiment_id
        try:
            return client.create_experiment(name, artifact_location=self._artifact_location(client))
        except Exception:  # created meanwhile by a parallel job
            found = client.get_experiment_by_name(name)
            if found is None:
                raise
            return found.experiment_id

    @staticmethod
    def _artifact_location(client: Any) -> str | None:
        """Beside the database for a SQLite store (else MLflow's default ``./mlruns`` would follow
        the working directory of whichever job created the experiment)."""
        uri = client.tracking_uri
        if uri.startswith("sqlite:///"):
            database = Path(uri[len("sqlite:///"):])
            return (database.resolve().parent / "mlruns").as_uri()
        return None
