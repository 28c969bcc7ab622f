"""swarmscene: a declarative scenario engine for quadrotor swarms.

Compose a scenario from Hydra config groups, run it, read back metrics and safety verdicts::

    from swarmscene import api
    result = api.run(["scenario=cem_six_vehicle", "avoidance.K=1"])
    result.metrics["min_separation"]

The engine lives in :mod:`swarmscene.core`, the algorithms in :mod:`swarmscene.plugins`, the config
tree in :mod:`swarmscene.scenarios`; this package is the thin application layer (command line,
Python API, the list of built-in plugins).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("swarmscene")  # one source of truth: pyproject.toml
except PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
    __version__ = "unknown"
