"""A method installed with pip (docs/examples/swarmscene-slowdown) is scored on swarmscene-bench and
shown beside the built-ins' shipped reference results by the one command of docs/suite.md."""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "swarmscene-slowdown"


def test_a_pip_installed_method_is_scored_beside_the_built_ins(tmp_path):
    shutil.copytree(EXAMPLE, tmp_path / "src", ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target",
                    str(site), str(tmp_path / "src")], check=True, capture_output=True)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    # the documented command, on one task and two seeds (the command line replaces the grid's entries)
    args = ["--multirun", "+sweep=suite_v1", "avoidance=slowdown", "task=dense_swap_ring", "seed=range(0,2)",
            "hydra/launcher=basic", f"hydra.sweep.dir={tmp_path}/suite_v1_slowdown"]
    proc = subprocess.run([sys.executable, "-c", "from swarmscene.cli import main; main()", *args], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "suite_v1_slowdown" / "suite"
    assert "2 runs scored of slowdown (reference: cbf, none, orca, potential)" in proc.stderr
    rows = list(csv.DictReader((out / "scores.csv").open()))
    mine = [r for r in rows if r["method"] == "slowdown"]
    assert sorted((r["task"], r["seed"], r["version"]) for r in mine) == [
        ("dense_swap_ring", "0", "v1"), ("dense_swap_ring", "1", "v1")]
    results = json.loads((out / "results.json").read_text())
    assert results["methods"] == ["cbf", "none", "orca", "potential", "slowdown"]
    assert results["tasks"] == ["dense_swap_ring"] and results["seeds"] == [0, 1]  # compared where all ran
    assert "slowdown>orca" in results["probability_of_improvement"]
    board = (out / "leaderboard.md").read_text()
    assert "| slowdown |" in board and "| orca |" in board
    marl = json.loads((out / "marl_eval.json").read_text())["swarmscene-bench-v1"]["dense_swap_ring"]
    assert set(marl["slowdown"]) == {"run_0", "run_1"} and len(marl["orca"]) == 10
