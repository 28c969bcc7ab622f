"""Live view: stream a run to a Rerun viewer while it is simulated (``output.live``; the rerun extra).

    swarmscene scenario=cem_six_vehicle output.live=spawn          # the native viewer, this machine
    swarmscene scenario=cem_six_vehicle output.live=serve          # a web viewer, for a headless node
    swarmscene ... output.live=connect:rerun+http://HOST:9876/proxy  # a viewer already running

Modes (``output.live``; :func:`target` reads the value, the config checks its grammar):

``off``                   no live view (the default).
``spawn[:PORT]``          the native Rerun viewer on this machine, listening on PORT (Rerun's 9876);
                          started in the background unless one already listens there, and left
                          running after the run (as ``rerun`` itself does), so a sweep's jobs and
                          later runs join it.
``serve[:PORT[:WEB_PORT]]``  a background Rerun server with its web viewer, bound to 127.0.0.1: gRPC
                          on PORT (9876), the viewer's page on WEB_PORT (9090). It outlives the run
                          and keeps what it was sent (up to Rerun's 1 GiB server buffer) for a
                          browser that connects later; reach it from another machine through an SSH
                          tunnel of both ports. Stop it with ``kill PID`` (its pid is printed).
``connect[:URL]``         a viewer or server that is already running (``rerun``, ``rerun
                          --serve-web``, another machine's), at URL (rerun+http://127.0.0.1:9876/proxy).

Every run is its own recording, with the replay's recording id (``replay.recording_id``:
``<name>-seed<seed>-<12 hex digits of the config hash>``) and application id, so a sweep's jobs
open side by side in one viewer instead of overwriting each other. The entities, their colours and
the layout are the replay's (:mod:`swarmscene.views.replay`): the static scene when the run starts, then
every guidance tick thinned to at most :data:`MAX_FRAMES` frames (the replay's own thinning) the
agents, bodies, trails, exclusion zones, comm edges and the separation and clearance series; the
failures and radio losses as they happen; at the end the first violation of each safety condition
and the stop reason.

A live view is a display: it changes no number of the run and is left out of the config hash
(``COSMETIC_KEYS``). When it cannot be had (the rerun extra is missing, no display for ``spawn``, a
viewer that does not start or a URL where nothing listens) one line on stderr says why and the run
goes on without it.
"""

from __future__ import annotations

import importlib.util
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any
from urllib.parse import quote, urlsplit

import numpy as np

from ..core.hookspecs import hookimpl

DEFAULT_PORT = 9876
"""Rerun's gRPC port."""
DEFAULT_WEB_PORT = 9090
"""Rerun's web viewer port."""
MAX_FRAMES = 600
"""Most frames streamed per run (every k-th guidance tick): the replay's thinning of a run."""
START_SECONDS = 15.0
"""How long a started viewer or server has to listen on its port."""
ALIVE_SECONDS = 1.0
"""... and to stay up once it does (a viewer without a display listens, then exits)."""
TRAIL_SECONDS = 3.0
"""Seconds of path drawn behind each agent (the replay's default)."""

SERVERS: dict[int, int] = {}
"""Port -> pid of each viewer or server this process started (left running after the run)."""
_ANNOUNCED: set[int] = set()


@dataclass(frozen=True)
class Target:
    """Where a run's live view goes: ``mode`` spawn / serve / connect, the gRPC ``url``, and for
    serve the web viewer's port."""

    mode: str
    url: str
    web_port: int | None = None

    @property
    def host(self) -> str:
        """The viewer server's host name (127.0.0.1 when the URL names none)."""
        return urlsplit(self.url).hostname or "127.0.0.1"

    @property
    def port(self) -> int:
        """The viewer server's port (``DEFAULT_PORT`` when the URL names none)."""
        return int(urlsplit(self.url).port or DEFAULT_PORT)

    @property
    def viewer_page(self) -> str | None:
        """The web viewer's address with the server to show (serve only)."""
        if self.web_port is None:
            return None
        return f"http://127.0.0.1:{self.web_port}/?url={quote(self.url, safe='')}"


def target(value: str) -> Target | None:
    """``output.live``'s value as a :class:`Target`; None for ``off`` (the grammar is checked by
    the config: core/config.py, ``LIVE_PATTERN``)."""
    mode, _, rest = value.partition(":")
    if mode == "off":
        return None
    if mode == "connect":
        return Target("connect", rest or f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy")
    ports = [int(p) for p in rest.split(":")] if rest else []
    port = ports[0] if ports else DEFAULT_PORT
    web = (ports[1] if len(ports) > 1 else DEFAULT_WEB_PORT) if mode == "serve" else None
    return Target(mode, f"rerun+http://127.0.0.1:{port}/proxy", web)


def listening(host: str, port: int, timeout: float = 0.5) -> bool:
    """Whether something accepts TCP connections at host:port."""
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def rerun_command() -> list[str]:
    """The Rerun viewer of the installed rerun-sdk (its ``rerun_cli`` binary: the same version as
    the SDK, whether or not the virtual environment's bin/ is on PATH)."""
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin:
        binary = Path(spec.origin).with_name("rerun")
        if binary.is_file() and os.access(binary, os.X_OK):
            return [str(binary)]
    return [sys.executable, "-m", "rerun"]


_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _last_line(log: Path) -> str:
    lines = [_ANSI.sub("", line).strip() for line in log.read_text(errors="replace").splitlines()]
    lines = [line for line in lines if line]
    return (lines[-1][:200] if lines else "no output") + f"; its log: {log}"


def start(where: Target) -> str | None:
    """Make sure a viewer (spawn) or server (serve) listens at ``where``: reuse one that does, else
    start one in the background (:data:`SERVERS`). None when one listens, else why not (a phrase)."""
    if listening("127.0.0.1", where.port):
        return None  # ours from an earlier run, another job's, or the user's own
    if where.mode == "spawn" and sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display here (DISPLAY and WAYLAND_DISPLAY are unset): on a headless node use output.live=serve"
    if where.mode == "serve":
        args = ["--serve-web", "--bind", "127.0.0.1", "--port", str(where.port),
                "--web-viewer-port", str(where.web_port)]
    else:
        args = ["--port", str(where.port), "--expect-data-soon"]
    fd, name = tempfile.mkstemp(prefix="swarmscene-rerun-", suffix=".log")  # private, never a planted link
    log = Path(name)
    with os.fdopen(fd, "wb") as out:
        proc = subprocess.Popen([*rerun_command(), *args], stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)  # outlives this run
    what = "viewer" if where.mode == "spawn" else "server"
    began, up = time.monotonic(), None
    while time.monotonic() - began < START_SECONDS:
        if proc.poll() is not None:  # exited: fine if another process (a parallel job) holds the port
            return None if listening("127.0.0.1", where.port) else f"the Rerun {what} exited ({_last_line(log)})"
        if up is None and listening("127.0.0.1", where.port):
            up = time.monotonic()
        if up is not None and time.monotonic() - up >= ALIVE_SECONDS:
            SERVERS[where.port] = proc.pid
            return None
        time.sleep(0.1)
    proc.terminate()
    return f"the Rerun {what} did not listen on port {where.port} within {START_SECONDS:g} s ({_last_line(log)})"


def _warn(value: str, why: str) -> None:
    print(f"swarmscene: warning: output.live={value}: {why}; the run goes on without a live view", file=sys.stderr)


def attach(sim: Any) -> LiveView | None:
    """Stream ``sim``'s run live as its ``output.live`` asks (module docstring): the observer,
    registered on the run's plugin manager before the run starts, or None (off, or a one-line
    warning on stderr when the view cannot be had)."""
    value = sim.config.output.live
    where = target(value)
    if where is None:
        return None
    if importlib.util.find_spec("rerun") is None:
        _warn(value, "needs the 'rerun' extra: pip install 'swarmscene[rerun]'")
        return None
    if where.mode == "connect":
        why = None if listening(where.host, where.port, timeout=2.0) else (
            f"nothing listens at {where.host}:{where.port} (start a viewer there with `rerun`, or use "
            "output.live=spawn or serve)")
    else:
        why = start(where)
    if why is not None:
        _warn(value, why)
        return None
    _announce(where)
    view = LiveView(sim, where.url)
    sim.pm.register(view, name="live_view")
    return view


def _announce(where: Target) -> None:
    """Once per port and process: where to look (the web viewer's page for serve)."""
    if where.port in _ANNOUNCED:
        return
    _ANNOUNCED.add(where.port)
    pid = SERVERS.get(where.port)
    by = f" (pid {pid}: stop it with kill {pid})" if pid is not None else ""
    if where.mode == "serve":
        print(f"live view: open {where.viewer_page}{by}; from another machine first: ssh -L "
              f"{where.web_port}:127.0.0.1:{where.web_port} -L {where.port}:127.0.0.1:{where.port} HOST",
              file=sys.stderr)
    else:
        print(f"live view: streaming to {where.url}{by}", file=sys.stderr)


class LiveView:
    """An observer that streams its run to a Rerun viewer (lifecycle hooks: core/hookspecs.py)."""

    def __init__(self, sim: Any, url: str) -> None:
        import rerun as rr

        from ..runs.outputs import config_hash
        from .plots import RunData, agent_colors
        from .replay import APPLICATION_ID, exclusion_radius, recording_id

        self.url = url
        self.every = max(1, sim.total_steps // MAX_FRAMES)  # the replay's thinning: <= ~600 frames
        self.trail = max(1, int(round(TRAIL_SECONDS / (sim.config.clock.guidance_period * self.every))))
        world, data = sim.world, sim.scenario.data
        # the run as the replay sees it (its first frame): the replay's functions draw from it
        self.run = RunData(config=data, t=np.array([float(world.t)]), pos=np.array(world.pos, float)[None],
                           vel=np.array(world.vel, float)[None], healthy=np.array(world.healthy)[None],
                           obstacles=list(sim.environment.obstacles), config_hash=config_hash(data))
        self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id(self.run))  # the replay's id
        self.palette = agent_colors(self.run.n)
        self.zone = exclusion_radius(data, {})  # cem's a_p is a metric: known at the end only, so none
        self.recent: list[np.ndarray] = []
        self.last_step = -1
        self.failed: set[int] = set()
        self.broken = False

    def _guard(self, action: Any, *args: Any) -> None:
        """Run one logging step; a failure ends the live view (one line), never the run."""
        if self.broken:
            return
        try:
            action(*args)
        except Exception as exc:  # noqa: BLE001 - a display must not stop a run
            self.broken = True
            print(f"swarmscene: warning: output.live: the live view stopped ({type(exc).__name__}: {exc}); "
                  "the run goes on", file=sys.stderr)

    # -- lifecycle hooks ----------------------------------------------------------------------
    @hookimpl
    def swarmscene_run_start(self, sim: Any) -> None:
        """Open the stream and send the static scene (a failure turns the live view off, not the run)."""
        self._guard(self._begin, sim)

    @hookimpl
    def swarmscene_step_end(self, sim: Any) -> None:
        """Every ``every``-th tick: send the frame."""
        if sim.step_count % self.every == 0:
            self._guard(self._frame, sim)

    @hookimpl
    def swarmscene_event(self, sim: Any, event: Any) -> None:
        """Send the event as a marker on the timeline."""
        self._guard(self._event, sim, event)

    @hookimpl(trylast=True)  # after the monitors have added their metrics
    def swarmscene_run_end(self, sim: Any, metrics: dict[str, Any]) -> None:
        """Send the last tick (when thinning skipped it) and the run's end lines, then disconnect."""
        self._guard(self._end, sim, metrics)

    # -- what is sent ---------------------------------------------------------------------------
    def _begin(self, sim: Any) -> None:
        import rerun as rr

        from .replay import blueprint, log_static

        self.rec.set_sinks(rr.GrpcSink(self.url), default_blueprint=blueprint(self.run))
        self.rec.send_recording_name(f"{self.run.name} seed {self.run.seed}")
        log_static(self.rec, self.run)
        self._frame(sim)

    def _frame(self, sim: Any) -> None:
        """The agents and the scene at the current tick (the replay's entities)."""
        from .replay import TIMELINE, log_agents, log_scene

        world = sim.world
        now = np.array(world.pos, float)
        self.recent = (self.recent + [now])[-(self.trail + 1):]
        quat = getattr(world, "quat", None)
        frame = replace(self.run, t=np.array([float(world.t)]), pos=now[None],
                        vel=np.array(world.vel, float)[None], healthy=np.array(world.healthy)[None],
                        quat=None if quat is None else np.array(quat, float)[None])
        log_agents(self.rec, frame, np.arange(1))
        self.rec.set_time(TIMELINE, duration=float(world.t))
        log_scene(self.rec, np.stack(self.recent), frame.healthy[0], self.zone, self.palette, frame.comm_range)
        self._safety(frame)
        self._failures(sim, float(world.t))
        self.last_step = sim.step_count

    def _safety(self, frame: Any) -> None:
        """Min separation and clearance now, with their limits (the replay's series)."""
        import rerun as rr

        from .plots import agent_clearance, nearest_neighbour

        for name, values, limit in (("separation", nearest_neighbour(frame), frame.min_separation_limit),
                                    ("clearance", agent_clearance(frame), frame.min_clearance_limit)):
            value = float(np.min(values))
            if np.isfinite(value):
                self.rec.log(f"safety/{name}/min", rr.Scalars(value))
                self.rec.log(f"safety/{name}/limit", rr.Scalars(limit))

    def _event(self, sim: Any, event: Any) -> None:
        """The event log's line, a marker on the separation series, and a failure marker for each
        vehicle the event failed (every kind but comm_loss), at the event's time."""
        import rerun as rr

        from .plots import nearest_neighbour
        from .replay import TIMELINE, event_text

        at = float(event.at)
        self.rec.set_time(TIMELINE, duration=at)
        self.rec.log("events", rr.TextLog(event_text(event.name, event.agents), level="WARN"))
        pos = np.array(sim.world.pos, float)[None]
        separation = float(np.min(nearest_neighbour(replace(self.run, pos=pos))))
        if np.isfinite(separation):
            self.rec.log("safety/separation/events", rr.Scalars(separation))
        self._failures(sim, at)

    def _failures(self, sim: Any, when: float) -> None:
        """A marker for each vehicle failed since the last look (replay.log_failure)."""
        from .replay import log_failure

        for agent in np.flatnonzero(~np.asarray(sim.world.healthy)):
            if int(agent) not in self.failed:
                self.failed.add(int(agent))
                log_failure(self.rec, int(agent), when, np.array(sim.world.pos[agent], float))

    def _end(self, sim: Any, metrics: dict[str, Any]) -> None:
        import rerun as rr

        from .replay import TIMELINE, end_events

        if self.last_step != sim.step_count:  # the last tick, when the thinning skipped it
            self._frame(sim)
        final = replace(self.run, t=np.array([float(sim.world.t)]), metrics=dict(metrics))
        for when, level, text in end_events(final):
            self.rec.set_time(TIMELINE, duration=when)
            self.rec.log("events", rr.TextLog(text, level=level))
        self.rec.flush()
        self.rec.disconnect()
