"""swarmscene: a declarative scenario engine for quadrotor swarms.

Compose a scenario from Hydra config groups, run it, read back metrics and safety verdicts::

    from swarmscene import api
    result = api.run(["scenario=cem_six_vehicle", "avoidance.K=1"])
    result.metrics["min_separation"]

The engine lives in :mod:`swarmscene.core`, the methods' numerics in :mod:`swarmscene.methods`, the
algorithms' plugins in :mod:`swarmscene.plugins`, the config tree in :mod:`swarmscene.scenarios`.
This package is the application around them: the public entry points (:mod:`~swarmscene.api`,
:mod:`~swarmscene.cli`, :mod:`~swarmscene.plugin`, :mod:`~swarmscene.testing`, :mod:`~swarmscene.env`),
the one path from a built run to its directory (:mod:`~swarmscene.runpath`), the run directory's
writer and reader (:mod:`~swarmscene.runs.outputs`, :mod:`~swarmscene.runs.rundir`), the sweeps
(:mod:`swarmscene.sweeps`), the suite (:mod:`swarmscene.suite`), the views of a run (summary,
plots, live view, replay, exports) and the tools (falsifier, compile, docs generation, schema, info).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("swarmscene")  # one source of truth: pyproject.toml
except PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
    __version__ = "unknown"
