"""A separately packaged plugin (docs/examples/swarmscene-slowdown) works after install alone."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "swarmscene-slowdown"


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The example package built and installed (with its entry points) into a private folder."""
    work = tmp_path_factory.mktemp("thirdparty")
    shutil.copytree(EXAMPLE, work / "src", ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    target = work / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target", str(target), str(work / "src")],
        check=True,
        capture_output=True,
    )
    return target


def run_cli(site: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    env.pop("HYDRA_FULL_ERROR", None)
    code = "from swarmscene.cli import main; main()"
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


def test_cli_runs_with_third_party_avoidance(site, tmp_path):
    proc = run_cli(site, tmp_path, "avoidance=slowdown", "avoidance.factor=0.25", f"hydra.run.dir={tmp_path}/run")
    assert proc.returncode == 0, proc.stderr
    assert "/ slowdown /" in proc.stdout
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["slowdown.agent_ticks_slowed"] > 0
    config = (tmp_path / "run" / "config.yaml").read_text()
    assert "name: slowdown" in config and "factor: 0.25" in config


def test_third_party_params_are_validated(site, tmp_path):
    proc = run_cli(site, tmp_path, "avoidance=slowdown", "avoidance.factor=2", f"hydra.run.dir={tmp_path}/run")
    assert proc.returncode == 2
    assert proc.stderr.strip() == "swarmscene: avoidance.factor: must be <= 1.0 (got 2)"


def test_help_and_completion_see_the_new_option(site, tmp_path):
    proc = run_cli(site, tmp_path, "--help")
    assert "slowdown" in proc.stdout


def test_the_example_package_passes_the_contract_checks_in_its_own_tests(site, tmp_path):
    """The packaged example runs swarmscene.testing's checks in its own test suite, as a third-party
    author would (its tests/ folder, run by pytest against the installed package)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir", str(tmp_path),
         "-c", os.devnull, str(EXAMPLE / "tests")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout
