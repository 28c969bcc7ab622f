"""A sweep directory under stress: concurrent sweeps, a damaged or planted grid record, a read-only
directory, damaged job files and kills, display options on a re-run, and api.sweep's values and paths.
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

from swarmscene.sweeps import records, tables

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
SMALL = ["--multirun", "seed=0,1", "clock.duration=1.0"]


def swarmscene(*args: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run([*EXE, *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=timeout)


def lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("swarmscene: ")]


def temporaries(directory: Path) -> list[Path]:
    return [p for p in directory.rglob(".*.tmp")]


# -- one sweep at a time --------------------------------------------------------------------------
def test_a_second_sweep_into_a_locked_directory_is_refused_in_one_line(tmp_path):
    sw = tmp_path / "sw"
    lock = records.SweepLock(sw).acquire()  # another sweep is running there
    try:
        proc = swarmscene(*SMALL, f"hydra.sweep.dir={sw}", cwd=tmp_path)
    finally:
        lock.release()
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"swarmscene: hydra.sweep.dir: {sw} is in use by another sweep (pid {os.getpid()}): wait for it to end, "
        "or choose another hydra.sweep.dir"
    ]
    assert not sw.exists()  # released, the lock removed what it made: nothing ran
    proc = swarmscene(*SMALL, f"hydra.sweep.dir={sw}", cwd=tmp_path)  # free again
    assert proc.returncode == 0, proc.stderr
    assert not (sw / records.LOCK_FILE).exists()


def test_a_sweep_into_a_single_runs_directory_is_refused_in_one_line(tmp_path):
    """A run's directory given as hydra.sweep.dir took the sweep's jobs among its files, and its
    summary then counted the old run alone ('1 jobs, all complete')."""
    from swarmscene import api

    run_dir = tmp_path / "run"
    api.run(["clock.duration=0.3", "output.summary=false"], output_dir=run_dir)
    before = sorted(p.name for p in run_dir.iterdir())
    proc = swarmscene(*SMALL, f"hydra.sweep.dir={run_dir}", cwd=tmp_path)
    assert proc.returncode == 2
    assert lines(proc.stderr) == [
        f"swarmscene: hydra.sweep.dir: {run_dir} is a run's directory (manifest.json or .hydra/overrides.yaml in "
        "it), not a sweep's: choose another hydra.sweep.dir"]
    assert sorted(p.name for p in run_dir.iterdir()) == before  # no job ran there


def test_two_sweeps_started_at_once_one_runs_one_is_refused(tmp_path):
    sw = tmp_path / "sw"
    env = dict(os.environ)
    env.pop("HYDRA_FULL_ERROR", None)
    procs = [
        subprocess.Popen([*EXE, "--multirun", f"seed={seeds}", "clock.duration=3.0", f"hydra.sweep.dir={sw}"],
                         cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        for seeds in ("0,1", "5,6")  # two different grids
    ]
    outcomes = sorted((p.wait(timeout=300), p.stderr.read()) for p in procs)
    (ok, _), (refused, stderr) = outcomes
    assert ok == 0 and refused == 2
    # The loser was refused by the lock, or (had the winner ended first) by the grid record.
    assert len(lines(stderr)) == 1 and ("is in use by another sweep" in stderr or "holds another sweep" in stderr)
    assert len(tables.collect_rows(sw)) == 2


# -- the grid record -------------------------------------------------------------------------------
@pytest.mark.parametrize("damage,problem", [
    ("directory", "sweep.json: not a regular file"),
    ("numbers", "sweep.json: 'jobs' should be a list of override lists"),
    ("garbage", "sweep.json: not valid JSON"),
    ("list", "sweep.json: should hold a mapping, holds list"),
    ("link", "sweep.json: is a symbolic link"),
])
def test_a_damaged_grid_record_stops_the_sweep_in_one_line(tmp_path, damage, problem):
    sw = tmp_path / "sw"
    sw.mkdir()
    record = sw / "sweep.json"
    if damage == "directory":
        record.mkdir()
    elif damage == "numbers":
        record.write_text(json.dumps({"grid": ["seed=0,1"], "jobs": [1, 2]}))
    elif damage == "garbage":
        record.write_bytes(b"\x00{not json")
    elif damage == "list":
        record.write_text("[]")
    else:
        (tmp_path / "elsewhere.json").write_text(json.dumps({"grid": [], "jobs": []}))
        record.symlink_to(tmp_path / "elsewhere.json")
    proc = swarmscene(*SMALL, f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(f"swarmscene: {sw}/{problem}") and "restore it, or delete the directory" in line
    assert sorted(p.name for p in sw.iterdir()) == ["sweep.json"]  # no job ran, no lock left


def read_only(directory: Path):
    """Make ``directory`` read-only: a read-only mount as root (who writes through modes), else
    its mode."""
    directory.mkdir()
    if os.geteuid() == 0:
        subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(directory)], check=True)
        return lambda: subprocess.run(["umount", str(directory)], check=True)
    directory.chmod(0o555)
    return lambda: directory.chmod(0o755)


def test_a_read_only_sweep_directory_is_one_line_naming_it(tmp_path):
    sw = tmp_path / "ro"
    undo = read_only(sw)
    try:
        for target in (sw, sw / "inner"):
            proc = swarmscene(*SMALL, f"hydra.sweep.dir={target}", cwd=tmp_path)
            assert proc.returncode == 2
            (line,) = proc.stderr.strip().splitlines()
            assert line.startswith(f"swarmscene: hydra.sweep.dir: {sw}") and "ead-only" in line, line
    finally:
        undo()


# -- resume ---------------------------------------------------------------------------------------
def test_a_resume_reruns_jobs_whose_files_do_not_load_and_the_report_never_calls_them_complete(tmp_path):
    sw = tmp_path / "sw"
    args = [*SMALL[:1], "seed=0,1,2", *SMALL[2:], f"hydra.sweep.dir={sw}"]
    assert swarmscene(*args, cwd=tmp_path).returncode == 0
    (sw / "0" / "metrics.json").write_text("garbage")
    trajectory = sw / "1" / "trajectory.npz"
    trajectory.write_bytes(trajectory.read_bytes()[:200])  # truncated after the job finished
    (sw / "2" / ".trajectory.npz.k1ll3d.tmp").write_bytes(b"half")  # a killed rewrite's temporary
    rows = {r["job"]: r for r in tables.collect_rows(sw)}
    assert rows["0"]["status"] == rows["1"]["status"] == "damaged"
    assert rows["0"]["error"].startswith(f"{sw}/0/metrics.json: not valid JSON")
    assert rows["1"]["error"].startswith(f"{sw}/1/trajectory.npz: ")
    assert rows["2"]["status"] == "complete"
    assert tables.exit_status(list(rows.values())) == 1
    proc = swarmscene(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "job 2 already complete" in proc.stderr
    assert "job 0 already complete" not in proc.stderr and "job 1 already complete" not in proc.stderr
    assert {r["status"] for r in tables.collect_rows(sw)} == {"complete"}
    assert temporaries(sw) == []


def test_a_sweep_killed_hard_resumes_and_leaves_no_temporary_file(tmp_path):
    sw = tmp_path / "sw"
    args = ["--multirun", "seed=0,1,2,3", "clock.duration=6.0", f"hydra.sweep.dir={sw}"]
    env = dict(os.environ)
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.Popen([*EXE, *args], cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=env, start_new_session=True)
    deadline = time.monotonic() + 240
    while not (sw / "0" / "manifest.json").exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    assert (sw / "0" / "manifest.json").exists()
    (sw / "1").mkdir(exist_ok=True)
    (sw / "1" / ".metrics.json.x.tmp").write_text("{")  # as a kill inside a write leaves it
    assert (sw / records.LOCK_FILE).exists()  # the killed sweep's lock file: no longer held
    resumed = swarmscene(*args, cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert "job 0 already complete (same config hash): skipped" in resumed.stderr
    assert [r["status"] for r in tables.collect_rows(sw)] == ["complete"] * 4
    assert temporaries(sw) == [] and not (sw / records.LOCK_FILE).exists()


def test_display_options_neither_change_the_hash_nor_refuse_the_rerun(tmp_path):
    sw = tmp_path / "sw"
    assert swarmscene(*SMALL, f"hydra.sweep.dir={sw}", cwd=tmp_path).returncode == 0
    hashes = [r["config_hash"] for r in tables.collect_rows(sw)]
    proc = swarmscene(*SMALL, "output.progress=off", "output.summary=false", "output.rerun=false",
                      "output.plots=false", f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "job 0 already complete" in proc.stderr and "job 1 already complete" in proc.stderr
    assert [r["config_hash"] for r in tables.collect_rows(sw)] == hashes
    # A value that changes what a job computes is another grid.
    proc = swarmscene(*SMALL, "clock.duration=2.0", f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 2 and "holds another sweep" in proc.stderr


# -- api.sweep --------------------------------------------------------------------------------------
def test_api_sweep_takes_values_as_values_and_paths_as_paths(tmp_path):
    from swarmscene import api
    from swarmscene.runs.rundir import RunDir

    where = tmp_path / "a dir, with a comma"
    result = api.sweep({"description": ["one, two", "it's"]}, ["clock.duration=0.5"], sweep_dir=where)
    assert result.exit_status == 0 and len(result.rows) == 2  # a comma inside a value: one job, not two
    assert [RunDir(where / str(i)).config()["description"] for i in (0, 1)] == ["one, two", "it's"]
    assert [r["status"] for r in result.rows] == ["complete", "complete"]


# -- large grids: checked and launched batch by batch ------------------------------------------------
def test_batches_start_small_and_double():
    from swarmscene.sweeps.sweeper import FIRST_BATCH, LAST_BATCH, batches

    assert batches(5, None, True) == [(0, 5)]  # checked whole: one launch (max_batch_size: all)
    assert batches(5, 2, True) == [(0, 2), (2, 4), (4, 5)]
    sizes = [stop - start for start, stop in batches(10_000, None, False)]
    assert sizes[:4] == [FIRST_BATCH, 2 * FIRST_BATCH, 4 * FIRST_BATCH, 8 * FIRST_BATCH]
    assert max(sizes) == LAST_BATCH and sum(sizes) == 10_000
    assert {stop - start for start, stop in batches(100, 8, False)} == {8, 4}  # max_batch_size caps them


def test_a_grid_checked_batch_by_batch_stops_at_the_batch_with_a_bad_value(tmp_path):
    """With more distinct overrides than ``upfront``, the first batch starts at once; a bad value
    in a later batch stops the sweep there with the same one line, the jobs before it complete."""
    sw = tmp_path / "sw"
    proc = swarmscene("--multirun", "scenario=cem_six_vehicle", "avoidance.K=1,0", "seed=range(0,20)",
                      "clock.duration=0.05", "hydra/sweeper=swarmscene", "hydra.sweeper.upfront=2",
                      f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 2
    assert lines(proc.stderr) == ["swarmscene: job 20 (avoidance.K=0): avoidance.K: must be >= 1 (got 0)"]
    rows = tables.collect_rows(sw)
    assert [r["job"] for r in rows] == [str(i) for i in range(16)]  # the first batch: 16 jobs
    assert {r["status"] for r in rows} == {"complete"}
    proc = swarmscene("--multirun", "seed=0,1", "hydra/sweeper=swarmscene", "hydra.sweeper.upfront=-1",
                      f"hydra.sweep.dir={tmp_path}/x", cwd=tmp_path)
    assert proc.returncode == 2 and "hydra.sweeper.upfront: must be an integer >= 0 (got -1)" in proc.stderr


def test_a_sweep_named_outside_its_directory_is_one_line_and_writes_nothing(tmp_path):
    """``name=../x`` is refused by the run-dir resolver: the sweep callback must not turn it into a
    multi-line Hydra warning before the one line (it left the sweep directory unresolved)."""
    work = tmp_path / "work"
    work.mkdir()
    proc = swarmscene("--multirun", "name=../x", "seed=0,1", "clock.duration=0.5", cwd=work)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "swarmscene: name: must not contain '/' or '\\' (it names one output directory) (got '../x')"
    ]
    assert list(tmp_path.iterdir()) == [work] and not any(work.iterdir())


def test_a_link_planted_at_multirun_yaml_is_replaced_not_written_through(tmp_path):
    sw = tmp_path / "sw"
    sw.mkdir()
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    (sw / "multirun.yaml").symlink_to(target)
    proc = swarmscene("--multirun", "seed=0", "clock.duration=0.5", f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert target.read_text() == "keep me"
    assert not (sw / "multirun.yaml").is_symlink() and "sweep:" in (sw / "multirun.yaml").read_text()


def test_a_job_directory_planted_as_a_link_is_refused_and_nothing_is_written_through_it(tmp_path):
    sw, outside = tmp_path / "sw", tmp_path / "outside"
    sw.mkdir()
    outside.mkdir()
    (sw / "0").symlink_to(outside)
    proc = swarmscene("--multirun", "seed=0,1", "clock.duration=0.5", f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 1  # job 0 did not complete
    assert [ln for ln in lines(proc.stderr) if ln.startswith("swarmscene: job 0 failed")] == [
        f"swarmscene: job 0 failed: {sw / '0'}: is a symbolic link (refused: a job's records are written "
        "inside the sweep directory)"
    ]
    assert list(outside.iterdir()) == []
    assert (sw / "1" / "manifest.json").is_file()
    rows = [(row["job"], row["status"]) for row in tables.collect_rows(sw)]
    assert rows == [("0", "damaged"), ("1", "complete")]  # the link is listed, never read


def test_a_sweep_adding_a_config_folder_composes_its_groups(tmp_path):
    """A group that only ``hydra.searchpath`` brings (``+experiment=fast``) is a group, not a value:
    such a sweep's jobs are composed by Hydra whole."""
    extra = tmp_path / "extra" / "experiment"
    extra.mkdir(parents=True)
    (extra / "fast.yaml").write_text("# @package _global_\ndescription: from the extra folder\nclock:\n  duration: 0.5\n")
    sw = tmp_path / "sw"
    proc = swarmscene("--multirun", f"hydra.searchpath=[file://{tmp_path / 'extra'}]", "+experiment=fast",
                      "seed=0,1", f"hydra.sweep.dir={sw}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for job in ("0", "1"):
        config = (sw / job / "config.yaml").read_text()
        assert "description: from the extra folder" in config and "duration: 0.5" in config


def test_sigterm_to_a_joblib_sweeps_main_process_stops_it_with_143(tmp_path):
    """The launcher's workers run the jobs; the main process only waits, so a SIGTERM sent to it
    alone (a scheduler's cancel, `kill PID`) stops the launch at once instead of after every job."""
    sw = tmp_path / "sw"
    env = dict(os.environ)
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.Popen(
        [*EXE, "--multirun", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2", "seed=range(0,40)",
         "clock.duration=3000", "termination.on_complete=false", f"hydra.sweep.dir={sw}"],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    deadline = time.monotonic() + 120
    while not (sw / "0").exists() and time.monotonic() < deadline:  # the first job has started
        time.sleep(0.2)
    time.sleep(2.0)
    proc.send_signal(signal.SIGTERM)
    started = time.monotonic()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert time.monotonic() - started < 60  # 40 jobs of 3,000 s would take hours
    # (termination.on_complete=false: the mission completes at 28 s, and 40 such jobs in tasks of
    # several ended within the 2 s the test waits)


def test_the_summary_is_written_while_the_sweep_still_holds_its_lock(tmp_path, monkeypatch, capsys):
    """The tables are written before the lock is released: a second sweep let into the directory
    once the lock is free can never change its jobs under tables being written."""
    import fcntl

    from swarmscene import cli
    from swarmscene.sweeps import callback

    sw = tmp_path / "sw"
    held = []
    real = callback.write_summary

    def write_summary(sweep_dir):
        fd = os.open(sw / records.LOCK_FILE, os.O_RDWR)  # a second opener, as another sweep would be
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            held.append(False)
        except BlockingIOError:
            held.append(True)
        finally:
            os.close(fd)
        return real(sweep_dir)

    monkeypatch.setattr(callback, "write_summary", write_summary)
    monkeypatch.setattr(sys, "argv", ["swarmscene", *SMALL, "clock.duration=0.3", f"hydra.sweep.dir={sw}"])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    try:
        cli.main()
    except SystemExit as exc:
        assert not exc.code
    assert "HYDRA_FULL_ERROR" not in os.environ  # the command put back what it set for itself
    assert held == [True]  # written once, by the sweeper, under its lock
    assert (sw / "summary.md").is_file() and not (sw / records.LOCK_FILE).exists()
    assert "2 jobs, all complete" in capsys.readouterr().err
