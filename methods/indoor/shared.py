"""The thesis' per-tick sensing snapshot (G_s, G_n, G_sigma and obstacle points), shared by the
indoor formation and the thesis' avoidance terms so the graphs are built once per tick."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field

from swarmscene.core.plugin import SHARED, PluginParams

from .control import TABLE_5_1, IndoorGains, IndoorSnapshot, sense, sense_indexed

if TYPE_CHECKING:  # pragma: no cover
    from pydantic.json_schema import JsonDict


def shared_snapshot(sensing: Any, gains: IndoorGains) -> IndoorSnapshot:
    """The tick's :class:`IndoorSnapshot` (G_s, G_n, G_sigma, obstacle points), built once per tick.

    The formation and the avoidance plugin both need G_sigma: the first caller builds it through
    the kernel's per-tick memo (:meth:`~swarmscene.core.sensing.Sensing.shared`), the second reuses
    it; if their graph parameters differ the memo refuses (they must describe one graph).
    """
    reach = gains.sensing_reach
    return sensing.shared("thesis.indoor_snapshot", gains.snapshot_key,
                          lambda: _snapshot(sensing, gains, reach))


def _snapshot(sensing: Any, gains: IndoorGains, reach: float) -> IndoorSnapshot:
    r = np.array(sensing.world.pos[:, :2])  # a copy: the snapshot outlives the tick (diagnostics)
    if sensing.environment.empty:  # the engine's pair list: no k-d tree is needed
        return sense(r, None, gains, None, None, sensing.pairs(gains.d_n))
    # The engine's obstacle query, footprint arrays and pair list, shared with the safety
    # monitor; o_i and the graphs then come from one compiled call.
    index, clearance = sensing.obstacle_nearest(reach)
    candidates = sensing.pairs(gains.d_n)
    footprints = sensing.environment.footprints
    return sense_indexed(r, footprints, gains, index, np.maximum(clearance, 0.0), candidates)


_GRAPH: JsonDict = {SHARED: "the thesis' sensing graphs (G_s, G_n, G_sigma)"}


class GraphParams(PluginParams):
    """Sensing and graph parameters shared by ``indoor_swarm`` and ``potential_barrier``.

    Both plugins read one snapshot per tick (:func:`shared_snapshot`); validation refuses a
    scenario where the two declare different values (``core.plugin.shared_option_conflicts``).
    """

    d_s: float = Field(TABLE_5_1.d_s, gt=0, description="sensing range d_s, m", json_schema_extra=_GRAPH)
    d_l: float = Field(TABLE_5_1.d_l, ge=0, description="LOS clearance d_l, m", json_schema_extra=_GRAPH)
    d_n: float = Field(
        TABLE_5_1.d_n, gt=0, description="neighbour maximum distance d_n, m", json_schema_extra=_GRAPH
    )
    phi_d: float = Field(
        TABLE_5_1.phi_d, gt=0, lt=0.7072, description="edge deactivation threshold phi_d (< 1/sqrt 2)",
        json_schema_extra=_GRAPH,
    )
    deactivation_candidates: Literal["neighbours", "common", "directed"] = Field(
        "neighbours",
        description="edge deactivation candidates m of eq. 5.15-5.16: 'neighbours' m in N_i(G_n) as "
        "printed, the edge off when either end's rule fires (literal reading); 'common' m in "
        "N_i and N_j (G_sigma keeps G_n's components, the pre-issue-17 reading); 'directed' each "
        "agent drops the edge from its own neighbour set only (G_sigma directed)",
        json_schema_extra=_GRAPH,
    )
    l_o: float = Field(
        TABLE_5_1.l_o, gt=0, description="obstacle avoidance range l_o, m", json_schema_extra=_GRAPH
    )
