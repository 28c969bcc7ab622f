"""Many worlds in one step: B runs of one composition, their controllers and physics stepped in one call.

A :class:`BatchSimulation` steps B :class:`~swarmscene.core.simulation.Simulation` objects tick by
tick. Each world keeps everything of its own: its seed and random streams, clock, events,
disturbances, plugin instances, observers and termination. What the worlds share are the
controller and physics phases: their per-agent state lies along a world axis
(:class:`~swarmscene.core.state.WorldBatch`, each world's arrays are slices of (B, N, k) arrays),
the formation's :meth:`~swarmscene.core.plugin.Formation.setpoints_batch` plans every world's
setpoints at once, the avoidance method's :meth:`~swarmscene.core.plugin.Avoidance.adjust_batch`
adjusts them at once, the dynamics model's :meth:`~swarmscene.core.plugin.Dynamics.control_batch`
latches every world's commands at once, its :meth:`~swarmscene.core.plugin.Dynamics.step_batch`
advances all of them at once. A phase's batched answer given as one
:class:`~swarmscene.core.setpoint.SetpointBatch` is handed on to the next as it is. A plugin
without batched forms plans, adjusts, controls and steps each world with its own instance (the
defaults), so every plugin works in a batch; the other phases run world by world, in the order a
single run runs them.

A world's tick is the single run's tick, phase by phase (``perceived``: events and sensing; the
formation; ``adjust``, ``control``, the physics sub-steps with the wind before and the force phase
after each ``step``, ``settle_world``, the observers): between two phases of a world run only
the other worlds' same phase, which share nothing with it, so a world of a batch equals its single
run bit for bit (tests/test_batch.py, every preset). Between the last two, the worlds' new
snapshots get their first queries answered in one pass (:func:`~swarmscene.core.prefetch.prefetch`:
the small worlds' pairs, closest pair and complete-graph test, and "no obstacle in range"): the
values their own queries would compute.
:class:`BatchSimulation` and :func:`lockstep` step their worlds with the same function,
:func:`_step`. A world that ends (its duration, the mission complete, a collision that stops it,
a non-finite state, a plugin's exception) is masked: the batch is rebuilt over the others, which
go on. A Ctrl-C ends every world between two ticks.

Timing metrics are the batch's: ``wall_time`` is the wall time of the whole batch up to the
world's end, and a tick's time is the batch's tick divided among its running worlds.
"""

from __future__ import annotations

import operator
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, cast

import numpy as np

from . import interrupts
from .disturbances import Disturbances, Perceived
from .disturbances.base import Disturbance
from .plugin import Dynamics
from .prefetch import prefetch
from .result import RunResult
from .setpoint import SetpointBatch, Setpoints
from .simulation import Simulation
from .state import WorldBatch, WorldState


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
        _step(self)
        share = (time.perf_counter() - tick_start) / max(len(self._running), 1)
        self._each(lambda sim: sim.ticked(share))

    # what _step asks of the worlds it steps (lockstep's _Plain answers the same)
    def _sims(self) -> list[Simulation]:
        """The running worlds, in the batch's order."""
        return [self.sims[b] for b in self._running]

    def _count(self) -> int:
        return len(self._running)

    def _stop_all(self, exc: Exception) -> None:
        """A batched form raised: every world it was working on stops with its exception."""
        for b in list(self._running):
            self._stop(b, exc)

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


class _Worlds(Protocol):
    """What :func:`_step` asks of the worlds it steps: a batch's running worlds
    (:class:`BatchSimulation`, a world's exception ends that world) or :func:`lockstep`'s
    (an exception is raised as is)."""

    model: type[Dynamics]

    def _sims(self) -> list[Simulation]: ...

    def _count(self) -> int: ...

    def _each(self, phase: Callable[[Simulation], object]) -> None: ...

    def _world_batch(self) -> WorldBatch: ...

    def _stop_all(self, exc: Exception) -> None: ...


def _step(worlds: _Worlds) -> None:
    """One tick of every running world: each world's events and sensing
    (:meth:`~swarmscene.core.simulation.Simulation.perceived`), the formation of all of them
    (:meth:`~swarmscene.core.plugin.Formation.setpoints_batch`), the avoidance of all of them
    (:meth:`~swarmscene.core.plugin.Avoidance.adjust_batch`), the controllers of all of them
    (:meth:`~swarmscene.core.plugin.Dynamics.control_batch`), the physics sub-steps (each world's
    wind, :meth:`~swarmscene.core.plugin.Dynamics.step_batch`, each world's forces), each world's
    ``settle_world``, the first queries of the worlds' new snapshots in one pass
    (:func:`~swarmscene.core.prefetch.prefetch`), each world's observers. A world's phases
    run in its single run's order; what runs between two phases of a world is only the other
    worlds' same phase."""
    perceived: dict[int, tuple[WorldState, Perceived | None, Setpoints | None]] = {}
    worlds._each(lambda sim: perceived.__setitem__(id(sim), sim.perceived()))
    planned = _formation(worlds, perceived)
    guided = _adjust(worlds, perceived, planned)
    if worlds._count():
        _control(worlds, perceived, guided)
    sims = worlds._sims()
    if sims:
        batch = worlds._world_batch()
        batch.controlled()
        dt = sims[0].physics_step
        for j in range(sims[0].substeps):
            _wind(worlds, j)
            _physics(worlds, [sim.dynamics for sim in sims], batch, dt)
            worlds._each(lambda sim: sim.push())
    worlds._each(lambda sim: sim.settle_world())
    prefetch([sim.sensing for sim in worlds._sims()])
    worlds._each(lambda sim: sim.observe())


class _Answers:
    """A guidance phase's setpoints of every world (the formation's, the avoidance's): each
    world's own record, or its place in the one :class:`SetpointBatch` a batched form answered
    with, whose records are made only when one is asked for (making them costs ~1.4 us a world,
    which a batch of 4,096 one-drone worlds would pay every tick for nothing when the next phase
    takes the batch whole)."""

    def __init__(self) -> None:
        self.records: dict[int, Setpoints] = {}
        self.batch: SetpointBatch | None = None
        self._sims: list[Simulation] = []
        self._place: dict[int, int] = {}

    def answer(self, sims: list[Simulation], done: Sequence[Setpoints]) -> None:
        """A batched form's answer for ``sims``: a :class:`SetpointBatch` kept whole, a list as records."""
        if isinstance(done, SetpointBatch):
            self.batch, self._sims = done, sims
            self._place = {id(sim): b for b, sim in enumerate(sims)}
        else:
            self.records.update(zip(map(id, sims), done, strict=True))

    def __contains__(self, sim: Simulation) -> bool:
        return id(sim) in self.records or id(sim) in self._place

    def of(self, sim: Simulation) -> Setpoints:
        """World ``sim``'s setpoints."""
        record = self.records.get(id(sim))
        return record if record is not None else cast(SetpointBatch, self.batch)[self._place[id(sim)]]

    def handed(self, sims: list[Simulation]) -> Sequence[Setpoints]:
        """The setpoints of ``sims`` for the next phase's batched form: the :class:`SetpointBatch`
        itself where it answered for exactly these worlds (none stopped since, none taking off or
        landing), else their records in a list."""
        if self.batch is not None and len(self._sims) == len(sims) and all(map(operator.is_, self._sims, sims)):
            return self.batch
        return [self.of(sim) for sim in sims]


def _formation(worlds: _Worlds, perceived: dict[int, tuple[WorldState, Perceived | None, Setpoints | None]]
               ) -> _Answers:
    """The formation of every running world, after its events and sensing: what each world's
    avoidance is handed (a take-off's or landing's setpoints as they are). The worlds flying one
    formation method are asked by its batched form; the others, and all of them when it has none
    (the default returns ``NotImplemented``) or declines this batch, world by world, so that a
    world whose ``setpoints`` raises stops alone. An exception of the batched form stops every
    world."""
    planned = _Answers()
    sims = []
    for sim in worlds._sims():
        _, view, phase = perceived[id(sim)]
        if view is None:
            planned.records[id(sim)] = cast(Setpoints, phase)
        else:
            sims.append(sim)
    seen = [cast(Perceived, perceived[id(sim)][1]) for sim in sims]
    done = _batched_form(worlds, sims, lambda sim: sim.formation, "setpoints_batch", "setpoints",
                         lambda method: method.setpoints_batch([sim.formation for sim in sims],
                                                               [p.formation_world for p in seen],
                                                               [p.formation_sensing for p in seen]))
    if done is not NotImplemented:
        planned.answer(sims, cast("Sequence[Setpoints]", done))

    def formation(sim: Simulation) -> None:
        if sim not in planned:
            p = cast(Perceived, perceived[id(sim)][1])
            planned.records[id(sim)] = sim.formation.setpoints(p.formation_world, p.formation_sensing)

    worlds._each(formation)
    return planned


def _batched_form(worlds: _Worlds, sims: list[Simulation], instance: Callable[[Simulation], object], batched: str,
                  single: str, call: Callable[[Any], object]) -> object:
    """A phase's batched form (``call(method)``) over ``sims`` (the worlds flying their
    formation), when their instances share one class whose ``batched`` form was written for its
    ``single`` one: its answer, checked to hold one record per world; ``NotImplemented`` where
    there is no batched form to ask, it declined, or it raised (every world is then stopped with
    its exception)."""
    method = type(instance(sims[0])) if sims else None
    if (method is None or len(sims) < 2 or not all(type(instance(sim)) is method for sim in sims)
            or not written_for(method, batched, single)):
        return NotImplemented
    try:
        done = call(method)
        if done is not NotImplemented and len(cast("Sequence[Setpoints]", done)) != len(sims):
            raise ValueError(f"{method.__name__}.{batched} returned {len(cast('Sequence', done))} setpoints "
                             f"for {len(sims)} worlds")
    except Exception as exc:
        worlds._stop_all(exc)
        return NotImplemented
    return done


def _adjust(worlds: _Worlds, perceived: dict[int, tuple[WorldState, Perceived | None, Setpoints | None]],
            planned: _Answers) -> _Answers:
    """The avoidance of every running world, after its formation: what each world's controller
    reads. The worlds flying their formation (not a take-off or landing) with one avoidance
    method are adjusted by its batched form, handed the formation's answer
    (:meth:`_Answers.handed`); the others, and all of them when the method has none (the default
    returns ``NotImplemented``) or declines this batch, world by world, so that a world whose
    ``adjust`` raises stops alone. An exception of the batched form stops every world."""
    guided = _Answers()
    sims = [sim for sim in worlds._sims() if perceived[id(sim)][1] is not None]
    seen = [cast(Perceived, perceived[id(sim)][1]) for sim in sims]
    done = _batched_form(worlds, sims, lambda sim: sim.avoidance, "adjust_batch", "adjust",
                         lambda method: method.adjust_batch([sim.avoidance for sim in sims], [p.world for p in seen],
                                                            [p.sensing for p in seen], planned.handed(sims)))
    if done is not NotImplemented:
        guided.answer(sims, cast("Sequence[Setpoints]", done))

    def adjust(sim: Simulation) -> None:
        if sim not in guided:
            p, sp = perceived[id(sim)][1], planned.of(sim)
            guided.records[id(sim)] = sp if p is None else sim.avoidance.adjust(p.world, p.sensing, sp)

    worlds._each(adjust)
    return guided


def _control(worlds: _Worlds, perceived: dict[int, tuple[WorldState, Perceived | None, Setpoints | None]],
             guided: _Answers) -> None:
    """The controllers of every running world, reading their agents' own estimates and the
    avoidance's answer (:meth:`_Answers.handed`): the model's batched form, or world by world when
    it has none (the default :meth:`~swarmscene.core.plugin.Dynamics.control_batch`, run here so
    that a world whose ``control`` raises stops alone), declines this batch, or leaves some of its
    worlds (returns their places in the batch). An exception of the batched form stops every world
    it was controlling."""
    sims = worlds._sims()
    left: set[int] | None = None  # ids of the worlds the engine controls one by one; None: all
    if len(sims) > 1 and has_batched_control(worlds.model):
        try:
            done = worlds.model.control_batch([sim.dynamics for sim in sims], worlds._world_batch(),
                                              [perceived[id(sim)][0] for sim in sims], guided.handed(sims))
            if done is not NotImplemented:
                left = {id(sims[b]) for b in left_places(done, len(sims), worlds.model)}
        except Exception as exc:
            worlds._stop_all(exc)
            return
    worlds._each(lambda sim: sim.dynamics.control(perceived[id(sim)][0], guided.of(sim))
                 if left is None or id(sim) in left else None)


def left_places(done: object, count: int, model: type) -> list[int]:
    """The worlds a ``control_batch`` left to their own ``control``: none for ``None``, else the
    places it returned (integers in ``range(count)``); anything else is the model's error."""
    if done is None:
        return []
    places = list(cast("Sequence[int]", done)) if isinstance(done, (list, tuple)) else None
    if places is None or not all(isinstance(b, int) and 0 <= b < count for b in places):
        raise ValueError(f"{model.__name__}.control_batch returned {done!r}: None, NotImplemented or the "
                         f"places (0..{count - 1}) of the worlds it left to their own control")
    return places


def _physics(worlds: _Worlds, models: list[Dynamics], batch: WorldBatch, dt: float) -> None:
    """The dynamics step of every running world: the model's batched form, or world by world
    when it declines this batch. An exception of the batched form stops every world it was stepping."""
    if (len(models) != worlds._count() or len(models) == 1  # a world ended in this sub-step's wind
            or not written_for(worlds.model, "step_batch", "step")):
        worlds._each(lambda sim: sim.dynamics.step(sim.world, dt))
        return
    try:
        done = worlds.model.step_batch(models, batch, dt)
    except Exception as exc:
        worlds._stop_all(exc)
        return
    if done is NotImplemented:
        worlds._each(lambda sim: sim.dynamics.step(sim.world, dt))


def has_batched_control(model: type[Dynamics]) -> bool:
    """Whether ``model`` overrides :meth:`~swarmscene.core.plugin.Dynamics.control_batch` (else the
    engine controls its worlds one by one, which is what the default does) for its own ``control``
    (:func:`written_for`)."""
    return (getattr(model.control_batch, "__func__", None) is not getattr(Dynamics.control_batch, "__func__", None)
            and written_for(model, "control_batch", "control"))


def written_for(cls: type, batched: str, single: str) -> bool:
    """Whether ``cls``'s batched form (``adjust_batch``, ``control_batch``, ``step_batch``) was
    written for the per-world form ``single`` it has: the class that defines the batched form
    defines ``single`` too, or inherits it. A subclass that overrides ``control`` alone (a plugin
    deriving from the double integrator) would otherwise have its worlds flown by its base's
    batched ``control``, not by its own; its worlds run their own ``single`` instead."""
    owner = next(k for k in cls.__mro__ if batched in vars(k))
    return issubclass(owner, next(k for k in cls.__mro__ if single in vars(k)))


def _wind(worlds: _Worlds, j: int) -> None:
    """The wind phase of physics sub-step ``j`` of every running world: the wind models whose
    class has a batched form (:meth:`~swarmscene.core.disturbances.base.Disturbance.air_batch`)
    asked for all worlds at once (:func:`airs_together`), the rest and each world's sums, forces
    and records world by world. An exception of a batched form stops every world. Nothing runs
    where no world declares a wind or a force model (most batches): their ``blow`` does nothing."""
    blowing = [sim for sim in worlds._sims() if sim.disturbances.blows]
    if not blowing:
        return
    sims = [sim for sim in blowing if sim.disturbances.has_wind]
    given: dict[int, list[np.ndarray]] = {}
    times = {sim.wind_time(j) for sim in sims}
    if len(sims) > 1 and len(times) == 1:
        try:
            airs = airs_together([sim.disturbances for sim in sims], [sim.world for sim in sims], times.pop())
        except Exception as exc:
            worlds._stop_all(exc)
            return
        given = dict(zip(map(id, sims), airs, strict=True))
    worlds._each(lambda sim: sim.blow(j, given.get(id(sim), ())))


def airs_together(sets: Sequence[Disturbances], worlds: Sequence[WorldState], t: float) -> list[list[np.ndarray]]:
    """The airs at ``t`` of B worlds' wind models (``sets``: each world's declared models, the
    same classes in the same order), model by model while its class answers for all B instances
    (``air_batch``, written for its ``air``: :func:`written_for`): one list per world, as long as
    the models answered (the rest are asked world by world, :meth:`Disturbances.blow`); empty
    lists where the worlds' wind models differ."""
    airs: list[list[np.ndarray]] = [[] for _ in sets]
    kinds = {tuple(type(model) for model in cast("list[Disturbance]", models.winds)) for models in sets}
    if len(kinds) != 1:
        return airs
    for k, cls in enumerate(kinds.pop()):
        if not written_for(cls, "air_batch", "air"):
            break
        done = cls.air_batch([models.winds[k] for models in sets], worlds, t)
        if done is NotImplemented:
            break
        if len(done) != len(sets):
            raise ValueError(f"{cls.__name__}.air_batch returned {len(done)} airs for {len(sets)} worlds")
        for world_airs, air in zip(airs, done, strict=True):
            world_airs.append(air)
    return airs


class _Plain:
    """:func:`lockstep`'s worlds: all of them, every phase raising what it raises."""

    def __init__(self, sims: Sequence[Simulation], batch: WorldBatch) -> None:
        self.sims, self.batch = list(sims), batch
        self.model = type(self.sims[0].dynamics)

    def _sims(self) -> list[Simulation]:
        return self.sims

    def _count(self) -> int:
        return len(self.sims)

    def _each(self, phase: Callable[[Simulation], object]) -> None:
        for sim in self.sims:
            phase(sim)

    def _world_batch(self) -> WorldBatch:
        return self.batch

    def _stop_all(self, exc: Exception) -> None:
        raise exc


def lockstep(sims: Sequence[Simulation], batch: WorldBatch) -> None:
    """One tick of every world of ``sims`` together, their controllers and physics in one batched
    call each: the phases of :meth:`BatchSimulation._tick` without its ends (an exception is
    raised as is). For a driver that decides itself when a world ends (the vector environment,
    swarmscene.env).

    Args:
        sims: the worlds, built as for :class:`BatchSimulation`.
        batch: ``WorldBatch([sim.world for sim in sims])``, kept while the worlds are the same.
    """
    _step(_Plain(sims, batch))
