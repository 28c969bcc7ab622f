"""The live view (``output.live``, swarmscene/views/live.py): a run streamed to a Rerun viewer while it is
simulated. What the viewer received is read back: a headless Rerun (``rerun --port P --save FILE``,
the SDK's own binary) stands in for the viewer the run connects to, and a late viewer
(``rerun --connect URL --save FILE``) reads what a served run left on its server. Both are compared
with the run's replay.rrd: the same recording id, entities, positions and event log."""

from __future__ import annotations

import shutil
import signal
import socket
import subprocess
import time
import urllib.request

import numpy as np
import pytest

pytest.importorskip("rerun", reason="the rerun extra")

from swarmscene import api  # noqa: E402
from swarmscene.core.errors import ConfigError  # noqa: E402
from swarmscene.runs.outputs import config_hash  # noqa: E402
from swarmscene.views import live, replay

RUN = ["scenario=cem_six_vehicle", "clock.duration=4"]
"""Six vehicles, agent 0 fails at 2 s (a hover event): 400 ticks, all streamed."""
AGENTS = "/world/agents:Points3D:positions"
EVENTS = "/events:TextLog:text"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(condition, seconds=20.0):
    began = time.monotonic()
    while not condition():
        assert time.monotonic() - began < seconds, "timed out"
        time.sleep(0.1)


def viewer(*args):
    """The SDK's Rerun binary, headless; Ctrl-C (SIGINT) closes its file, so SIGINT is given back
    its default action (a shell's background job would hand it down ignored)."""
    return subprocess.Popen([*live.rerun_command(), *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def recordings_in(saved, copy):
    """The recordings of a file a viewer is still writing ({} while a chunk is half-written)."""
    if not saved.exists():
        return {}
    shutil.copy(saved, copy)
    try:
        return replay.read_recordings([copy])
    except Exception:  # noqa: BLE001 - a chunk half-written by the viewer: look again
        return {}


def agent_frames(frame):
    return int(frame[AGENTS].notna().sum()) if AGENTS in frame else 0


@pytest.fixture
def sink(tmp_path):
    """A headless Rerun viewer on a free port that saves what it receives: (url, file)."""
    port, saved = free_port(), tmp_path / "received.rrd"
    proc = viewer("--port", str(port), "--save", str(saved))
    wait_until(lambda: live.listening("127.0.0.1", port))
    yield f"rerun+http://127.0.0.1:{port}/proxy", saved, proc
    if proc.poll() is None:
        proc.kill()
        proc.wait(10)


def stop(proc):
    proc.send_signal(signal.SIGINT)  # the viewer closes its file on Ctrl-C
    proc.wait(20)


def simulate(overrides, live_value=None, progress=None):
    """Build, attach the live view as the run's extra writers do, run: (sim, result, view)."""
    sim = api.build([*overrides, *([f"output.live={live_value}"] if live_value else [])])
    view = live.attach(sim)
    return sim, sim.run(progress=progress), view


def replay_of(sim, result, tmp_path):
    run_dir = tmp_path / "run"
    api.write_outputs(sim, result, run_dir, [lambda d: replay.export_rerun(d, sim=sim, result=result)])
    (rid, frame), = replay.read_recordings([run_dir / "replay.rrd"]).items()
    return rid, frame


def assert_same_run(streamed, replayed):
    """Same times, bit-identical agent positions at every one, the same event log."""
    a, b = (frame.dropna(subset=[AGENTS]).set_index("sim_time")[AGENTS] for frame in (streamed, replayed))
    assert list(a.index) == list(b.index) and len(a) == a.index.nunique() == 401  # every tick, 0 to 4 s
    for t in a.index:
        np.testing.assert_array_equal(np.stack(a[t]), np.stack(b[t]))
    log = [(t, list(v)) for t, v in streamed[["sim_time", EVENTS]].dropna().values]
    assert log == [(t, list(v)) for t, v in replayed[["sim_time", EVENTS]].dropna().values]
    assert [v for _, v in log] == [["agent 0: failed (hovers in place)"], ["run ended: duration"]]


# -- the option ---------------------------------------------------------------------------------
@pytest.mark.parametrize("value, expected", [
    ("off", None),
    ("spawn", live.Target("spawn", "rerun+http://127.0.0.1:9876/proxy")),
    ("spawn:9877", live.Target("spawn", "rerun+http://127.0.0.1:9877/proxy")),
    ("serve", live.Target("serve", "rerun+http://127.0.0.1:9876/proxy", 9090)),
    ("serve:9000", live.Target("serve", "rerun+http://127.0.0.1:9000/proxy", 9090)),
    ("serve:9000:9001", live.Target("serve", "rerun+http://127.0.0.1:9000/proxy", 9001)),
    ("connect", live.Target("connect", "rerun+http://127.0.0.1:9876/proxy")),
    ("connect:rerun+http://node7:9999/proxy", live.Target("connect", "rerun+http://node7:9999/proxy")),
])
def test_each_value_names_its_viewer(value, expected):
    assert api.load([*RUN, f"output.live={value}"]).config.output.live == value
    assert live.target(value) == expected


@pytest.mark.parametrize("value", ["on", "serve:0", "spawn:65536", "serve:9000:x", "connect:http://h:1/proxy",
                                   "connect:rerun+http://h/proxy"])
def test_a_bad_value_is_one_line_naming_the_option(value):
    with pytest.raises(ConfigError) as err:
        api.load([*RUN, f"output.live={value}"])
    assert err.value.lines == [
        "output.live: must be off, spawn[:PORT], serve[:PORT[:WEB_PORT]] or connect[:URL] with a port 1-65535 "
        f"and a URL rerun+http(s)://HOST:PORT/proxy (got {value!r})"]


def test_the_live_view_is_left_out_of_the_config_hash():
    from swarmscene.sweeps.records import DISPLAY_KEYS

    off = api.load(RUN).data
    served = api.load([*RUN, "output.live=serve"]).data
    assert served["output"]["live"] == "serve" and config_hash(served) == config_hash(off)
    assert "output.live" in DISPLAY_KEYS


# -- streaming ----------------------------------------------------------------------------------
def test_a_run_streams_the_replays_recording_while_it_is_simulated(sink, tmp_path):
    url, saved, proc = sink
    midway = {}

    def progress(sim):  # halfway (t = 2 s): the viewer already holds the frames up to now, none later
        if sim.step_count == 200:
            view.rec.flush()

            def arrived():
                frames = recordings_in(saved, tmp_path / "midway.rrd")
                midway.update(frames)
                return bool(frames) and max(f["sim_time"].max() for f in frames.values()).total_seconds() == 2.0

            wait_until(arrived)

    sim = api.build([*RUN, f"output.live=connect:{url}"])
    view = live.attach(sim)
    result = sim.run(progress=progress)
    rid, replayed = replay_of(sim, result, tmp_path)
    stop(proc)
    (streamed_id, streamed), = replay.read_recordings([saved]).items()
    assert streamed_id == rid == f"cem_six_vehicle-seed0-{config_hash(sim.scenario.data)[:12]}"
    (mid_id, mid), = midway.items()
    assert mid_id == rid and len(mid) == 201
    assert_same_run(streamed, replayed)
    # every entity of the replay, but CEM's exclusion circles (a_p is a metric: known at the end)
    assert set(replayed.columns) - set(streamed.columns) == {"/world/exclusion:LineStrips3D:colors",
                                                             "/world/exclusion:LineStrips3D:strips"}
    assert set(streamed.columns) <= set(replayed.columns)
    # a display only: the run's numbers are those of a run without it
    plain = api.build(RUN).run()
    np.testing.assert_array_equal(plain.trajectory["pos"], result.trajectory["pos"])
    assert {k: v for k, v in plain.metrics.items() if "time" not in k and "step_ms" not in k and "realtime" not in k} \
        == {k: v for k, v in result.metrics.items() if "time" not in k and "step_ms" not in k and "realtime" not in k}


def test_serve_runs_a_web_viewer_that_keeps_each_run_as_its_own_recording(tmp_path, capsys):
    """Two runs (two seeds, as two jobs of a sweep) served on free ports: one background server,
    started by the first and joined by the second; its web viewer's page answers; a viewer that
    connects after both runs receives both recordings, each the run's replay."""
    port, web = free_port(), free_port()
    value = f"serve:{port}:{web}"
    try:
        sim0, result0, _ = simulate(RUN, value)
        pid = live.SERVERS[port]
        sim1, result1, _ = simulate([*RUN, "seed=1"], value)
        assert live.SERVERS[port] == pid  # joined, not started twice
        err = capsys.readouterr().err.splitlines()
        page = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{port}%2Fproxy"
        assert err == [f"live view: open {page} (pid {pid}: stop it with kill {pid}); from another machine first: "
                       f"ssh -L {web}:127.0.0.1:{web} -L {port}:127.0.0.1:{port} HOST"]
        with urllib.request.urlopen(page, timeout=10) as response:
            assert response.status == 200 and b"Rerun" in response.read()
        saved = tmp_path / "late.rrd"
        late = viewer("--connect", f"rerun+http://127.0.0.1:{port}/proxy", "--save", str(saved))
        try:  # the server sends what it buffered (both runs), then keeps the stream open
            wait_until(lambda: sorted(agent_frames(f) for f in recordings_in(saved, tmp_path / "c.rrd").values())
                       [-2:] == [401, 401], seconds=60)
        finally:
            stop(late)
        received = replay.read_recordings([saved])
    finally:
        pid = live.SERVERS.pop(port, None)
        if pid is not None:
            import os

            os.kill(pid, signal.SIGTERM)  # the server this test started
    rid0, replayed0 = replay_of(sim0, result0, tmp_path / "0")
    rid1, replayed1 = replay_of(sim1, result1, tmp_path / "1")
    assert rid0 != rid1 and {rid0, rid1} <= set(received)
    assert_same_run(received[rid0], replayed0)
    assert_same_run(received[rid1], replayed1)


# -- when there is no live view, the run still completes ------------------------------------------
def test_connect_where_nothing_listens_is_one_line_and_the_run_completes(capsys):
    port = free_port()
    sim, result, view = simulate(RUN, f"connect:rerun+http://127.0.0.1:{port}/proxy")
    assert view is None and result.complete and result.metrics["steps"] == 400
    assert capsys.readouterr().err.splitlines() == [
        f"swarmscene: warning: output.live=connect:rerun+http://127.0.0.1:{port}/proxy: nothing listens at "
        f"127.0.0.1:{port} (start a viewer there with `rerun`, or use output.live=spawn or serve); the run goes on "
        "without a live view"]


def test_spawn_without_a_display_is_one_line_and_the_run_completes(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(live.sys, "platform", "linux")
    sim, result, view = simulate(RUN, f"spawn:{free_port()}")
    assert view is None and result.complete
    assert capsys.readouterr().err.splitlines() == [
        f"swarmscene: warning: output.live={sim.config.output.live}: no display here (DISPLAY and WAYLAND_DISPLAY "
        "are unset): on a headless node use output.live=serve; the run goes on without a live view"]


def test_a_viewer_that_exits_at_start_is_one_line_with_its_last_words(monkeypatch, capsys):
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(live, "rerun_command",
                        lambda: [live.sys.executable, "-c", "import sys; print('cannot open a window'); sys.exit(3)"])
    sim, result, view = simulate(RUN, f"spawn:{free_port()}")
    assert view is None and result.complete
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"swarmscene: warning: output.live={sim.config.output.live}: the Rerun viewer exited "
                           "(cannot open a window; its log: ")
    assert line.endswith(".log); the run goes on without a live view")


def test_without_the_rerun_extra_it_is_one_line(monkeypatch, capsys):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "rerun" else real(name, *a))
    sim, result, view = simulate(RUN, "serve")
    assert view is None and result.complete
    assert capsys.readouterr().err.splitlines() == [
        "swarmscene: warning: output.live=serve: needs the 'rerun' extra: pip install 'swarmscene[rerun]'; "
        "the run goes on without a live view"]


def test_a_viewer_lost_mid_run_ends_the_live_view_not_the_run(sink, capsys):
    url, _, proc = sink

    def lose(sim):
        if sim.step_count == 100:
            view.rec = None  # the stream broken: the next frame raises

    sim = api.build([*RUN, f"output.live=connect:{url}"])
    view = live.attach(sim)
    result = sim.run(progress=lose)
    assert result.complete and result.metrics["steps"] == 400 and view.broken
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == ("swarmscene: warning: output.live: the live view stopped (AttributeError: 'NoneType' object "
                       "has no attribute 'send_columns'); the run goes on")


# -- from the command line and in a sweep (api.extra_writers attaches the view) --------------------
def test_the_command_line_streams_its_run(sink, tmp_path):
    import sys

    url, saved, proc = sink
    run_dir = tmp_path / "run"
    done = subprocess.run([sys.executable, "-c", "from swarmscene.cli import main; main()", *RUN,
                           f"output.live=connect:{url}", "output.rerun=true", "output.summary=false",
                           f"hydra.run.dir={run_dir}"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"live view: streaming to {url}" in done.stderr.splitlines()
    stop(proc)
    (rid, streamed), = replay.read_recordings([saved]).items()
    (replay_id, replayed), = replay.read_recordings([run_dir / "replay.rrd"]).items()
    assert rid == replay_id
    assert_same_run(streamed, replayed)


def test_each_job_of_a_sweep_is_its_own_recording(sink, tmp_path):
    import json

    url, saved, proc = sink
    result = api.sweep({"seed": [0, 1]}, [*RUN, f"output.live=connect:{url}", "output.rerun=true"],
                       sweep_dir=tmp_path / "sweep")
    assert result.exit_status == 0 and not result.failed
    stop(proc)
    received = replay.read_recordings([saved])
    for job in ("0", "1"):
        manifest = json.loads((tmp_path / "sweep" / job / "manifest.json").read_text())
        (replay_id, replayed), = replay.read_recordings([tmp_path / "sweep" / job / "replay.rrd"]).items()
        assert replay_id == f"cem_six_vehicle-seed{job}-{manifest['config_hash'][:12]}"
        assert_same_run(received[replay_id], replayed)
    assert len(received) == 2
