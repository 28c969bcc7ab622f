"""Simulation._step_end: the step-end observers called as pluggy calls them (same order, the same
implementations, one registered meanwhile included), and pluggy itself where a wrapper or a monitor
needs it."""

from __future__ import annotations

from swarmscene import api
from swarmscene.core.hookspecs import hookimpl


class Recorder:
    def __init__(self, name: str, log: list) -> None:
        self.name, self.log = name, log

    @hookimpl
    def swarmscene_step_end(self, sim):
        self.log.append((self.name, sim.step_count))


class NoArgs:
    def __init__(self, log: list) -> None:
        self.log = log

    @hookimpl
    def swarmscene_step_end(self):
        self.log.append(("no-args", None))


def small_sim():
    return api.build(api.compose(["clock.duration=1.0"]))


def test_the_observers_run_in_pluggys_order_and_a_late_registration_takes_part():
    sim, log = small_sim(), []
    first, second = Recorder("first", log), Recorder("second", log)
    sim.pm.register(first)
    sim.pm.register(second)
    sim.step()
    assert log == [("second", 1), ("first", 1)]  # last registered first, as pluggy calls them
    order = [i.plugin for i in reversed(sim.hook.swarmscene_step_end.get_hookimpls())]  # pluggy's
    assert order.index(second) < order.index(first)
    sim.pm.register(NoArgs(log))
    log.clear()
    sim.step()
    assert log == [("no-args", None), ("second", 2), ("first", 2)]
    sim.pm.unregister(first)
    log.clear()
    sim.step()
    assert log == [("no-args", None), ("second", 3)]


def test_a_wrapper_or_a_monitor_leaves_the_call_to_pluggy():
    sim, log = small_sim(), []

    class Wrapper:
        @hookimpl(wrapper=True)
        def swarmscene_step_end(self, sim):
            log.append("before")
            yield
            log.append("after")

    sim.pm.register(Recorder("plain", log))
    sim.pm.register(Wrapper())
    sim.step()
    assert log == ["before", ("plain", 1), "after"]
    plain, log = small_sim(), []
    plain.pm.register(Recorder("plain", log))
    traced = []
    undo = plain.pm.add_hookcall_monitoring(lambda name, impls, kw: traced.append(name), lambda *a: None)
    plain.step()
    undo()
    assert "swarmscene_step_end" in traced and log == [("plain", 1)]  # the monitor saw the call
