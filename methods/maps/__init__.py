"""Map generation: obstacle maps from a few numbers (thesis section 5.4, Fig. 5.11/5.12; Appendix A).

The numerics of the built-in map generators (``plugins/generator/``): the walls of a free space
that is a union of rectangles, rounded to :data:`DECIMALS` places (:mod:`.walls`), the corridor
(:mod:`.corridor`), the building (:mod:`.building`) and the random obstacle field (:mod:`.field`).
They reproduce the thesis' maps (:mod:`swarmscene.methods.indoor.maps`) without importing them, so
this package stands alone.
"""

from .building import DOOR_OVERLAP, PARTITION, SEPARATION, building, building_free_space
from .corridor import corridor, corridor_axis, corridor_free_space
from .field import FIELD_BATCH, MAX_FIELD_CANDIDATES, obstacle_field, obstacle_field_discs
from .walls import DECIMALS, snap, snapped_box, wall_polygons

__all__ = [
    "DECIMALS", "DOOR_OVERLAP", "FIELD_BATCH", "MAX_FIELD_CANDIDATES", "PARTITION", "SEPARATION",
    "building", "building_free_space", "corridor", "corridor_axis", "corridor_free_space",
    "obstacle_field", "obstacle_field_discs", "snap", "snapped_box", "wall_polygons",
]
