"""Sweeps: many runs as one object.

    grid.py      the grid (Hydra's product, plus cases) and its one check: every distinct override
                 validated once before it runs
    sweeper.py   the sweeper of every multirun: no per-job composition in the main process, jobs
                 launched in batches (Hydra finds it through hydra_plugins/swarmscene_sweeper)
    compose.py   the launchers' config loader: one composition per set of group overrides
    chunks.py    launcher tasks of several jobs, run back to back in one process
    pool.py      the pool launcher (``hydra/launcher=pool``): workers forked from a warm fork server
    batch.py     the batch launcher (``hydra/launcher=batch``): the pool's workers, the jobs that differ
                 only in their seed flown as batches of worlds (core/batch.py)
    warm.py      what that fork server loads before it forks: the engine, the sweep's scenario run once
    records.py   a sweep directory's records: job outcomes, resume, the grid that owns it, its lock
    tables.py    summary.csv/.parquet/.md and the sweep's exit status
    stats.py     intervals (Student t, percentile bootstrap, Wilson)
    report.py    ``swarmscene-report``
    progress.py  the progress line of a running sweep
    callback.py  the Hydra callback (progress while the jobs run, tables at the end)

Imports run one way: ``hydra_plugins.swarmscene_sweeper`` imports this package, never the reverse.
"""
