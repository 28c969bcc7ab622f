"""The pool launcher (``hydra/launcher=pool``, swarmscene/sweeps/pool.py): workers forked from a
fork server that loaded the engine and ran the sweep's scenario once.

- the basic launcher's numbers, bit for bit, jobs of one task and jobs launched alone alike, with
  the manifests naming the command as typed;
- the fork server really is warm: importing its preload module with a CEM scenario loads the
  modules, compiled kernels and libraries that scenario's jobs use;
- a stop request sent to the main process alone stops the workers' jobs between ticks (written,
  marked incomplete) and ends the command with 143; a worker killed outright ends it with one line
  and status 1, and the same command then resumes the jobs not written;
- ``n_jobs`` is counted as joblib counts it, and a bad value is one line.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_sweep_launchers import GRID, TIMING, assert_identical, basic, site_env, swarmscene  # noqa: F401  (basic: a fixture)

from swarmscene.runs.rundir import RunDir
from swarmscene.sweeps import chunks, pool, tables

POOL = ["hydra/launcher=pool", "hydra.launcher.n_jobs=2"]


def table(sweep_dir: Path) -> list[dict]:
    """A sweep's summary rows without their wall-clock columns."""
    return [{k: v for k, v in row.items() if k not in TIMING} for row in tables.collect_rows(sweep_dir)]


@pytest.mark.parametrize("per_task", ["auto", "1"], ids=["tasks", "job-by-job"])
def test_the_pool_gives_the_basic_launchers_numbers_bit_for_bit(basic, tmp_path, per_task):  # noqa: F811
    args = [*GRID, *POOL, "hydra/sweeper=swarmscene", f"hydra.sweeper.jobs_per_task={per_task}",
            f"hydra.sweep.dir={tmp_path}/pool"]
    proc = swarmscene(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert_identical(basic, tmp_path / "pool")
    manifest = RunDir(tmp_path / "pool" / "3").manifest()
    assert manifest["command"][1:] == args
    assert table(tmp_path / "pool") == table(basic)


COMPOSITIONS = """\
import os

from hydra._internal.config_loader_impl import ConfigLoaderImpl

_load_sweep_config = ConfigLoaderImpl.load_sweep_config


def load_sweep_config(self, *args, **kwargs):
    with open(os.environ["SWARMSCENE_TEST_COMPOSED"], "a") as out:
        out.write(f"{os.getpid()}\\n")
    return _load_sweep_config(self, *args, **kwargs)


ConfigLoaderImpl.load_sweep_config = load_sweep_config
"""


@pytest.mark.parametrize("launcher", ["pool", "batch"])
def test_the_workers_compose_nothing_the_grids_check_composed(basic, tmp_path, launcher):  # noqa: F811
    """Hydra composes a sweep's group overrides once, in the main process, for the grid's check;
    the workers adopt that composition at their start (``compose.adopt``), so their jobs' configs
    cost a copy, not a composition, and are the basic launcher's all the same."""
    counted = tmp_path / "composed.txt"
    env = site_env(tmp_path, COMPOSITIONS, SWARMSCENE_TEST_COMPOSED=str(counted))
    proc = swarmscene(*GRID, f"hydra/launcher={launcher}", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={tmp_path}/sw",
                      cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr
    assert len(counted.read_text().split()) == 1  # the check's, in the main process; none in the 2 workers
    assert_identical(basic, tmp_path / "sw")


def test_an_optuna_sweep_on_the_pool_gives_the_basic_launchers_trials(tmp_path):
    """The falsifier (Hydra's Optuna sweeper): Hydra's plugin scan re-imports the sweeper's config
    class, which plain pickle refuses; the pool pickles it by name, both ways."""
    args = ["+sweep=falsify", "hydra.sweeper.n_trials=4", "hydra.sweeper.n_jobs=2"]
    for name, launcher in (("basic", []), ("pool", POOL)):
        proc = swarmscene(*args, *launcher, f"hydra.sweep.dir={tmp_path}/{name}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    assert table(tmp_path / "pool") == table(tmp_path / "basic")
    assert len(tables.collect_rows(tmp_path / "pool")) == 4


def test_the_fork_servers_preload_runs_the_sweeps_scenario_and_loads_what_its_jobs_use(tmp_path):
    from swarmscene import api

    scenario = api.compose(["scenario=cem_six_vehicle"])
    probe = (
        "import sys; import swarmscene.sweeps.warm\n"
        "from swarmscene.methods.cem import kernels\n"
        "print(int('scipy.optimize' in sys.modules), len(kernels.navigator_step_into.signatures))\n"
    )
    env = {**os.environ, pool.WARM_ENV: json.dumps(scenario)}
    warm = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, cwd=tmp_path)
    assert warm.returncode == 0, warm.stderr
    assert warm.stdout.split() == ["1", "1"]  # CEM acted (its failure moved early): optimizer and kernel loaded
    env[pool.WARM_ENV] = ""  # no scenario: the engine imported, nothing run
    cold = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, cwd=tmp_path)
    assert cold.stdout.split() == ["0", "0"], cold.stderr
    assert list(tmp_path.iterdir()) == []  # the warm-up writes nothing


def _long_sweep(sw: Path, seeds: int = 40, wait: float = 2.0) -> subprocess.Popen:
    """A sweep of ``seeds`` jobs of 30,000 ticks each (~2 s), started; returned ``wait`` s after its
    first job began."""
    env = dict(os.environ)
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.Popen(
        [sys.executable, "-c", "from swarmscene.cli import main; main()", "--multirun", *POOL,
         f"seed=range(0,{seeds})", "clock.duration=3000", "termination.on_complete=false", f"hydra.sweep.dir={sw}"],
        cwd=sw.parent, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while not (sw / "0").exists() and time.monotonic() < deadline:  # the first job has started
        time.sleep(0.05)
    time.sleep(wait)
    return proc


def _group(pid: int) -> list[int]:
    """The live processes of the sweep's process group (a zombie waits for its reaper: not live)."""
    out = subprocess.run(["ps", "-o", "pid=,stat=", "-g", str(pid)], capture_output=True, text=True).stdout
    return [int(line.split()[0]) for line in out.splitlines() if not line.split()[1].startswith("Z")]


def _workers(pid: int) -> list[int]:
    """The pool's workers in the sweep's process group: the fork server's children."""
    out = subprocess.run(["ps", "-ww", "-o", "pid=,ppid=,args=", "-g", str(pid)], capture_output=True, text=True).stdout
    rows = [line.split(None, 2) for line in out.splitlines()]
    server = [int(r[0]) for r in rows if len(r) == 3 and int(r[1]) == pid and "multiprocessing.forkserver" in r[2]]
    workers = [int(r[0]) for r in rows if server and int(r[1]) == server[0]]
    assert workers, out
    return workers


def test_sigterm_to_the_main_process_stops_the_workers_jobs_between_ticks_with_143(tmp_path):
    sw = tmp_path / "sw"
    proc = _long_sweep(sw)
    proc.send_signal(signal.SIGTERM)  # to the main process alone: it passes the request on
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    stopped = [job for job in sw.glob("*/manifest.json") if not json.loads(job.read_text())["complete"]]
    assert stopped  # the jobs running were written, marked incomplete, with the reason
    assert all(json.loads((job.parent / "metrics.json").read_text())["stop_reason"] == "interrupted"
               for job in stopped)
    deadline = time.monotonic() + 30  # the fork server and the tracker end when they see the command gone
    while _group(proc.pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _group(proc.pid) == []  # no worker, fork server or tracker left behind


def test_a_killed_worker_is_one_line_and_the_same_command_resumes(tmp_path):
    sw = tmp_path / "sw"
    proc = _long_sweep(sw, seeds=6, wait=0.5)
    os.kill(_workers(proc.pid)[0], signal.SIGKILL)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    assert err.strip().splitlines()[-1] == (f"swarmscene: {sw}: a worker process died (killed, or out of memory); "
                                            "the jobs written are kept: run the same command to resume the others")
    written = {job.parent.name for job in sw.glob("*/manifest.json") if json.loads(job.read_text())["complete"]}
    again = swarmscene("--multirun", *POOL, "seed=range(0,6)", "clock.duration=3000", "termination.on_complete=false",
                       f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert {line for line in again.stderr.splitlines() if "already complete" in line} == {
        f"swarmscene: job {job} already complete (same config hash): skipped" for job in written}
    assert len(tables.collect_rows(sw)) == 6 and all(RunDir(sw / str(i)).manifest()["complete"] for i in range(6))


def test_n_jobs_counts_as_joblib_and_a_bad_value_is_one_line(tmp_path):
    cores = len(os.sched_getaffinity(0))
    assert chunks.workers_for(None) == cores
    assert chunks.workers_for(-1) == cores
    assert chunks.workers_for(-cores - 5) == 1
    assert chunks.workers_for(3) == 3
    proc = swarmscene("--multirun", "seed=0,1", "hydra/launcher=pool", "hydra.launcher.n_jobs=0",
                      f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1] == (
        "swarmscene: hydra.launcher.n_jobs: must be null, an integer >= 1 or a negative count (-1: all cores) (got 0)")
