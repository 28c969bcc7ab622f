"""What a run needs of the machine: its estimated peak memory against what the machine has.

Checked by the validation pass (:func:`swarmscene.core.validation.validate`) before anything is
built, so a run that cannot fit is one config error, not a crash an hour in.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from .config import ScenarioConfig

AGENT_WORKING_BYTES = 16 * 1024
"""Estimated engine memory per agent besides the trajectory record: state arrays, the tick's
k-d trees and neighbour lists, plugin arrays (measured peak 15.4 and 16.5 KiB per agent at
N = 2 x 10^4 and 10^5: reynolds_flocking with ~80 neighbours each and potential avoidance)."""
BASE_WORKING_BYTES = 256 * 2**20
"""Estimated memory of the interpreter and the imported packages."""


def memory_checks(config: ScenarioConfig, dynamics: Any) -> list[str]:
    """The run's estimated peak memory against the machine's: one line when it does not fit.

    Estimate: :data:`BASE_WORKING_BYTES` + N x :data:`AGENT_WORKING_BYTES` + 8 bytes per tick
    (timing) + the trajectory frames held in memory (the whole record, or one chunk of
    ``output.trajectory_buffer_mb`` when it is streamed; see :mod:`swarmscene.core.recorder`).
    """
    need = estimated_memory(config, getattr(dynamics, "has_attitude", False))
    have = machine_memory()
    if have is None or need <= have:
        return []
    return [
        f"swarm.n: the run needs an estimated {need / 2**30:.3g} GiB of memory, the machine has "
        f"{have / 2**30:.3g} GiB (got swarm.n = {config.swarm.n}, "
        f"{config.clock.duration / config.clock.guidance_period:.3g} ticks, "
        f"output.trajectory_buffer_mb = {config.output.trajectory_buffer_mb})"
    ]


def estimated_memory(config: ScenarioConfig, has_attitude: bool) -> float:
    """Estimated peak memory of a run, bytes (see :func:`memory_checks`)."""
    n, out = config.swarm.n, config.output
    ticks = config.clock.duration / config.clock.guidance_period
    total = BASE_WORKING_BYTES + n * AGENT_WORKING_BYTES + 8.0 * ticks
    if out.trajectory:
        itemsize = 4 if out.float32 else 8
        frame = n * ((6 + (4 if has_attitude else 0)) * itemsize + 1)
        frames = ticks // out.trajectory_every + 1
        held = frames * frame
        streamed = out.trajectory_stream == "on" or (
            out.trajectory_stream == "auto" and held > out.trajectory_buffer_mb * 2**20
        )
        if streamed:
            held = max(1.0, min(frames, out.trajectory_buffer_mb * 2**20 // frame)) * frame
        total += held + 8.0 * frames
    return total


def machine_memory() -> int | None:
    """Memory the run may use, bytes: MemAvailable of /proc/meminfo, else physical memory
    (``os.sysconf``), else None (unknown: not checked)."""
    import os

    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None
