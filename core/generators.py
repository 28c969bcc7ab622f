"""The map generator interface: obstacle maps from a few numeric parameters, so a map is swept like
any option.

``environment.generator`` chooses a registered :class:`MapGenerator`; its parameters sit beside it
in the ``environment`` section (``environment.width=0.5,0.6,0.7`` sweeps a corridor's width) and
the run's config records all of them, defaults included. Listed ``obstacles`` are added to what the
generator builds. The built-ins are plugins like any other (``plugins/generator/``: ``corridor``,
thesis section 5.4, Fig. 5.11/5.12; ``building``, thesis Appendix A; ``obstacle_field``), their
geometry in :mod:`swarmscene.methods.maps`; the kernel names none of them.
"""

from __future__ import annotations

from typing import Any, ClassVar

from shapely.geometry import Polygon

from .fields import StrictModel


class MapGenerator:
    """A map generator: obstacle footprints from a few numeric parameters (``environment.generator``).

    Subclasses declare ``name``, a ``Params`` model (its parameters, which sit beside
    ``generator`` in the ``environment`` section: ``environment.width=0.5``) and :meth:`build`.
    Errors a build finds (a density out of reach) are ``ValueError`` whose message starts with
    the key it names (``environment.density: ...``).
    """

    name: ClassVar[str]
    Params: ClassVar[type[StrictModel]] = StrictModel

    @classmethod
    def build(cls, params: Any) -> list[Polygon]:
        """The obstacle footprints (shapely polygons, m) of ``params``, a validated ``Params``."""
        raise NotImplementedError
