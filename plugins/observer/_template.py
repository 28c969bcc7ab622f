"""Template of an observer (a monitor, a metric, a recorder): copy this file, rename, fill in.

A copy runs as is: list your module under the ``swarmscene`` entry-point group of your package.
Every registered observer runs in every run (it is not chosen); it is built as ``cls(sim)`` for
each run, so its state never leaks between runs. It only reads the run (``sim.world``,
``sim.sensing``, ``sim.config``) through the lifecycle hooks and adds metrics under its own prefix.
Check it with ``swarmscene.testing.check_observer(MyObserver)`` in your tests.
"""

from __future__ import annotations

from swarmscene.plugin import hookimpl


class MyObserver:
    """Counts the guidance ticks at which some pair of agents is closer than twice the limit."""

    def __init__(self, sim):
        self.limit = 2.0 * sim.config.safety.separation_limit  # m
        self.close_ticks = 0

    @hookimpl
    def swarmscene_step_end(self, sim):
        distance, _ = sim.sensing.nearest  # the tick's shared k-d tree: each agent's nearest other
        self.close_ticks += int((distance < self.limit).any())

    @hookimpl
    def swarmscene_run_end(self, sim, metrics):
        metrics["my_observer.close_ticks"] = self.close_ticks  # under its own prefix


@hookimpl
def swarmscene_register_observers(register):
    register(MyObserver)
