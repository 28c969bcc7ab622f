"""swarmscene's pluggy markers: ``hookspec`` for the specifications, ``hookimpl`` for implementations.

Apart from :mod:`.hookspecs`, which names the types its hooks take (a disturbance model, an event
kind, the run's view), so that an engine module that implements a hook (the disturbances' run-end
metrics) marks it without importing what the specifications name: no import circle
(tests/test_layout.py). :mod:`.hookspecs` and ``swarmscene.plugin`` hand out the same markers.
"""

from __future__ import annotations

import pluggy

PROJECT = "swarmscene"
"""The pluggy project name: the hooks' prefix and the entry-point group."""
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)
