"""The run directory records what ran: the effective configuration, its hash, the manifest."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from swarmscene import api
from swarmscene.runs.outputs import COSMETIC_KEYS, atomic_write_bytes, config_hash, source_revision

TIMING = ("wall_time", "realtime_factor", "step_ms_median")
EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
SCENARIOS = Path(api.__file__).resolve().parent.parent / "scenarios" / "scenario"


def same_numbers(a: dict, b: dict) -> bool:
    return {k: v for k, v in a.items() if k not in TIMING} == {k: v for k, v in b.items() if k not in TIMING}


@pytest.mark.parametrize("preset", sorted(p.stem for p in SCENARIOS.glob("*.yaml")))
def test_effective_config_holds_every_default_and_validates_to_itself(preset):
    scenario = api.load([f"scenario={preset}"])
    data = scenario.data
    for kind, params in scenario.plugin_params.items():
        assert set(data[kind]) == {"name", *type(params).model_fields}  # every option, defaults included
    assert set(data["output"]) == set(type(scenario.config.output).model_fields)
    again = api.load(yaml.safe_load(yaml.safe_dump(data)))
    assert again.data == data and config_hash(again.data) == config_hash(data)


def test_config_yaml_records_plugin_defaults_absent_from_the_composition(tmp_path):
    api.run(["clock.duration=1"], output_dir=tmp_path)
    recorded = yaml.safe_load((tmp_path / "config.yaml").read_text())
    assert "k_v" not in api.compose([])["dynamics"]
    assert recorded["dynamics"]["k_v"] == 12.04 and recorded["clock"]["duration"] == 1.0
    assert recorded["swarm"]["start"]["extent"] == 10.0


def test_hash_changes_with_every_effective_value_and_not_with_cosmetic_keys():
    data = api.load([]).data
    base = config_hash(data)

    def edited(path, value):
        copy = json.loads(json.dumps(data))
        node = copy
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
        return config_hash(copy)

    # a default changed by an upgrade changes the effective config, hence the hash
    assert edited(("dynamics", "k_v"), 12.05) != base
    assert edited(("swarm", "start", "extent"), 11.0) != base
    assert edited(("output", "trajectory_every"), 2) != base
    for path in COSMETIC_KEYS:
        assert edited(path, "something else") == base, path
    assert "progress" in data["output"]  # config_hash leaves its input untouched


# config_hash of two quadrotor compositions as 0.8.0 (eb3deeb) computed them, before the quadrotor
# had its ``threads`` option
HASHES_0_8_0 = {
    ("dynamics=quadrotor",): "abbab648e0aed1c50e0bfd7d492d4152c6d1ee5eab60136f8990b0035a6a22c3",
    ("scenario=vrb_airshow",): "37020f9a8eca57ed31e6c6c67af9bff85ff6e1bfb2df4484a6fbbf67db7c2846",
}


@pytest.mark.parametrize("overrides", sorted(HASHES_0_8_0))
def test_the_physics_threads_leave_0_8_0s_hashes_and_any_count_hashes_alike(overrides):
    """``dynamics.threads`` changes no number (tests/plugins/dynamics/test_quadrotor_threads.py), so
    it is out of the hash: a sweep recorded by 0.8.0, or on another thread count, resumes."""
    data = api.load(list(overrides)).data
    assert data["dynamics"]["threads"] == 1
    assert config_hash(data) == HASHES_0_8_0[overrides]
    assert config_hash(api.load([*overrides, "dynamics.threads=4"]).data) == HASHES_0_8_0[overrides]


@pytest.mark.parametrize("overrides", sorted(HASHES_0_8_0))
def test_float64_physics_keeps_0_8_0s_hashes_and_float32_has_its_own(overrides):
    """``dynamics.dtype`` (0.8.3) at float64 is the step as it was before the option, so it is out
    of the hash there (a sweep recorded by 0.8.0 resumes); float32 changes the numbers and the hash."""
    data = api.load(list(overrides)).data
    assert data["dynamics"]["dtype"] == "float64"
    assert config_hash(data) == HASHES_0_8_0[overrides]
    assert config_hash(api.load([*overrides, "dynamics.dtype=float32"]).data) != HASHES_0_8_0[overrides]


def test_rerun_from_a_run_directory_gives_identical_metrics(tmp_path):
    """The documented way: swarmscene --config-path <run dir> --config-name config (a relative
    path is taken from the working directory)."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    first = subprocess.run([*EXE, "swarm=grid", "swarm.n=9", "swarm.start.layout=random", "swarm.start.extent=12",
                            "swarm.start.connected=true", "avoidance.v_max=1.2", "clock.duration=6",
                            f"hydra.run.dir={tmp_path}/a"], capture_output=True, text=True, env=env, timeout=120)
    assert first.returncode == 0, first.stderr
    second = subprocess.run([*EXE, "--config-path", "a", "--config-name", "config", f"hydra.run.dir={tmp_path}/b"],
                            capture_output=True, text=True, env=env, timeout=120, cwd=tmp_path)
    assert second.returncode == 0, second.stderr
    a, b = tmp_path / "a", tmp_path / "b"
    assert same_numbers(json.loads((a / "metrics.json").read_text()), json.loads((b / "metrics.json").read_text()))
    assert np.array_equal(np.load(a / "trajectory.npz")["pos"], np.load(b / "trajectory.npz")["pos"])
    assert yaml.safe_load((a / "config.yaml").read_text()) == yaml.safe_load((b / "config.yaml").read_text())
    manifests = [json.loads((d / "manifest.json").read_text()) for d in (a, b)]
    assert manifests[0]["config_hash"] == manifests[1]["config_hash"]


def git_head() -> str | None:
    head = subprocess.run(["git", "-C", str(Path(api.__file__).parent), "rev-parse", "HEAD"],
                          capture_output=True, text=True)
    return head.stdout.strip() if head.returncode == 0 else None


def test_manifest_has_start_time_version_and_source_revision(tmp_path):
    source_revision.cache_clear()  # read once per process: other commits may have landed since
    before = git_head()
    api.run(["clock.duration=1"], output_dir=tmp_path)
    heads = {before, git_head()}
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    from datetime import datetime

    started = datetime.fromisoformat(manifest["started_at"])
    assert started.utcoffset().total_seconds() == 0
    assert manifest["versions"]["swarmscene"]
    if before is not None:  # this test runs from the source checkout (editable install)
        assert manifest["source"]["revision"] in heads
        assert isinstance(manifest["source"]["dirty"], bool)
    else:
        assert "source" not in manifest and source_revision() is None


@pytest.mark.parametrize("umask", [0o022, 0o002, 0o077])
def test_files_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        atomic_write_bytes(tmp_path / "x.txt", b"x")
        api.run(["clock.duration=0.3"], output_dir=tmp_path / "run")
    finally:
        os.umask(old)
    expected = 0o666 & ~umask
    assert (tmp_path / "x.txt").stat().st_mode & 0o777 == expected
    for name in ("config.yaml", "metrics.json", "trajectory.npz", "manifest.json"):
        assert (tmp_path / "run" / name).stat().st_mode & 0o777 == expected, name


def test_validation_builds_the_start_once_and_the_run_uses_it():
    scenario = api.load(["swarm=grid", "swarm.n=12", "swarm.start.layout=random", "swarm.start.extent=12",
                         "swarm.start.connected=true", "clock.duration=0.2"])
    assert scenario.initial_positions.shape == (12, 3) and not scenario.initial_positions.flags.writeable
    assert len(scenario.obstacles) == 1 and scenario.obstacles[0].geom_type == "Polygon"
    sim = api.build(scenario)
    assert np.array_equal(sim.world.pos, scenario.initial_positions)
    # the run continues the seeded stream after the start's draws, as when it drew them itself
    rng = np.random.default_rng(scenario.config.seed)
    from swarmscene.core.geometry import initial_positions

    initial_positions(scenario.config, rng)
    assert sim.rng.random() == rng.random()


def test_sigterm_is_handled_like_ctrl_c(tmp_path):
    """A scheduler's cancel: partial outputs marked incomplete, exit status 143.

    The signal is sent once the progress line proves the stepping loop runs (kernels compiled),
    however loaded the machine; the handler only records it and the loop stops between ticks.
    """
    import signal
    import threading
    import time

    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    proc = subprocess.Popen([*EXE, "swarm=grid", "swarm.n=400", "clock.duration=3000", "output.trajectory=false",
                             "termination.on_complete=false", "output.progress=on",
                             f"hydra.run.dir={tmp_path}/run"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    seen: list[str] = []
    reader = threading.Thread(target=lambda: seen.extend(iter(lambda: proc.stderr.read(1), "")), daemon=True)
    reader.start()
    deadline = time.monotonic() + 300
    while "x real time" not in "".join(seen) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)
    assert "x real time" in "".join(seen), "".join(seen)
    proc.send_signal(signal.SIGTERM)
    proc.stdout.read()
    proc.wait(timeout=120)
    reader.join(timeout=10)
    err = "".join(seen)
    run = tmp_path / "run"
    assert proc.returncode == 143, err
    assert "swarmscene: terminated at t = " in err and "Traceback" not in err
    manifest = json.loads((run / "manifest.json").read_text())
    metrics = json.loads((run / "metrics.json").read_text())
    assert manifest["complete"] is False and metrics["stop_reason"] == "interrupted"
    assert 0 < metrics["duration"] < 3000
