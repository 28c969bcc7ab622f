"""The run summary printed by the command line, and the progress line for long runs."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any


def _fmt(value: Any, unit: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3g}{unit}"
    return f"{value}{unit}"


def verdicts(sim: Any, metrics: dict[str, Any]) -> list[tuple[str, bool, str]]:
    """(name, holds, detail) for the engine's safety conditions and every plugin's ``*_holds`` key."""
    safety = sim.config.safety
    out = [
        (
            "separation",
            metrics.get("collisions", 0) == 0,
            f"min {_fmt(metrics.get('min_separation'), ' m')} vs {safety.separation_limit} m",
        ),
        (
            "clearance",
            metrics.get("clearance_violations", 0) == 0,
            f"min {_fmt(metrics.get('min_clearance'), ' m')} vs {safety.clearance_limit} m",
        ),
        ("connectivity", bool(metrics.get("connected")), f"comm range {sim.config.comm.range} m"),
    ]
    for key in sorted(metrics):
        if key.endswith("_holds") and isinstance(metrics[key], bool):
            out.append((key, metrics[key], ""))
    return out


def summary_text(sim: Any, result: Any, run_dir: Path | None) -> str:
    m = result.metrics
    lines = [
        f"swarmscene: scenario {sim.config.name!r} ({sim.formation.name} / {sim.avoidance.name} / "
        f"{sim.dynamics.name})",
        f"  simulated {_fmt(m['duration'], ' s')} in {m['steps']} steps, {m['agents']} agents, "
        f"stopped by {m['stop_reason']}; real-time factor {_fmt(m['realtime_factor'], 'x')}",
        f"  min separation {_fmt(m.get('min_separation'), ' m')}, min clearance "
        f"{_fmt(m.get('min_clearance'), ' m')}, collisions {m.get('collisions', 0)}, "
        f"success {m.get('success')}",
    ]
    for name, holds, detail in verdicts(sim, m):
        lines.append(f"  {'OK  ' if holds else 'FAIL'} {name}" + (f" ({detail})" if detail else ""))
    if run_dir is not None:
        lines.append(f"  outputs: {run_dir}")
    return "\n".join(lines)


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
    def maybe(cls, mode: str, enabled: bool = True, delay: float | None = None) -> "Progress | None":
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
