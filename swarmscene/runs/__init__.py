"""A run's directory: its writer and its reader, the one checked path for both.

    outputs.py   writes a run directory: config.yaml, the trajectory, metrics.json, the observers'
                 files and the manifest last, each atomically and never through a link
    rundir.py    reads one back (:class:`~.rundir.RunDir`): every file a run or a sweep directory
                 holds may be damaged or hostile, so each is read through its checks
    build.py     a run from its configuration: the plugin manager, validation, the simulation

Imports run one way: the views, the sweeps, the tools and the entry points import this package;
it imports only the engine (``swarmscene.core``).
"""
