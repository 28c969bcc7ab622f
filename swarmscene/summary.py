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
            f"min {_fmt(metrics.get('min_separation'), ' m')} vs {safety.min_separation} m",
        ),
        (
            "clearance",
            metrics.get("clearance_violations", 0) == 0,
            f"min {_fmt(metrics.get('min_clearance'), ' m')} vs {safety.min_clearance} m",
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


class Progress:
    """A one-line progress display (simulated time, real-time factor) for runs over ~2 s."""

    DELAY = 2.0

    def __init__(self, stream: Any = None) -> None:
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()
        self.last = 0.0
        self.shown = False

    @classmethod
    def maybe(cls, mode: str, enabled: bool = True) -> "Progress | None":
        """A Progress when asked for (``on``), or for ``auto`` when stderr is a terminal."""
        if not enabled or mode == "off":
            return None
        if mode == "auto" and not sys.stderr.isatty():
            return None
        return cls()

    def __call__(self, sim: Any) -> None:
        now = time.perf_counter() - self.start
        if now < self.DELAY or now - self.last < 0.2:
            return
        self.last, self.shown = now, True
        t, total = sim.world.t, sim.config.clock.duration
        width = 30
        done = int(width * min(t / total, 1.0))
        bar = "#" * done + "-" * (width - done)
        self.stream.write(f"\r  [{bar}] t = {t:.1f}/{total:.1f} s, {t / now:.1f}x real time ")
        self.stream.flush()

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
