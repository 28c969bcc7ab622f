"""Hydra's handles on swarmscene's sweeper (``hydra/sweeper=swarmscene``, the default of every
multirun), pool launcher (``hydra/launcher=pool``) and batch launcher (``hydra/launcher=batch``):
the classes are :class:`swarmscene.sweeps.sweeper.SwarmsceneSweeper`,
:class:`swarmscene.sweeps.pool.PoolLauncher` and :class:`swarmscene.sweeps.batch.BatchLauncher`.
Hydra takes sweeper and launcher classes from the ``hydra_plugins`` package only, so they are named
here."""

from swarmscene.sweeps import batch as _batch
from swarmscene.sweeps import pool as _pool
from swarmscene.sweeps import sweeper as _sweeper

__version__ = "1.0"


class SwarmsceneSweeper(_sweeper.SwarmsceneSweeper):
    """The sweeper of :mod:`swarmscene.sweeps.sweeper`, under the package name Hydra scans."""

    __doc__ = _sweeper.SwarmsceneSweeper.__doc__  # what Hydra and help() show: the sweeper's own


class PoolLauncher(_pool.PoolLauncher):
    """The launcher of :mod:`swarmscene.sweeps.pool`, under the package name Hydra scans."""

    __doc__ = _pool.PoolLauncher.__doc__


class BatchLauncher(_batch.BatchLauncher):
    """The launcher of :mod:`swarmscene.sweeps.batch`, under the package name Hydra scans."""

    __doc__ = _batch.BatchLauncher.__doc__


def register() -> None:
    """Make Hydra know the sweeper and the launchers (its scan of ``hydra_plugins`` misses editable
    installs)."""
    from hydra.core.plugins import Plugins

    plugins = Plugins.instance()
    for cls in (SwarmsceneSweeper, PoolLauncher, BatchLauncher):
        if cls not in plugins.class_name_to_class.values():
            plugins.register(cls)
