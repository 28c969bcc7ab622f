"""swarmscene: a declarative scenario engine for quadrotor swarms.

Compose a scenario from Hydra config groups, run it, read back metrics and safety verdicts::

    from swarmscene import api
    result = api.run(["scenario=cem_six_vehicle", "avoidance.K=1"])
    result.metrics["min_separation"]

The engine lives in :mod:`swarmscene.core`, the methods' numerics in :mod:`swarmscene.methods`, the
algorithms' plugins in :mod:`swarmscene.plugins`, the config tree in :mod:`swarmscene.scenarios`.
This package is the application around them, in rooms with one import direction
(swarmscene/README.md; ``tests/test_layout.py`` holds it): the public entry points
(:mod:`~swarmscene.api`, :mod:`~swarmscene.cli`, :mod:`~swarmscene.plugin`, :mod:`~swarmscene.testing`,
:mod:`~swarmscene.env`) at the top; the tools (:mod:`swarmscene.tools`) and the benchmark suite
(:mod:`swarmscene.suite`); the sweeps (:mod:`swarmscene.sweeps`); the one path from a built run to
its directory (:mod:`~swarmscene.runpath`); the views of a run (:mod:`swarmscene.views`) and Hydra's
side (:mod:`swarmscene.composition`); the run directory's writer and reader (:mod:`swarmscene.runs`).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("swarmscene")  # one source of truth: pyproject.toml
except PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
    __version__ = "unknown"
