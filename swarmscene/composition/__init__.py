"""Hydra's side: composing a scenario from the config tree, and what Hydra reads and writes.

    compose.py          ``compose(overrides)``: the config tree composed, as plain data
    searchpath.py       the search path (third-party packages' YAML), plain ``key=value`` overrides
    groups.py           the config groups a user chooses from (the README's table, ``--help``)
    scenario_files.py   limits on a user's YAML files, checked before Hydra parses them
    hydra_files.py      Hydra's ``.hydra/`` files kept inside the run directory, never through a link
    hydra_errors.py     Hydra's multi-line errors as the command line's one line
    hydra_internals.py  the one module that imports or patches Hydra's private API (each use with its
                        reason and the version it was checked against)

Imports run one way: the entry points, the sweeps, the suite and the tools import this package; it
imports the run directory's writer (:mod:`swarmscene.runs`) and the engine.
"""
