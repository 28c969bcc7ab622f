"""Hydra's handle on swarmscene's sweeper (``hydra/sweeper=swarmscene``, the default of every
multirun): the sweeper is :class:`swarmscene.sweeps.sweeper.SwarmsceneSweeper`. Hydra takes sweeper
classes from the ``hydra_plugins`` package only, so the class is named here."""

from swarmscene.sweeps import sweeper as _sweeper

__version__ = "1.0"


class SwarmsceneSweeper(_sweeper.SwarmsceneSweeper):
    """The sweeper of :mod:`swarmscene.sweeps.sweeper`, under the package name Hydra scans."""

    __doc__ = _sweeper.SwarmsceneSweeper.__doc__  # what Hydra and help() show: the sweeper's own


def register() -> None:
    """Make Hydra know the sweeper (its scan of ``hydra_plugins`` misses editable installs)."""
    from hydra.core.plugins import Plugins

    plugins = Plugins.instance()
    if SwarmsceneSweeper not in plugins.class_name_to_class.values():
        plugins.register(SwarmsceneSweeper)
