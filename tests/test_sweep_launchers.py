"""The same sweep under every launcher: identical numbers, bit for bit, and every job's manifest
naming the command as typed and the node it ran on.

- the basic launcher (one process), joblib (2 workers) and ``api.sweep``: every job's metrics and
  trajectory identical;
- a real multi-node Ray cluster on this machine: a head (no CPUs for jobs) and two worker nodes,
  each started with ``ray start`` by the fixture (small memory and CPU settings, every start bounded
  in time, everything stopped at the end); the sweep's jobs land on both worker nodes, and its table
  and trajectories are the basic launcher's;
- the SLURM path (hydra-submitit-launcher) through submitit's local executor.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from swarmscene.runs.rundir import RunDir
from swarmscene.sweeps import tables

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
GRID = ["--multirun", "avoidance.v_max=1.0,1.5", "seed=0,1,2,3", "clock.duration=2.0"]
TIMING = {"wall_time", "realtime_factor", "step_ms_median"}


def swarmscene(*args: str, cwd: Path, env: dict | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    full_env = dict(os.environ if env is None else env)
    full_env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run([*EXE, *args], cwd=cwd, capture_output=True, text=True, env=full_env, timeout=timeout)


def site_env(tmp_path: Path, sitecustomize: str, **variables: str) -> dict:
    """An environment whose Python processes (a sweep's main process, fork server and workers:
    Python imports ``sitecustomize`` at start) run ``sitecustomize`` first, with ``variables`` set."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(sitecustomize)
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]), **variables}


def outcome(sweep_dir: Path) -> list[tuple[dict, dict]]:
    """Every job's metrics (wall-clock figures aside) and trajectory arrays, in job order."""
    jobs = []
    for row in tables.collect_rows(sweep_dir):
        run = RunDir(sweep_dir / row["job"])
        metrics = {k: v for k, v in run.metrics().items() if k not in TIMING}
        jobs.append((metrics, run.trajectory()))
    return jobs


def assert_identical(a: Path, b: Path) -> None:
    left, right = outcome(a), outcome(b)
    assert len(left) == len(right) == 8
    for (m1, t1), (m2, t2) in zip(left, right, strict=True):
        assert m1 == m2
        assert t1.keys() == t2.keys()
        for name in t1:
            assert t1[name].dtype == t2[name].dtype and t1[name].tobytes() == t2[name].tobytes()


@pytest.fixture(scope="module")
def basic(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("basic")
    proc = swarmscene(*GRID, f"hydra.sweep.dir={root}/sw", cwd=root)
    assert proc.returncode == 0, proc.stderr
    return root / "sw"


def test_joblib_and_api_sweep_give_the_basic_launchers_numbers_bit_for_bit(basic, tmp_path):
    from swarmscene import api

    proc = swarmscene(*GRID, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={tmp_path}/jl",
                      cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert_identical(basic, tmp_path / "jl")
    result = api.sweep({"avoidance.v_max": [1.0, 1.5], "seed": [0, 1, 2, 3]}, ["clock.duration=2.0"],
                       sweep_dir=tmp_path / "api")
    assert result.exit_status == 0
    # Job i of api.sweep is job i of the command line (the same grid order).
    def jobs(rows):
        return [sorted(o.replace("++", "") for o in r["overrides"].split()) for r in rows]
    assert jobs(result.rows) == jobs(tables.collect_rows(basic))
    assert_identical(basic, tmp_path / "api")
    manifest = RunDir(tmp_path / "jl" / "0").manifest()
    assert manifest["command"][1:] == [*GRID, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
                                       f"hydra.sweep.dir={tmp_path}/jl"]
    assert manifest["node"]["host"] == socket.gethostname()


# -- a multi-node Ray cluster on this machine ---------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen) -> None:
    """A `ray start --block` process group (ours only): SIGTERM, then SIGKILL for what is left."""
    for sig, wait in ((signal.SIGTERM, 10), (signal.SIGKILL, None)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            pass
    proc.wait()


def _nodes(ray_bin: Path, address: str, env: dict) -> int:
    proc = subprocess.run([str(ray_bin), "status", f"--address={address}"], env=env, capture_output=True,
                          text=True, timeout=60)
    active = proc.stdout.split("Active:")[-1].split("Pending:")[0]
    return sum(line.strip().startswith("1 node_") for line in active.splitlines())


@pytest.fixture
def ray_nodes(ray_env):
    """A Ray head (0 CPUs: it runs no job) and two worker nodes (1 CPU each) on 127.0.0.1, started
    one after the other with ``ray start`` (two nodes starting at once on one host can time out
    against each other), each start bounded to 90 s; yields (address, the client's environment)."""
    env = {**ray_env, "RAY_AUTH_MODE": "disabled",
           # Several nodes on one Linux host: Ray's own switch for clusters it does not expect there.
           "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "1"}
    ray_bin = Path(sys.executable).with_name("ray")
    temp_dir = tempfile.mkdtemp(prefix="ray")  # short: Ray's socket paths have a length limit
    port = _free_port()
    address = f"127.0.0.1:{port}"
    common = ["--block", "--node-ip-address=127.0.0.1", "--object-store-memory=78643200", "--disable-usage-stats"]
    started: list[subprocess.Popen] = []
    try:
        for n, extra in enumerate([
            ["--head", f"--port={port}", "--num-cpus=0", "--include-dashboard=false", f"--temp-dir={temp_dir}"],
            [f"--address={address}", "--num-cpus=1"],
            [f"--address={address}", "--num-cpus=1"],
        ]):
            started.append(subprocess.Popen([str(ray_bin), "start", *common, *extra], env=env, start_new_session=True,
                                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
            deadline = time.monotonic() + 90
            while _nodes(ray_bin, address, env) < n + 1:
                assert started[-1].poll() is None, f"ray node {n} exited while starting"
                assert time.monotonic() < deadline, f"ray node {n} did not join in 90 s"
                time.sleep(1)
        yield address, env
    finally:
        for proc in reversed(started):
            _stop(proc)
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_a_sweep_spreads_over_the_nodes_of_a_ray_cluster_with_the_basic_launchers_numbers(basic, tmp_path, ray_nodes):
    address, env = ray_nodes
    args = [*GRID, "hydra/launcher=ray", f"hydra.launcher.ray.init.address={address}",
            "+hydra.launcher.ray.init.object_store_memory=null", f"hydra.sweep.dir={tmp_path}/ray"]
    proc = swarmscene(*args, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr
    manifests = [RunDir(tmp_path / "ray" / str(i)).manifest() for i in range(8)]
    nodes = {m["node"]["ray_node_id"] for m in manifests}
    assert len(nodes) >= 2  # the jobs ran on both worker nodes
    assert all(m["command"][1:] == args for m in manifests)  # as typed, not the Ray worker's argv
    assert_identical(basic, tmp_path / "ray")
    keep = lambda rows: [{k: v for k, v in r.items() if k not in TIMING} for r in rows]  # noqa: E731
    assert keep(tables.collect_rows(tmp_path / "ray")) == keep(tables.collect_rows(basic))


def test_the_slurm_path_through_submitits_local_executor(basic, tmp_path):
    proc = swarmscene(*GRID, "hydra/launcher=submitit_local", "hydra.launcher.timeout_min=10",
                      f"hydra.sweep.dir={tmp_path}/slurm", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert_identical(basic, tmp_path / "slurm")
    manifest = json.loads((tmp_path / "slurm" / "0" / "manifest.json").read_text())
    assert manifest["command"][1:4] == GRID[:3]


def test_the_pool_launcher_ends_its_workers_when_the_sweep_ends(tmp_path):
    """Left to the interpreter's exit, the executor's manager thread could write to a closed
    wake-up pipe: `OSError: [Errno 9] Bad file descriptor` after a successful sweep. The sweeper
    closes the launcher after its last batch; close() shuts the pool down once."""
    from swarmscene.sweeps.pool import PoolLauncher

    calls = []

    class Executor:
        def shutdown(self, wait):
            calls.append(wait)

    launcher = PoolLauncher(n_jobs=1)
    launcher._executor = Executor()
    launcher.close()
    launcher.close()  # idempotent: nothing left to end
    assert calls == [True] and launcher._executor is None
