"""``swarmscene-report``: moved to :mod:`swarmscene.sweeps.report` (this name stays for the console
script of installs made before the move)."""

from .sweeps.report import entry, main, methods_table, metric_against, plot_metric  # noqa: F401
