"""Run directories recorded before ``kind`` had one meaning (issue #35): their ``config.yaml`` keys
an event's kind and a disturbance model ``kind`` (until 0.6.0), and the start layout
``swarm.start.kind`` (until 0.7.0). Every reader takes either spelling: such a directory plots,
replays, exports and scores as the same run recorded with ``name`` and ``layout``, has the same
config hash, and runs again from the command line (one deprecation line per key, the new record
spelt ``name`` and ``layout``)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from swarmscene import api
from swarmscene.runs.outputs import config_hash
from swarmscene.suite import score
from swarmscene.views import plots, replay
from swarmscene.views.mcap_bag import noise_deviations

TASK = ["task=resil_lead_fails", "avoidance=orca", "seed=0", "output.summary=false"]
"""A suite task with an event (the lead hovers at 2 s) and a disturbance model (mocap: sensing_noise)."""


def spelt_kind(config: dict) -> dict:
    """``config`` as 0.6.0 recorded it: each event's and disturbance model's name under ``kind``,
    and the start layout too."""
    old = json.loads(json.dumps(config))
    for node in [*old.get("events", []), *old.get("disturbances", {}).values()]:
        node["kind"] = node.pop("name")
    start = old["swarm"]["start"]
    old["swarm"]["start"] = {("kind" if k == "layout" else k): v for k, v in start.items()}
    return old


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> tuple[Path, Path]:
    """(the task's run directory, a copy whose config.yaml is spelt as 0.6.0 wrote it)."""
    root = tmp_path_factory.mktemp("spelling")
    api.run(TASK, output_dir=root / "new")
    shutil.copytree(root / "new", root / "old")
    config = yaml.safe_load((root / "new" / "config.yaml").read_text())
    (root / "old" / "config.yaml").write_text(yaml.safe_dump(spelt_kind(config), sort_keys=False))
    return root / "new", root / "old"


def test_the_record_is_spelt_name_and_an_old_one_kind(runs):
    new, old = (yaml.safe_load((d / "config.yaml").read_text()) for d in runs)
    assert new["events"] == [{"at": 2.0, "agents": [0], "name": "hover"}]
    assert new["disturbances"]["mocap"]["name"] == "sensing_noise" and "kind" not in new["disturbances"]["mocap"]
    assert old["events"] == [{"at": 2.0, "agents": [0], "kind": "hover"}]
    assert new["swarm"]["start"]["layout"] == old["swarm"]["start"]["kind"] == "explicit"
    assert "kind" not in new["swarm"]["start"] and "layout" not in old["swarm"]["start"]
    manifest = json.loads((runs[0] / "manifest.json").read_text())
    assert config_hash(new) == config_hash(old) == manifest["config_hash"]


def test_an_old_run_directory_plots_and_replays_as_the_new_one(runs):
    new, old = (plots.load_run(d) for d in runs)
    assert old.config_hash == new.config_hash
    assert old.failures()[0][:2] == new.failures()[0][:2] == (0, 2.0)  # the event's time, not a frame's
    assert replay.events(old) == replay.events(new)
    assert (2.0, "WARN", "agent 0: failed (hovers in place)") in replay.events(old)
    legend = plots.trajectory_figure(old).axes[0].get_legend()
    assert "failed (1)" in [text.get_text() for text in legend.get_texts()]
    deviations = noise_deviations(old.config)  # the MCAP bag's covariance: sensing_noise found by its kind
    assert deviations is not None and all((a == b).all() for a, b in zip(deviations, noise_deviations(new.config),
                                                                          strict=True))


def test_an_old_suite_run_is_scored_as_the_new_one(runs):
    new, old = (score.score_run(d) for d in runs)
    assert isinstance(new, score.RunScore) and new.task == "resil_lead_fails"
    assert {**new.row(), "run": ""} == {**old.row(), "run": ""}


def test_an_old_run_directory_runs_again_with_one_deprecation_line_per_key(runs, tmp_path):
    """``swarmscene --config-path <run> --config-name config`` (as config.yaml's first line says):
    the old spelling works, each key warned once on the command line; the new record says name and
    hashes as the old one."""
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTHONWARNINGS")}
    proc = subprocess.run([sys.executable, "-c", "from swarmscene.cli import main; main()",
                           "--config-path", str(runs[1]), "--config-name", "config", f"hydra.run.dir={tmp_path}/again"],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    for key in ("events.0", "disturbances.mocap"):
        line = f"SwarmsceneDeprecationWarning: {key}.kind is deprecated: write {key}.name (kind is accepted until 0.9.0)"
        assert proc.stderr.count(line) == 1, proc.stderr
    line = ("SwarmsceneDeprecationWarning: swarm.start.kind is deprecated: write swarm.start.layout "
            "(kind is accepted until 0.9.0)")
    assert proc.stderr.count(line) == 1, proc.stderr
    again = yaml.safe_load((tmp_path / "again" / "config.yaml").read_text())
    assert again["events"] == [{"at": 2.0, "agents": [0], "name": "hover"}]
    assert again["swarm"]["start"]["layout"] == "explicit" and "kind" not in again["swarm"]["start"]
    manifest = json.loads((tmp_path / "again" / "manifest.json").read_text())
    assert manifest["config_hash"] == json.loads((runs[0] / "manifest.json").read_text())["config_hash"]
    assert json.loads((tmp_path / "again" / "metrics.json").read_text())["min_separation"] == json.loads(
        (runs[0] / "metrics.json").read_text())["min_separation"]
