"""The batch launcher (``hydra/launcher=batch``, swarmscene/sweeps/batch.py): the jobs of a sweep that
differ only in their seed flown as batches of worlds, every job's run directory the basic launcher's.

- a sweep of ``swap`` and the default scenario cut into several batches (``batch_size`` smaller
  than a group) and single jobs: every job's metrics (timing aside), trajectory, ``config.yaml``
  and ``.hydra/overrides.yaml`` equal to the basic launcher's, the same table and exit status;
- jobs that a batch cannot fly (an output it does not write) in the same sweep as batched ones:
  run alone, with their files and the same numbers;
- resume: a rerun skips the complete jobs (untouched) and flies the others;
- a world whose plugin raises fails alone, recorded as under the basic launcher;
- how a launch is cut into batches, and a bad option value is one line.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
import yaml
from test_sweep_launchers import TIMING, site_env, swarmscene

from swarmscene.runs.rundir import RunDir
from swarmscene.sweeps import batch, tables

GRID = ["--multirun", "scenario=swap,default", "seed=0,1,2", "clock.duration=1.5"]
BATCH = ["hydra/launcher=batch", "hydra.launcher.n_jobs=2", "hydra.launcher.batch_size=2"]
# The default scenario's formation raises at t = 0.5 s in the world of seed 1, in every process the
# sweep starts (the launcher's fork server and workers included): Python imports sitecustomize at start.
FAILING = """\
from swarmscene.plugins.formation.static_shape import StaticShape

_setpoints, _init = StaticShape.setpoints, StaticShape.__init__


def setpoints(self, world, sensing):
    if self.seed_one and world.t >= 0.5:
        raise FloatingPointError("non-finite setpoint for agent 3")
    return _setpoints(self, world, sensing)


def init(self, params, ctx):
    _init(self, params, ctx)
    self.seed_one = ctx.rng.bit_generator.seed_seq.entropy == 1


StaticShape.setpoints, StaticShape.__init__ = setpoints, init
# planned world by world, as a formation without a batched form (one raising in setpoints_batch
# would stop every world of its batch)
del StaticShape.setpoints_batch
"""


def job(sweep_dir: Path, name: str) -> tuple[dict, dict, str, str]:
    """A job's metrics without the wall-clock ones, trajectory, config.yaml and overrides.yaml."""
    run = RunDir(sweep_dir / name)
    metrics = {k: v for k, v in run.metrics().items() if k not in TIMING}
    trajectory = {k: (v.dtype, v.tobytes()) for k, v in run.trajectory().items()}
    return (metrics, trajectory, (sweep_dir / name / "config.yaml").read_text(),
            (sweep_dir / name / ".hydra" / "overrides.yaml").read_text())


def table(sweep_dir: Path) -> list[dict]:
    """A sweep's summary rows without their wall-clock columns."""
    return [{k: v for k, v in row.items() if k not in TIMING} for row in tables.collect_rows(sweep_dir)]


def launched(proc) -> str:
    """The batch launcher's log line of the launch (how many jobs it batched)."""
    return next(line for line in (proc.stdout + proc.stderr).splitlines() if "Batch launcher:" in line)


@pytest.fixture(scope="module")
def basic(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("basic")
    proc = swarmscene(*GRID, f"hydra.sweep.dir={root}/sw", cwd=root)
    assert proc.returncode == 0, proc.stderr
    return root / "sw"


@pytest.fixture(scope="module")
def batched(tmp_path_factory) -> tuple[Path, object]:
    root = tmp_path_factory.mktemp("batched")
    proc = swarmscene(*GRID, *BATCH, f"hydra.sweep.dir={root}/sw", cwd=root)
    return root / "sw", proc


def test_batches_give_the_basic_launchers_run_directories_bit_for_bit(basic, batched):
    sweep_dir, proc = batched
    assert proc.returncode == 0, proc.stderr
    # 3 seeds a group, batches of at most 2: per scenario one batch of 2 and one job alone
    assert "6 jobs, 4 of them in 2 batches" in launched(proc)
    for name in map(str, range(6)):
        assert job(sweep_dir, name) == job(basic, name), name
    assert table(sweep_dir) == table(basic)
    assert proc.stderr.strip().splitlines()[-1] == f"swarmscene: 6 jobs, all complete; summary in {sweep_dir}/summary.md"
    assert tables.sweep_exit_status(sweep_dir) == 0
    manifest = RunDir(sweep_dir / "4").manifest()
    assert manifest["command"][1:] == [*GRID, *BATCH, f"hydra.sweep.dir={sweep_dir}"] and manifest["complete"]


def test_jobs_a_batch_cannot_fly_run_alone_beside_batched_ones(basic, tmp_path):
    """output.plots: a batch writes no pictures, so those jobs run one by one (their plots drawn);
    the others of the same sweep are batched. Both give the basic launcher's numbers."""
    proc = swarmscene("--multirun", "scenario=default", "seed=0,1", "output.plots=false,true", "clock.duration=1.5",
                      *BATCH, f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "4 jobs, 4 of them in 2 batches" in launched(proc)
    rows = tables.collect_rows(tmp_path / "sw")
    for row in rows:
        plots = "output.plots=true" in row["overrides"].lower()  # Hydra writes the value True
        metrics, trajectory, config, overrides = job(tmp_path / "sw", row["job"])
        reference = job(basic, str(3 + int(row["seed"])))  # the default scenario's jobs of the basic sweep
        assert (metrics, trajectory) == reference[:2]
        assert config == reference[2].replace("plots: false", f"plots: {str(plots).lower()}")
        files = RunDir(tmp_path / "sw" / row["job"]).manifest()["files"]
        assert ("trajectories.png" in files) == plots, files


def test_a_rerun_skips_complete_jobs_and_flies_the_others(basic, batched, tmp_path):
    source, _ = batched
    sw = tmp_path / "sw"
    shutil.copytree(source, sw)

    def stamp(name):  # atomic writes replace the file: a rewritten file has a new inode
        st = (sw / name / "metrics.json").stat()
        return st.st_ino, st.st_mtime_ns

    before = {name: stamp(name) for name in map(str, range(6))}
    for name in ("2", "4", "5"):  # interrupted before their manifests: one of a batch, a whole batch
        (sw / name / "manifest.json").unlink()
    proc = swarmscene(*GRID, *BATCH, f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    skipped = {line for line in proc.stderr.splitlines() if "already complete" in line}
    assert skipped == {f"swarmscene: job {n} already complete (same config hash): skipped" for n in "013"}
    after = {name: stamp(name) for name in map(str, range(6))}
    assert [name for name in after if after[name] != before[name]] == ["2", "4", "5"]  # the others untouched
    for name in map(str, range(6)):
        assert job(sw, name) == job(basic, name), name
    assert table(sw) == table(basic)


def test_a_world_whose_plugin_raises_is_recorded_failed_alone(tmp_path):
    env = site_env(tmp_path, FAILING)
    grid = ["--multirun", "scenario=default", "seed=0,1,2", "clock.duration=1.5"]
    procs = {name: swarmscene(*grid, *launcher, f"hydra.sweep.dir={tmp_path}/{name}", cwd=tmp_path, env=env)
             for name, launcher in (("basic", []), ("batch", ["hydra/launcher=batch", "hydra.launcher.n_jobs=2"]))}
    proc = procs["batch"]
    assert "3 jobs, 2 of them in 1 batches" in launched(proc)  # job 0 alone, jobs 1 and 2 one batch
    assert proc.returncode == procs["basic"].returncode == 1, proc.stderr
    err = proc.stderr.splitlines()
    assert ("swarmscene: job 1 failed: formation 'static_shape' raised in setpoints at t = 0.5 s: "
            "FloatingPointError: non-finite setpoint for agent 3") in err
    assert err[-1] == f"swarmscene: 1 of 3 jobs failed; summary in {tmp_path}/batch/summary.md"
    rows = table(tmp_path / "batch")
    assert [(r["seed"], r["status"], r["reason"]) for r in rows] == [
        (0, "complete", None), (1, "failed", "plugin-error"), (2, "complete", None)]
    assert rows == table(tmp_path / "basic")
    error = json.loads((tmp_path / "batch" / "1" / "error.json").read_text())
    assert "FloatingPointError" in error["traceback"]
    for name in "012":  # the failed world's records up to its failure too
        assert job(tmp_path / "batch", name) == job(tmp_path / "basic", name), name


COUNTED = """\
import os

from swarmscene.sweeps import batch

_composed = batch._composed


def composed(loader, config, idx, *rest):
    with open(os.environ["SWARMSCENE_TEST_COMPOSED"], "a") as out:
        out.write(f"{idx}\\n")
    return _composed(loader, config, idx, *rest)


batch._composed = composed
"""


def test_a_batchs_later_seeds_are_twins_of_its_first_composed_job(tmp_path):
    """A batch composes its first job; the jobs that differ from it in their seed alone are made
    from its config with their seed set (``_Twin``), and are the basic launcher's jobs all the same:
    an interpolation of the seed (each job's own obstacle field) and the ``++seed`` spelling
    resolve per job. A rerun whose twin is complete composes that job and skips it."""
    counted = tmp_path / "composed.txt"
    env = site_env(tmp_path, COUNTED, SWARMSCENE_TEST_COMPOSED=str(counted))
    grid = ["--multirun", "environment=obstacle_field", "environment.seed=${seed}", "++seed=3,4,5,6",
            "clock.duration=1.5"]
    one_batch = ["hydra/launcher=batch", "hydra.launcher.n_jobs=1", "hydra.launcher.batch_size=4"]
    basic = swarmscene(*grid, f"hydra.sweep.dir={tmp_path}/basic", cwd=tmp_path)
    proc = swarmscene(*grid, *one_batch, f"hydra.sweep.dir={tmp_path}/batch", cwd=tmp_path, env=env)
    assert basic.returncode == proc.returncode == 0, proc.stderr
    assert "4 jobs, 4 of them in 1 batches" in launched(proc)
    assert counted.read_text().split() == ["0"]  # jobs 1-3: twins of job 0
    for name in "0123":
        assert job(tmp_path / "batch", name) == job(tmp_path / "basic", name), name
    configs = [yaml.safe_load((tmp_path / "batch" / name / "config.yaml").read_text()) for name in "0123"]
    assert [(c["seed"], c["environment"]["seed"]) for c in configs] == [(3, 3), (4, 4), (5, 5), (6, 6)]
    assert table(tmp_path / "batch") == table(tmp_path / "basic")
    counted.unlink()
    (tmp_path / "batch" / "0" / "manifest.json").unlink()  # its first job incomplete, its twins complete
    rerun = swarmscene(*grid, *one_batch, f"hydra.sweep.dir={tmp_path}/batch", cwd=tmp_path, env=env)
    assert rerun.returncode == 0, rerun.stderr
    assert counted.read_text().split() == ["0", "1", "2", "3"]  # each complete twin composed, then skipped
    skipped = {line for line in rerun.stderr.splitlines() if "already complete" in line}
    assert skipped == {f"swarmscene: job {n} already complete (same config hash): skipped" for n in "123"}
    for name in "0123":
        assert job(tmp_path / "batch", name) == job(tmp_path / "basic", name), name


def test_a_launch_is_cut_into_batches_of_one_group_each():
    jobs = [[f"avoidance.K={k}", f"seed={s}"] for k in (1, 2) for s in range(5)]
    jobs += [["++seed=7"], ["seed=8"], ["avoidance.K=3"]]
    tasks = batch.plan(jobs, 10, batch_size=2, workers=2)
    assert [[idx for idx, _ in task] for task in tasks] == [[10], [11, 12], [13, 14], [15], [16, 17], [18, 19],
                                                            [20, 21], [22]]
    assert tasks[6] == [(20, ["++seed=7"]), (21, ["seed=8"])]  # no override but the seed: one group
    # a group is cut so that each worker gets tasks, at most batch_size jobs a batch
    sizes = [len(task) for task in batch.plan([[f"seed={s}"] for s in range(1000)], 0, 64, 2)]
    assert sizes == [62, 63] * 8
    assert [len(task) for task in batch.plan([[f"seed={s}"] for s in range(4)], 0, 64, 2)] == [2, 2]
    assert [len(task) for task in batch.plan([[f"seed={s}"] for s in range(4)], 0, 1, 2)] == [1, 1, 1, 1]
    assert batch.group_key(["seed=1", "::job=1"]) is None  # a launcher task of several jobs: never grouped


def test_grouped_by_physics_a_launch_is_one_group_of_every_job_that_parses():
    jobs = [["scenario=swap", "seed=0"], ["scenario=default", "avoidance=orca", "seed=1"],
            ["events.0.at=2.5", "events.0.agents.0=3"], ["seed=1", "::job=1"]]
    tasks = batch.plan(jobs, 0, batch_size=64, workers=1, group="physics")
    assert [[idx for idx, _ in task] for task in tasks] == [[0, 1, 2], [3]]  # a task of several jobs alone


def test_grouped_by_physics_a_null_physics_step_is_the_guidance_period_it_stands_for():
    """``clock.physics_step: null`` means the guidance period: such a world batches with one that
    spells that step out, and not with one of another step."""
    from swarmscene import api

    def key(*overrides):
        scenario = api.load(list(overrides))
        return batch._World(0, [], scenario.data, scenario, None, Path("."), {}).key("physics")

    null = ("clock.physics_step=null", "clock.guidance_period=0.1")
    assert key(*null) == key("clock.physics_step=0.1", "clock.guidance_period=0.1") != key()  # default: 0.02
    assert key(*null) != key("clock.physics_step=null", "clock.guidance_period=0.2")


def test_grouped_by_physics_jobs_of_other_scenarios_share_a_task_and_fly_by_their_physics(basic, tmp_path):
    """``group=physics`` on one worker: the six jobs of two scenarios (other formations, methods
    and dynamics) are one task; the worker flies swap's worlds and the default's as two batches (their
    dynamics differ), every job the basic launcher's bit for bit."""
    proc = swarmscene(*GRID, "hydra/launcher=batch", "hydra.launcher.n_jobs=1", "hydra.launcher.group=physics",
                      f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "6 jobs, 6 of them in 1 batches (grouped by physics)" in launched(proc)
    for name in map(str, range(6)):
        assert job(tmp_path / "sw", name) == job(basic, name), name
    assert table(tmp_path / "sw") == table(basic)


def test_worlds_with_other_options_share_a_batch_grouped_by_physics(tmp_path):
    """Four jobs of the default scenario that differ in a controller gain and in the avoidance's
    largest speed: grouped by physics they fly as one batch of four worlds (the double integrator's
    batched control declines worlds tuned apart), each job the basic launcher's bit for bit."""
    grid = ["--multirun", "seed=0", "dynamics.omega=1.5,2.0", "avoidance.v_max=1.5,1.0", "clock.duration=2"]
    runs = {}
    for name, launcher in (("basic", []), ("batch", ["hydra/launcher=batch", "hydra.launcher.n_jobs=1",
                                                      "hydra.launcher.group=physics"])):
        proc = swarmscene(*grid, *launcher, f"hydra.sweep.dir={tmp_path}/{name}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        runs[name] = proc
    assert "4 jobs, 4 of them in 1 batches" in launched(runs["batch"])
    for name in map(str, range(4)):
        assert job(tmp_path / "batch", name) == job(tmp_path / "basic", name), name


def test_a_bad_group_is_one_line(tmp_path):
    proc = swarmscene("--multirun", "seed=0,1", "hydra/launcher=batch", "hydra.launcher.group=everything",
                      f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1] == (
        "swarmscene: hydra.launcher.group: must be one of seed, physics (got 'everything')")


def test_a_bad_batch_size_is_one_line(tmp_path):
    proc = swarmscene("--multirun", "seed=0,1", "hydra/launcher=batch", "hydra.launcher.batch_size=0",
                      f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1] == "swarmscene: hydra.launcher.batch_size: must be an integer >= 1 (got 0)"


def test_api_sweep_takes_the_batch_launcher_by_name(basic, tmp_path):
    """``api.sweep(..., launcher="batch")`` is ``hydra/launcher=batch``: the basic launcher's rows."""
    from swarmscene import api

    result = api.sweep({"seed": "0,1,2"}, ["scenario=swap", "clock.duration=1.5"], launcher="batch",
                       sweep_dir=tmp_path / "sw")
    assert result.exit_status == 0
    by_seed = {row["seed"]: row for row in table(result.sweep_dir)}
    expected = {row["seed"]: row for row in table(basic) if "scenario=swap" in row.get("overrides", "")}
    assert sorted(by_seed) == [0, 1, 2] == sorted(expected)
    for seed, row in by_seed.items():
        assert {k: v for k, v in row.items() if k not in ("job", "overrides")} == {
            k: v for k, v in expected[seed].items() if k not in ("job", "overrides")}


def test_a_sweep_of_threaded_quadrotors_completes(tmp_path):
    """``dynamics.threads`` > 1 at 1,024 agents: the fork server warms the scenario on one thread,
    since numba's GNU OpenMP threads, once started, kill every process forked from theirs (the
    sweep ended interrupted before); the workers fly the jobs on two."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "2"}  # a one-core machine too starts two threads
    proc = swarmscene("--multirun", "scenario=flocking", "dynamics=quadrotor", "swarm.n=1024", "dynamics.threads=2",
                      "clock.duration=1", "seed=0,1", "hydra/launcher=batch", "hydra.launcher.n_jobs=1",
                      f"hydra.sweep.dir={tmp_path}/sw", cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == f"swarmscene: 2 jobs, all complete; summary in {tmp_path}/sw/summary.md"
