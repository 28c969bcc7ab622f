"""Many worlds in one step: B runs of one composition, their physics stepped in one call.

A :class:`BatchSimulation` steps B :class:`~swarmscene.core.simulation.Simulation` objects tick by
tick. Each world keeps everything of its own: its seed and random streams, clock, events,
disturbances, plugin instances, observers and termination. What the worlds share is the physics
phase: their per-agent state lies along a world axis (:class:`~swarmscene.core.state.WorldBatch`,
each world's arrays are slices of (B, N, k) arrays), and the dynamics model's
:meth:`~swarmscene.core.plugin.Dynamics.step_batch` advances all of them at once. A model without a
batched form steps each world with its own instance (the default ``step_batch``), so every model
works in a batch; the other phases run world by world, in the order a single run runs them.

A world's tick is the single run's tick, phase by phase (``guide``, the physics sub-steps with the
wind before and the force phase after each ``step``, ``settle``), so a world of a batch equals its
single run bit for bit (tests/test_batch.py, every preset). A world that ends (its duration, the
mission complete, a collision that stops it, a non-finite state, a plugin's exception) is masked:
the batch is rebuilt over the others, which go on. A Ctrl-C ends every world between two ticks.

Timing metrics are the batch's: ``wall_time`` is the wall time of the whole batch up to the
world's end, and a tick's time is the batch's tick divided among its running worlds.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from . import interrupts
from .plugin import Dynamics
from .result import RunResult
from .simulation import Simulation
from .state import WorldBatch


@dataclass
class WorldOutcome:
    """One world's end: its result, and the plugin exception that stopped it (if one did)."""

    result: RunResult
    failure: Exception | None


class BatchSimulation:
    """B runs of one composition stepped together.

    Args:
        sims: the worlds, built (e.g. :func:`swarmscene.api.build`) from scenarios of the same
            composition: the same dynamics model, number of agents, guidance period and physics
            step (their seeds and any other option may differ). Each owns its plugin manager.

    Raises:
        ValueError: the worlds cannot share a physics step (the message names what differs).
    """

    def __init__(self, sims: Sequence[Simulation]) -> None:
        if not sims:
            raise ValueError("a batch needs at least one world")
        self.sims = list(sims)
        first = self.sims[0]
        for b, sim in enumerate(self.sims[1:], start=1):
            for what, value, expected in (
                ("dynamics", type(sim.dynamics), type(first.dynamics)),
                ("swarm.n", sim.world.n, first.world.n),
                ("clock.guidance_period", sim.guidance_period, first.guidance_period),
                ("physics step", sim.physics_step, first.physics_step),
            ):
                if value != expected:
                    raise ValueError(f"world {b} cannot share the batch's physics: its {what} is {value}, "
                                     f"world 0's {expected}")
        self.model = type(first.dynamics)
        self.outcomes: list[WorldOutcome | None] = [None] * len(self.sims)
        self._running: list[int] = []
        self._batch: WorldBatch | None = None
        self._wall_start = 0.0

    def run(self, progress: Callable[[BatchSimulation], None] | None = None) -> list[WorldOutcome]:
        """Run every world to its end; return their outcomes in the worlds' order.

        Args:
            progress: called after every tick of the batch (e.g. a progress line); must be cheap.

        A world's outcome is what its single run returns: ``Simulation.run``'s result, and the
        exception a plugin raised (``Simulation.run`` raises it as
        :class:`~swarmscene.core.raised.PluginRaised`; here it is kept, and the other worlds go on).
        """
        self._wall_start = time.perf_counter()
        self._running = list(range(len(self.sims)))
        for b in list(self._running):
            self._guarded(b, lambda sim: sim.hook.swarmscene_run_start(sim=sim.view))
        self._end_finished()
        while self._running:
            if interrupts.requested() is not None:  # between ticks, as a single run
                for b in self._running:
                    self.sims[b].stop_reason = "interrupted"
                self._end_finished()
                break
            try:
                self._tick()
            except KeyboardInterrupt:
                for b in self._running:
                    self.sims[b].stop_reason = "interrupted"
            self._end_finished()
            if progress is not None:
                progress(self)
        return [outcome for outcome in self.outcomes if outcome is not None]

    @property
    def running(self) -> int:
        """How many worlds are still running."""
        return len(self._running)

    # -- one tick of every running world -------------------------------------------------------
    def _tick(self) -> None:
        tick_start = time.perf_counter()
        self._each(lambda sim: sim.guide())
        sims = [self.sims[b] for b in self._running]
        if sims:
            batch = self._world_batch()
            batch.controlled()
            models = [sim.dynamics for sim in sims]
            dt = sims[0].physics_step
            for j in range(sims[0].substeps):
                self._each(_wind_of(j))
                self._physics(models, batch, dt)
                self._each(lambda sim: sim.push())
        self._each(lambda sim: sim.settle())
        share = (time.perf_counter() - tick_start) / max(len(self._running), 1)
        self._each(lambda sim: sim.ticked(share))

    def _physics(self, models: list[Dynamics], batch: WorldBatch, dt: float) -> None:
        """The dynamics step of every running world: the model's batched form, or world by world
        when it declines this batch. An exception stops every world it was stepping."""
        if len(models) != len(self._running) or len(models) == 1:  # a world ended in this sub-step's wind
            self._each(lambda sim: sim.dynamics.step(sim.world, dt))
            return
        try:
            done = self.model.step_batch(models, batch, dt)
        except Exception as exc:
            for b in list(self._running):
                self._stop(b, exc)
            return
        if done is NotImplemented:
            self._each(lambda sim: sim.dynamics.step(sim.world, dt))

    def _each(self, phase: Callable[[Simulation], object]) -> None:
        """A phase run world by world; a world whose phase raised is stopped as its single run."""
        for b in list(self._running):
            self._guarded(b, phase)

    def _guarded(self, b: int, phase: Callable[[Simulation], object]) -> None:
        try:
            phase(self.sims[b])
        except Exception as exc:
            self._stop(b, exc)

    def _stop(self, b: int, exc: BaseException) -> None:
        sim = self.sims[b]
        failure = sim.stopped_by(exc)
        self._finish(b, failure)

    # -- ends ------------------------------------------------------------------------------------
    def _end_finished(self) -> None:
        """Every world that has no tick left, or was asked to stop, ends now."""
        for b in list(self._running):
            if not self.sims[b].going():
                self._finish(b, None)

    def _finish(self, b: int, failure: Exception | None) -> None:
        sim = self.sims[b]
        self._running.remove(b)
        self._batch = None  # rebuilt over the worlds still running
        result, failure = sim.finish(time.perf_counter() - self._wall_start, failure)
        self.outcomes[b] = WorldOutcome(result, failure)

    def _world_batch(self) -> WorldBatch:
        """The running worlds' batch: built again after a world ended (or before the first tick)."""
        if self._batch is None or len(self._batch.worlds) != len(self._running):
            self._batch = WorldBatch([self.sims[b].world for b in self._running])
        return self._batch


def _wind_of(j: int) -> Callable[[Simulation], None]:
    """The wind phase of physics sub-step ``j``, as a phase of one world."""
    def wind(sim: Simulation) -> None:
        sim.blow(j)
    return wind


def lockstep(sims: Sequence[Simulation], batch: WorldBatch) -> None:
    """One tick of every world of ``sims`` together, their physics in one batched step: the
    phases of :meth:`BatchSimulation._tick` without its ends (an exception is raised as is). For a
    driver that decides itself when a world ends (the vector environment, swarmscene.env).

    Args:
        sims: the worlds, built as for :class:`BatchSimulation`.
        batch: ``WorldBatch([sim.world for sim in sims])``, kept while the worlds are the same.
    """
    for sim in sims:
        sim.guide()
    batch.controlled()
    first = sims[0]
    model, models, dt = type(first.dynamics), [sim.dynamics for sim in sims], first.physics_step
    for j in range(first.substeps):
        for sim in sims:
            sim.blow(j)
        if len(sims) == 1 or model.step_batch(models, batch, dt) is NotImplemented:
            for sim in sims:
                sim.dynamics.step(sim.world, dt)
        for sim in sims:
            sim.push()
    for sim in sims:
        sim.settle()

