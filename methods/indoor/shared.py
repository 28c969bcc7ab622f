"""The thesis' per-tick sensing snapshot (G_s, G_n, G_sigma and obstacle points), shared by the
indoor formation and the thesis' avoidance terms so the graphs are built once per tick."""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np
from pydantic import Field

from swarmscene.core.plugin import PluginParams

from .control import TABLE_5_1, IndoorGains, IndoorSnapshot, sense
from .sensing import nearest_points

_SNAPSHOTS: "weakref.WeakKeyDictionary[Any, dict]" = weakref.WeakKeyDictionary()


def shared_snapshot(sensing: Any, gains: IndoorGains) -> IndoorSnapshot:
    """The tick's :class:`IndoorSnapshot`, computed once per Sensing object and sensing parameters.

    The formation and the avoidance plugin both need G_sigma; the kernel hands them the same
    per-tick ``sensing`` (with its shared k-d tree), so the second caller reuses the first one's
    graphs. Weakly keyed: a snapshot dies with its tick.
    """
    reach = min(gains.l_o, gains.d_s)
    key = (gains.d_n, gains.d_l, gains.phi_d, reach)
    per_tick = _SNAPSHOTS.setdefault(sensing, {})
    if key not in per_tick:
        r = np.array(sensing.world.pos[:, :2])  # a copy: the snapshot outlives the tick (diagnostics)
        obstacles = sensing.environment.tree
        nearest = None
        if obstacles is not None:  # the engine's obstacle query, shared with the safety monitor
            index, clearance = sensing.obstacle_nearest(reach)
            nearest = (nearest_points(r, obstacles.geometries, index), np.maximum(clearance, 0.0))
        candidates = sensing.pairs(gains.d_n)  # the engine's pair list, shared with the monitor
        per_tick[key] = sense(r, obstacles, gains, sensing.tree, nearest, candidates)
    return per_tick[key]


class GraphParams(PluginParams):
    """Sensing and graph parameters shared by ``indoor_swarm`` and ``potential_barrier``."""

    d_s: float = Field(TABLE_5_1.d_s, gt=0, description="sensing range d_s, m")
    d_l: float = Field(TABLE_5_1.d_l, ge=0, description="LOS clearance d_l, m")
    d_n: float = Field(TABLE_5_1.d_n, gt=0, description="neighbour maximum distance d_n, m")
    phi_d: float = Field(
        TABLE_5_1.phi_d, gt=0, lt=0.7072, description="edge deactivation threshold phi_d (< 1/sqrt 2)"
    )
    l_o: float = Field(TABLE_5_1.l_o, gt=0, description="obstacle avoidance range l_o, m")
