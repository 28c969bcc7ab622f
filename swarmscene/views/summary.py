"""The run summary printed by the command line, and the progress line for long runs."""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path
from types import TracebackType
from typing import Any


def _fmt(value: Any, unit: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3g}{unit}"
    return f"{value}{unit}"


OK, FAIL, NA, MET, NOT_MET = "OK", "FAIL", "n/a", "met", "not met"
"""Verdict statuses: a condition that held or was violated, a check that does not apply to this run,
and a theorem's precondition (an assumption of a guarantee, not a safety outcome: a precondition
that is not met means the guarantee is not claimed, never that the run was unsafe)."""

PRECONDITION = "_precondition_met"
"""Plugin keys ending so are printed as preconditions (``met`` / ``not met``), keys ending in
``_holds`` as conditions (``OK`` / ``FAIL``: what was measured, never hidden). A plugin explains a
key's limit and scope with ``describe_verdict(key, metrics) -> str | None`` (a static method); a
detail starting ``n/a: `` prints the line as n/a (nothing to check in this run). The first
violation of ``<plugin>.<condition>_holds``, ``<plugin>.violations.<condition>.first_time`` /
``.agents``, is appended to its line. Keys a plugin lists in ``RENAMED_METRICS`` (old -> new, kept
in metrics.json for one release) are not printed."""

ENGINE_LIMITS = ("separation", "clearance", "keep_out")
"""The lines ``success`` counts, with the mission (core.simulation's default success; ``keep_out``
only when ``safety.keep_out`` is set, else it has no line)."""


Verdict = tuple[str, str, str]
"""(name, status, detail): status one of OK, FAIL, n/a, met, not met."""


def _first(metrics: dict[str, Any], prefix: str) -> str:
    """'; first at T s (agents ...)' for a condition violated in this run, from ``<prefix>.first_time``
    and ``<prefix>.agents`` (``violations.separation``, ``cem.violations.clearance``), else ''."""
    t = metrics.get(f"{prefix}.first_time")
    if t is None:
        return ""
    agents = metrics.get(f"{prefix}.agents") or []
    shown = ", ".join(str(a) for a in agents[:8]) + (f", ... ({len(agents)} in all)" if len(agents) > 8 else "")
    return f"; first at {t:.2f} s (agents {shown})"


def _plugins(sim: Any) -> list[Any]:
    return [p for p in (getattr(sim, "formation", None), getattr(sim, "avoidance", None),
                        getattr(sim, "dynamics", None)) if p is not None]


def _does_not_avoid(sim: Any) -> list[str]:
    """Names of the run's methods that declare ``avoids_collisions = False`` (boids, by design)."""
    return [p.name for p in _plugins(sim) if getattr(type(p), "avoids_collisions", True) is False]


def engine_verdicts(sim: Any, metrics: dict[str, Any]) -> list[Verdict]:
    """Separation, clearance, connectivity and (when ``safety.keep_out`` is set) the keep-out
    ellipsoid as core/monitors.py measures them, each line saying its limit and scope (the engine's
    keys keep their names; their scope is stated here)."""
    safety = sim.config.safety
    collisions = metrics.get("collisions", 0)
    detail = (f"min {_fmt(metrics.get('min_separation'), ' m')} vs {safety.separation_limit} m, all pairs "
              f"(failed vehicles included), sampled once per guidance tick; {collisions} pair(s) under the limit")
    detail += _first(metrics, "violations.separation")
    for name in _does_not_avoid(sim):
        detail += f"; {name} does not avoid collisions by design"
    out = [("separation", OK if collisions == 0 else FAIL, detail)]
    if metrics.get("min_clearance") is None:
        out.append(("clearance", NA, "no obstacles in this environment"))
    else:
        out.append(("clearance", OK if metrics.get("clearance_violations", 0) == 0 else FAIL,
                    f"min {_fmt(metrics.get('min_clearance'), ' m')} vs {safety.clearance_limit} m, every agent to "
                    f"every obstacle, once per guidance tick; {metrics.get('clearance_violations', 0)} agent(s) "
                    "under the limit" + _first(metrics, "violations.clearance")))
    out.append(("connectivity", OK if metrics.get("connected") else FAIL,
                f"communication graph connected, by range {sim.config.comm.range} m (line of sight not "
                "considered), every tick" + _first(metrics, "violations.connectivity")))
    keep_out = _keep_out_verdict(safety.keep_out, metrics)
    return out if keep_out is None else [*out, keep_out]


def _keep_out_verdict(radii: tuple[float, float, float] | None, metrics: dict[str, Any]) -> Verdict | None:
    """The keep-out ellipsoid's line (``safety.keep_out`` = ``radii``), or None when it is not set:
    a condition the scenario did not declare is not printed (as the floor's)."""
    if radii is None:
        return None
    conflicts = metrics.get("keep_out_conflicts") or 0
    nearest = metrics.get("min_keep_out")
    measured = f"min {_fmt(nearest)} vs 1" if nearest is not None else f"no pair within {max(radii):g} m"
    detail = (f"{measured}, ||E^-1 (p_i - p_j)|| with E = diag({', '.join(f'{r:g}' for r in radii)}) m, all pairs "
              f"(failed vehicles included), sampled once per guidance tick; {conflicts} pair(s) inside")
    return ("keep_out", OK if conflicts == 0 else FAIL, detail + _first(metrics, "violations.keep_out"))


def _describe(sim: Any, key: str, metrics: dict[str, Any]) -> str:
    """The first plugin detail for ``key`` (``describe_verdict``), or ''."""
    for plugin in _plugins(sim):
        describe = getattr(type(plugin), "describe_verdict", None)
        detail = describe(key, metrics) if describe is not None else None
        if detail:
            return detail
    return ""


def mission_verdict(sim: Any, metrics: dict[str, Any]) -> Verdict:
    """Whether the formation's mission completed (its ``complete``; None: it defines none)."""
    done = sim.mission_complete()  # after a landing: judged when the mission ended
    if metrics.get("phases.land_start") is not None:
        end, stop = metrics["phases.land_start"], "then the landing"
    else:
        end, stop = metrics.get("duration"), f"stopped by {metrics.get('stop_reason', 'duration')}"
    if done is None:
        return ("mission", NA, f"{sim.formation.name} sets no goal; {stop}")
    if done:
        return ("mission", OK, f"complete at {_fmt(end, ' s')} ({stop})")
    why = _describe(sim, "mission", metrics)
    return ("mission", FAIL, f"not complete when the run stopped at {_fmt(end, ' s')} "
            f"({stop})" + (f"; {why}" if why else ""))


def landing_verdicts(metrics: dict[str, Any]) -> list[Verdict]:
    """With ``swarm.land``: whether every healthy vehicle ended on the floor (core/phases.py)."""
    if "phases.airborne" not in metrics:
        return []
    airborne, landed = metrics["phases.airborne"], metrics["phases.landed"]
    detail = (f"{landed} healthy vehicle(s) on the floor at the end, {airborne} still in the air; the landing "
              f"began at {_fmt(metrics.get('phases.land_start'), ' s')}")
    return [("landing", OK if airborne == 0 else FAIL, detail)]


def plugin_verdicts(sim: Any, metrics: dict[str, Any]) -> list[Verdict]:
    """Every plugin's ``*_holds`` (OK / FAIL) and ``*_precondition_met`` (met / not met, or n/a when
    the plugin's detail says the theorem does not apply) key, with the plugin's own detail."""
    renamed: set[str] = set()
    for plugin in _plugins(sim):
        renamed.update(getattr(type(plugin), "RENAMED_METRICS", {}))
    out = []
    for key in sorted(metrics):
        value = metrics[key]
        if key in renamed or not isinstance(value, bool):
            continue
        if key.endswith(PRECONDITION):
            status = MET if value else NOT_MET
        elif key.endswith("_holds"):
            status = OK if value else FAIL
        else:
            continue
        detail = _describe(sim, key, metrics)
        if detail.startswith("n/a: "):  # the plugin says there is nothing to check in this run
            status, detail = NA, detail[len("n/a: "):]
        elif key.endswith("_holds"):
            plugin, condition = key[: -len("_holds")].rsplit(".", 1)
            detail += _first(metrics, f"{plugin}.violations.{condition}")
        out.append((key, status, detail))
    return out


def verdicts(sim: Any, metrics: dict[str, Any]) -> list[Verdict]:
    """(name, status, detail) for the engine's safety conditions, the mission and every plugin's
    conditions and preconditions, in the order the summary prints them."""
    return [*engine_verdicts(sim, metrics), mission_verdict(sim, metrics), *landing_verdicts(metrics),
            *plugin_verdicts(sim, metrics)]


def success_reason(metrics: dict[str, Any], lines: list[Verdict]) -> str:
    """What ``success`` measured (no engine limit violated, the mission complete) and why it is what
    it is; FAIL lines that ``success`` does not count (connectivity, a plugin's ``*_holds``) are named
    beside it, so that ``success True`` never reads as "every check passed"."""
    counted = (*ENGINE_LIMITS, "mission", "landing")
    if metrics.get("success"):
        mission = next(status for name, status, _ in lines if name == "mission")
        reason = "no engine limit violated, " + ("mission complete" if mission == OK else "no mission to complete")
    else:
        failed = [name for name, status, _ in lines if status == FAIL and name in counted]
        if metrics.get("stop_reason") in ("interrupted", "non_finite"):
            failed.append(f"stopped by {metrics['stop_reason']}")
        reason = "failed: " + ", ".join(failed) if failed else "failed (see the plugin's metrics)"
    uncounted = [name for name, status, _ in lines if status == FAIL and name not in counted]
    return reason + ("; not counted by success: FAIL " + ", ".join(uncounted) if uncounted else "")


def summary_text(sim: Any, result: Any, run_dir: Path | None) -> str:
    """The lines printed after a run: the scenario, the verdicts on its safety limits, its metrics
    and where its outputs are."""
    m = result.metrics
    if result.error is not None:  # it did not fly to its end: no verdict would be true of it
        where = f"; outputs up to then (marked failed) in {run_dir}" if run_dir is not None else ""
        return f"swarmscene: scenario {sim.config.name!r} failed: {result.error}{where}"
    lines = verdicts(sim, m)
    out = [
        f"swarmscene: scenario {sim.config.name!r} ({sim.formation.name} / {sim.avoidance.name} / "
        f"{sim.dynamics.name})",
        f"  simulated {_fmt(m['duration'], ' s')} in {m['steps']} steps, {m['agents']} agents, "
        f"stopped by {m['stop_reason']}; real-time factor {_fmt(m['realtime_factor'], 'x')}",
        f"  min separation {_fmt(m.get('min_separation'), ' m')}, min clearance "
        f"{_fmt(m.get('min_clearance'), ' m')}, collisions {m.get('collisions', 0)}, "
        f"success {m.get('success')} ({success_reason(m, lines)})",
    ]
    for name, status, detail in lines:
        out.append(f"  {status:<{len(NOT_MET)}} {name}" + (f": {detail}" if detail else ""))
    if run_dir is not None:
        out.append(f"  outputs: {run_dir}")
    return "\n".join(out)


def format_duration(seconds: float) -> str:
    """A short human duration: ``42 s``, ``3 min 05 s``, ``1 h 02 min``."""
    seconds = max(0.0, float(seconds))
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, sec = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {sec:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


class Progress:
    """A one-line progress display with the time left, for runs and long writes over ~2 s.

    The time left is the work remaining divided by the rate so far (simulated seconds per wall
    second for a run, frames per second for a write): ``remaining = (total - done) * elapsed / done``.
    """

    DELAY = 2.0
    """Seconds before the line first shows (short runs print nothing)."""
    WIDTH = 30
    """Characters of the bar."""

    def __init__(self, stream: Any = None, delay: float | None = None) -> None:
        self.stream = stream or sys.stderr
        self.delay = self.DELAY if delay is None else delay
        self.start = time.perf_counter()
        self.last = -1.0
        self.shown = False
        self.first: tuple[float, float] | None = None  # (done, elapsed) at a write's first item

    @classmethod
    def maybe(cls, mode: str, enabled: bool = True, delay: float | None = None) -> Progress | None:
        """A Progress when asked for (``on``), or for ``auto`` when stderr is a terminal and this
        is not a job of a Hydra multirun (parallel jobs would interleave their lines)."""
        if not enabled or mode == "off":
            return None
        if mode == "auto" and (not sys.stderr.isatty() or _in_multirun()):
            return None
        return cls(delay=delay)

    def line(self, done: float, total: float, text: str, elapsed: float,
             since: tuple[float, float] = (0.0, 0.0)) -> str:
        """The progress line (no carriage return) for ``done`` of ``total`` after ``elapsed`` s;
        the rate is measured from ``since`` = (done, elapsed) on (a write's set-up is not its rate)."""
        fraction = min(max(done / total, 0.0), 1.0) if total > 0 else 1.0
        filled = int(self.WIDTH * fraction)
        bar = "#" * filled + "-" * (self.WIDTH - filled)
        done0, elapsed0 = since
        if done > done0 and elapsed > elapsed0:
            left = f", {format_duration((total - done) * (elapsed - elapsed0) / (done - done0))} left"
        else:
            left = ""
        return f"  [{bar}] {text}{left} "

    def _show(self, text: str) -> None:
        self.stream.write("\r" + text)
        self.stream.flush()

    def _due(self) -> float | None:
        """Elapsed seconds when a new line is due (after the delay, at most 5 per second)."""
        now = time.perf_counter() - self.start
        if now < self.delay or now - self.last < 0.2:
            return None
        self.last, self.shown = now, True
        return now

    def __call__(self, sim: Any) -> None:
        """The run's line: simulated time, real-time factor, time left."""
        now = self._due()
        if now is None:
            return
        t, total = sim.world.t, sim.config.clock.duration
        self._show(self.line(t, total, f"t = {t:.1f}/{total:.1f} s, {t / now:.1f}x real time", now))

    def update(self, done: int, total: int, label: str) -> None:
        """A write's line: ``label done/total`` and the time left (the last item always shows)."""
        now = time.perf_counter() - self.start
        if self.first is None:
            self.first = (float(done), now)
        if now < self.delay or (done < total and now - self.last < 0.2):
            return
        self.last, self.shown = now, True
        self._show(self.line(done, total, f"{label} {done}/{total}", now, since=self.first))

    def close(self) -> None:
        """End the progress line (a newline) if one was shown."""
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()


def _in_multirun() -> bool:
    """True inside a job of a Hydra multirun (Hydra not imported: False)."""
    if "hydra" not in sys.modules:
        return False
    try:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        return HydraConfig.initialized() and HydraConfig.get().mode == RunMode.MULTIRUN
    except Exception:  # pragma: no cover - a Hydra without these names: no progress policy change
        return False


class RunWarnings:
    """The warnings raised during a run, held until it ends and then shown, each distinct one once.

    A run that stops on a non-finite state has already said so in one line naming the agent and the
    tick: numpy's floating-point warnings on the way there (``overflow encountered``, ``invalid
    value encountered``, ``divide by zero encountered``) only repeat it in less precise words, so
    they are dropped for such a run and shown for any other.
    """

    NUMERIC = ("overflow encountered", "invalid value encountered", "divide by zero encountered")

    def __enter__(self) -> RunWarnings:
        self._catch = warnings.catch_warnings(record=True)
        self.records = self._catch.__enter__()
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._catch.__exit__(kind, exc, tb)

    def show(self, failed: bool) -> None:
        """Show what was recorded (after :meth:`__exit__`), the numeric ones only if not ``failed``."""
        shown: set[tuple[type[Warning], str]] = set()
        for record in self.records:
            key = (record.category, str(record.message))
            numeric = issubclass(record.category, RuntimeWarning) and key[1].startswith(self.NUMERIC)
            if key in shown or (failed and numeric):
                continue
            shown.add(key)
            warnings.showwarning(record.message, record.category, record.filename, record.lineno)
