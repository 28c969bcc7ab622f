"""What the pool launcher's fork server loads before it forks any worker (:mod:`.pool`).

Python's fork server imports the modules of its preload list once, at its start; this module is
that list. Importing it loads, in the fork server, what every job of the sweep would otherwise load
in each worker: Hydra's job machinery, the engine and every registered plugin, and then, by running
the sweep's scenario briefly (the scenario :mod:`.pool` puts in ``SWARMSCENE_POOL_WARM``; its events
moved to the first ticks and its duration cut, as ``swarmscene-compile`` runs it, and nothing
written), the compiled kernels its methods call and the libraries they load when they first act.
The workers forked afterwards share all of it.

Nothing here changes a job's numbers: the run uses its own simulation objects, and the engine keeps
no state between runs but caches of loaded code. A scenario that fails here is left to its job,
which reports it in its run directory.
"""

from __future__ import annotations

import json
import os

from .pool import WARM_ENV


def warm(scenario: str | None) -> None:
    """Import the engine; run ``scenario`` (JSON of a composed config) briefly if given."""
    import importlib

    import hydra.core.utils  # noqa: F401  (run_job and its logging: every job's first call)

    from ..runs.build import build, plugins, shortened

    importlib.import_module("swarmscene.cli")  # the module of the task function the workers call by name
    plugins()  # every registered plugin's module, the third parties' included
    if not scenario:
        return
    data = shortened(json.loads(scenario))
    data["output"] = {**data["output"], "plots": False, "animation": False, "rerun": False, "live": "off"}
    if isinstance(data.get("dynamics"), dict) and "threads" in data["dynamics"]:
        # numba's threads must not start here: its GNU OpenMP layer (where TBB is missing) kills
        # every child forked after they did, and the workers are forked from this process
        data["dynamics"] = {**data["dynamics"], "threads": 1}
    try:
        build(data).run()
    except Exception:  # the job reports it, in its own run directory
        pass


warm(os.environ.pop(WARM_ENV, None))  # read once: the workers' jobs do not inherit it
