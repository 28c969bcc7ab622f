"""Fault injection (issue #29): hostile files, planted links, names that climb out, a full disk,
a read-only directory, kills and re-runs, signals at random moments.

Every case checks the same contract: one line naming the file, option or directory; a non-zero
exit status (2 for bad input, 130/143 for an interruption); nothing written outside the
directory; nothing left that reads as complete when it is not; no temporary file left behind.

The quick form runs in CI; ``-m slow`` adds the long form (a real full disk on a small tmpfs
where the machine lets us mount one, and many signals and kills at random moments).
"""

from __future__ import annotations

import errno
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from swarmscene import api, cli
from swarmscene.runs.rundir import RunDir, RunFileError
from swarmscene.views import export, plots

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
SHORT = ["clock.duration=0.5", "output.summary=false"]


def command(monkeypatch, capsys, *args: str) -> tuple[int, list[str]]:
    """Run the ``swarmscene`` command in this process: (exit status, stderr lines)."""
    monkeypatch.setattr(sys, "argv", ["swarmscene", *args])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    monkeypatch.delenv(cli.DEBUG_ENV, raising=False)
    status = 0
    try:
        cli.main()
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    return status, capsys.readouterr().err.strip().splitlines()


def temps(directory: Path) -> list[str]:
    return sorted(p.name for p in Path(directory).rglob("*") if p.name.endswith(".tmp"))


@pytest.fixture(scope="module")
def good_run(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("faults") / "run"
    api.run(SHORT, output_dir=path)
    return path


def damaged(good_run: Path, tmp_path: Path, name: str, content: bytes | None) -> Path:
    run = tmp_path / "run"
    shutil.copytree(good_run, run)
    if content is None:
        (run / name).unlink()
    else:
        (run / name).write_bytes(content)
    return run


HOSTILE = [
    ("trajectory.npz", b"garbage", "trajectory.npz: not a readable numpy archive"),
    ("trajectory.npz", None, "trajectory.npz: missing"),
    ("metrics.json", b"[1, 2, 3]", "metrics.json: should hold a mapping, holds list"),
    ("manifest.json", b'"complete"', "manifest.json: should hold a mapping, holds str"),
    ("config.yaml", b"{{{{", "config.yaml: not valid YAML"),
    ("config.yaml", b"clock: [1, 2]\n", "config.yaml: 'clock' should be a mapping, holds list"),
    ("config.yaml", b"a: &x [1]\nb: *x\n", "config.yaml: holds YAML aliases"),
]


# -- hostile files: every reading tool, one line naming the file -------------------------------------
@pytest.mark.parametrize("name, content, words", HOSTILE)
def test_the_export_names_a_damaged_file_in_one_line(good_run, tmp_path, capsys, name, content, words):
    run = damaged(good_run, tmp_path, name, content)
    with pytest.raises(SystemExit) as exit_:
        export.main([str(run), "--csv", str(tmp_path / "csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(err) == 1
    assert err[0].startswith(f"python -m swarmscene.views.export: {run}/{words}"), err
    assert not (tmp_path / "csv").exists()


@pytest.mark.parametrize("name, content, words", HOSTILE[:4])
def test_plots_and_the_replay_raise_the_same_line(good_run, tmp_path, name, content, words):
    run = damaged(good_run, tmp_path, name, content)
    for read in (plots.load_run, lambda d: plots.write_run_plots(d, plots=True)):  # metrics, manifest: optional
        with pytest.raises(RunFileError, match=f"^{run}/{words}"):
            read(run)
    assert not list(run.glob("*.png"))


def test_a_missing_run_directory_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        export.main([str(tmp_path / "nope"), "--csv", str(tmp_path / "csv")])
    assert exit_.value.code == 2
    assert capsys.readouterr().err == \
        f"python -m swarmscene.views.export: {tmp_path}/nope: not a run directory (missing, or not a directory)\n"


# -- planted links and names: nothing written through or outside ---------------------------------------
def test_links_planted_in_a_run_directory_are_replaced_never_followed(tmp_path, monkeypatch, capsys):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    run = tmp_path / "run"
    (run / ".hydra").mkdir(parents=True)
    for name in (".hydra/config.yaml", ".hydra/overrides.yaml", "config.yaml", "metrics.json", "trajectory.npz",
                 "manifest.json", ".replay.rrd.tmp", ".metrics.json.abc123.tmp"):
        (run / name).symlink_to(victim)
    status, err = command(monkeypatch, capsys, *SHORT, f"hydra.run.dir={run}")
    assert status == 0, err
    assert victim.read_text() == "precious"
    assert not [p for p in run.rglob("*") if p.is_symlink()] and temps(run) == []
    assert RunDir(run).manifest()["complete"] is True and RunDir(run).trajectory()["t"][-1] == pytest.approx(0.5)


def test_a_run_directory_or_hydra_dir_that_is_a_link_is_refused(tmp_path, monkeypatch, capsys):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    run = tmp_path / "run"
    run.mkdir()
    (run / ".hydra").symlink_to(elsewhere)
    status, err = command(monkeypatch, capsys, *SHORT, f"hydra.run.dir={run}")
    assert status == 2
    assert err == [f"swarmscene: {run}/.hydra: is a symbolic link (refused: Hydra's records are written inside "
                   "the run directory)"]
    assert list(elsewhere.iterdir()) == []


@pytest.mark.parametrize("name", ["../../x", "a/b", "..", ".hidden", "x\\y"])
def test_a_name_that_would_leave_the_working_directory_is_refused_before_any_directory(
        tmp_path, monkeypatch, capsys, name):
    work = tmp_path / "a" / "b" / "work"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    status, err = command(monkeypatch, capsys, *SHORT, f"name={name}")
    assert status == 2 and len(err) == 1 and err[0].startswith("swarmscene: name: must "), err
    assert list(tmp_path.rglob("*")) == [tmp_path / "a", tmp_path / "a" / "b", work]


def test_the_schema_refuses_such_a_name_too():
    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        api.load(["name=../up", "clock.duration=0.1"])
    assert info.value.lines == ["name: must not contain '/' or '\\' (it names one output directory) (got '../up')"]


# -- file-system faults -----------------------------------------------------------------------------
def _fail_writes_with(monkeypatch, code: int) -> None:
    """The archive writer fails half-way, as a full disk (ENOSPC) or a read-only one (EROFS) does."""
    real = np.lib.format.write_array

    def failing(fh, array, *args, **kwargs):
        fh.write(b"\0" * 64)  # something reached the temporary file before the disk filled up
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(np.lib.format, "write_array", failing)
    return real


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS])
def test_a_failing_disk_is_one_line_naming_the_directory_and_leaves_nothing(tmp_path, monkeypatch, capsys, code):
    run = tmp_path / "out" / "run"
    _fail_writes_with(monkeypatch, code)
    status, err = command(monkeypatch, capsys, *SHORT, f"hydra.run.dir={run}")
    assert status == 2
    assert err == [f"swarmscene: {run}: cannot be written ({os.strerror(code)})"]
    assert not run.exists() and temps(tmp_path) == []


def test_a_rewrite_that_fails_leaves_no_complete_looking_directory(good_run, tmp_path, monkeypatch):
    """A directory written again: the old manifest goes first, so a failure leaves it unfinished."""
    run = tmp_path / "run"
    shutil.copytree(good_run, run)
    _fail_writes_with(monkeypatch, errno.ENOSPC)
    with pytest.raises(OSError) as info:
        api.run(SHORT, output_dir=run)
    assert info.value.filename == str(run) and info.value.errno == errno.ENOSPC
    assert not RunDir(run).has("manifest.json") and temps(run) == []


def test_temporary_files_a_killed_writer_left_are_removed_by_the_next_write(good_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(good_run, run)
    (run / ".trajectory.npz.k3j2x9.tmp").write_bytes(b"half")
    (run / ".replay.rrd.q8w7e6.tmp").mkdir()
    (run / ".replay.rrd.q8w7e6.tmp" / "replay.rrd").write_bytes(b"half")
    api.run(SHORT, output_dir=run)
    assert temps(run) == [] and RunDir(run).manifest()["complete"] is True


@pytest.mark.slow
def test_a_real_full_disk_on_a_small_tmpfs(tmp_path, monkeypatch, capsys):
    """Where this process may mount a tmpfs (root on Linux); elsewhere the same run with ENOSPC
    injected at the write, so the case always runs."""
    mount = tmp_path / "small"
    mount.mkdir()
    mounted = os.geteuid() == 0 and subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=200k", "tmpfs", str(mount)], capture_output=True).returncode == 0
    if not mounted:
        _fail_writes_with(monkeypatch, errno.ENOSPC)
    try:
        run = mount / "run"
        status, err = command(monkeypatch, capsys, "swarm=grid", "swarm.n=50", "clock.duration=60",
                              "termination.on_complete=false", "output.summary=false", f"hydra.run.dir={run}")
        assert status == 2 and err == [f"swarmscene: {run}: cannot be written (No space left on device)"]
        assert not run.exists() and temps(mount) == []
    finally:
        if mounted:
            subprocess.run(["umount", str(mount)], check=True)


# -- signals and kills ----------------------------------------------------------------------------------
def _start(run: Path, *extra: str) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    return subprocess.Popen([*EXE, "output.summary=false", f"hydra.run.dir={run}", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _state(run: Path) -> str:
    """absent, incomplete, unfinished (no manifest) or complete (and every file reads back)."""
    if not run.exists():
        return "absent"
    d = RunDir(run)
    if not d.has("manifest.json"):
        return "unfinished"
    if d.manifest()["complete"] is not True:
        return "incomplete"
    d.metrics()
    if d.has("trajectory.npz"):
        d.check_trajectory()
    return "complete"


def check_signal_outcome(run: Path, sig: int, proc: subprocess.Popen, err: str) -> str:
    """The contract of a stop request at any moment (module docstring)."""
    state = _state(run)
    assert temps(run.parent) == [] and "SystemError" not in err, err
    if "Traceback" in err:  # only during the interpreter's own start-up, before any code of ours runs
        assert sig == signal.SIGINT and "/swarmscene/" not in err and state == "absent", err
        assert err.rstrip().endswith("KeyboardInterrupt"), err
        return state
    if proc.returncode == 0:  # the run ended before the signal came
        assert state == "complete", err
    elif proc.returncode == -sig:  # before the handler was installed, or after the interpreter let it go
        assert state in ("absent", "complete"), (state, err)
    else:
        assert proc.returncode == 128 + sig, err
        assert state in ("absent", "incomplete", "complete"), (state, err)
    return state


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_before_the_run_starts_leaves_no_directory(tmp_path, sig):
    """Sent once Hydra has made the run directory, while the plugins are still being built."""
    run = tmp_path / "run"
    proc = _start(run, "swarm=grid", "swarm.n=400", "clock.duration=3000", "output.trajectory=false")
    deadline = time.monotonic() + 120
    while not (run / ".hydra").is_dir() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.005)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    state = check_signal_outcome(run, sig, proc, err)
    assert state in ("absent", "incomplete")  # 3000 s of 400 agents never completes first


@pytest.mark.parametrize("seed", range(3))
def test_a_signal_at_a_random_moment_ends_in_130_or_143_and_an_honest_directory(tmp_path, seed):
    rng = random.Random(seed)
    sig = rng.choice([signal.SIGINT, signal.SIGTERM])
    run = tmp_path / "run"
    proc = _start(run, "clock.duration=200", "termination.on_complete=false")
    time.sleep(rng.uniform(0.0, 1.5))
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    check_signal_outcome(run, sig, proc, err)


def test_a_killed_run_is_unfinished_and_a_rerun_completes_it_cleanly(tmp_path):
    run = tmp_path / "run"
    proc = _start(run, "swarm=grid", "swarm.n=200", "clock.duration=3000", "termination.on_complete=false",
                  "output.progress=on")
    deadline = time.monotonic() + 120
    while not (run / ".hydra").is_dir() and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)
    proc.kill()
    proc.communicate(timeout=60)
    assert _state(run) in ("absent", "unfinished")  # SIGKILL: nothing can be marked, nothing claims completion
    again = subprocess.run([*EXE, "clock.duration=0.5", "output.summary=false", f"hydra.run.dir={run}"],
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert _state(run) == "complete" and temps(run) == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(20))
def test_many_signals_and_kills_at_random_moments(tmp_path, seed):
    rng = random.Random(1000 + seed)
    sig = rng.choice([signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
    run = tmp_path / "run"
    proc = _start(run, "clock.duration=100", "termination.on_complete=false", "output.trajectory_stream=on",
                  "output.plots=" + rng.choice(["true", "false"]))
    time.sleep(rng.uniform(0.0, 4.0))
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=300)
    if sig == signal.SIGKILL:
        assert _state(run) in ("absent", "unfinished", "complete") or proc.returncode == 0
    else:
        check_signal_outcome(run, sig, proc, err)
    again = subprocess.run([*EXE, "clock.duration=0.5", "output.summary=false", f"hydra.run.dir={run}"],
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 0 and _state(run) == "complete" and temps(run) == [], again.stderr
