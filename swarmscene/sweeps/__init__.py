"""Sweeps: many runs as one object (job records, grids, tables and statistics, report, progress).

:mod:`swarmscene.sweeps.stats` holds the intervals every table and report uses.
"""
