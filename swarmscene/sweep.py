"""Old import path of the sweep machinery, now :mod:`swarmscene.sweeps` (records, tables, stats).

Kept for the names other modules still import from here: ``record_failure`` (the command line's
single-run path) and ``mean_ci``/``wilson`` (benchmarks/reproduce.py, bench_resilience.py,
sweep_indoor.py).
"""

from .sweeps.records import record_failure  # noqa: F401
from .sweeps.stats import mean_ci, wilson  # noqa: F401
