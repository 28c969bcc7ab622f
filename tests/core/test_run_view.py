"""Hooks and observers receive a narrow, read-only view of the run (core.run_view.RunView, issue #27):
what it holds reads through to the live run, setting anything raises, and reading another attribute
of the simulation warns for one release."""

from __future__ import annotations

import pytest

from swarmscene import api
from swarmscene.core.hookspecs import hookimpl
from swarmscene.plugin import RunView

VIEW = ("world", "sensing", "environment", "config", "t", "step_count", "total_steps", "has_attitude")


class Spy:
    """Keeps what each lifecycle hook received, and the view's values at that moment."""

    def __init__(self) -> None:
        self.seen: list[tuple[str, object, float, int]] = []

    def _keep(self, hook: str, sim) -> None:
        self.seen.append((hook, sim, sim.t, sim.step_count))

    @hookimpl
    def swarmscene_run_start(self, sim):
        self._keep("run_start", sim)

    @hookimpl
    def swarmscene_event(self, sim, event):
        self._keep("event", sim)

    @hookimpl
    def swarmscene_step_end(self, sim):
        self._keep("step_end", sim)

    @hookimpl
    def swarmscene_run_end(self, sim, metrics):
        self._keep("run_end", sim)


def test_every_lifecycle_hook_and_observer_gets_the_view_reading_the_live_run():
    sim = api.build(api.compose(["clock.duration=0.5", "events=lead_fails", "events.0.at=0.2"]))
    spy = Spy()
    sim.pm.register(spy)
    sim.run()
    hooks = [hook for hook, *_ in spy.seen]
    assert hooks[0] == "run_start" and hooks[-1] == "run_end" and "event" in hooks
    n, dt = sim.total_steps, sim.guidance_period
    assert hooks.count("step_end") == n == 5
    assert all(view is sim.view and isinstance(view, RunView) for _, view, *_ in spy.seen)
    steps = [(t, k) for hook, _, t, k in spy.seen if hook == "step_end"]
    assert steps == [(pytest.approx(dt * k), k) for k in range(1, n + 1)]  # live, not a snapshot
    view = sim.view
    assert view.world is sim.world and view.sensing is sim.sensing and view.environment is sim.environment
    assert view.config is sim.config and view.t == sim.world.t == pytest.approx(0.5)
    assert (view.step_count, view.total_steps, view.has_attitude) == (n, n, sim.dynamics.has_attitude)


def test_observers_are_built_with_the_view():
    built = []

    class Observer:
        def __init__(self, sim):
            built.append(sim)

    sim = api.build(api.compose(["clock.duration=0.1"]))
    from swarmscene.core.simulation import Simulation

    again = Simulation(sim.scenario, api.plugins()[0], [Observer])
    assert len(built) == 1 and built[0] is again.view and isinstance(built[0], RunView)


def test_the_view_is_read_only_and_request_stop_reaches_the_run():
    sim = api.build(api.compose(["clock.duration=1.0"]))
    for name in (*VIEW, "formation", "anything"):
        with pytest.raises(AttributeError, match=f"a hook's view of the run is read-only \\(cannot set '{name}'\\)"):
            setattr(sim.view, name, None)
    sim.view.request_stop("a test asked")
    result = sim.run()
    assert sim.step_count == 0 and result.stop_reason == "a test asked"  # asked before the first tick


def test_another_attribute_of_the_simulation_is_refused_in_one_line():
    sim = api.build(api.compose(["clock.duration=0.1"]))
    with pytest.raises(AttributeError, match=r"^swarmscene: a hook read sim\.formation, which is not part of the "
                       r"run's view \(world, sensing, .*\); refused since 0\.6\.0: read what you need from the "
                       r"view, or take it at construction") as raised:
        sim.view.formation  # noqa: B018 (the access is the test)
    assert "\n" not in str(raised.value)
    with pytest.raises(AttributeError, match="sim.no_such_thing"):
        sim.view.no_such_thing  # noqa: B018
