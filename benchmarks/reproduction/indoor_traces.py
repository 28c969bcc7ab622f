"""Traces behind docs/indoor_fidelity.md: why the L corridor fails, term by term (thesis ch. 5).

Flies the shipped scenarios through the engine (``swarmscene.api.build``) and records, every tick,
the positions, G_n, G_sigma, the estimated ranks and each term of the follower law (eq. 5.31:
w_obs, w_col, w_con, w_com, w_led) with the saturation factor of eq. 5.30, and the leader's input
(eq. 5.44). Two investigations (issue 17):

``split`` (why w = 0.8 m does worse than 0.7 m in the L): for every run, the G_n links that cross
the L's inner corner (one end in each leg) and their clearance from the corner point; for a run
that splits, the cut link's geometry (where its ends are, their offsets from the inner walls) and
what closed the clearance of that link onto the corner in the ``--window`` seconds before the
split, split into the five terms: the clearance c of segment a-b from the corner changes by
(1 - lambda) e . u_a + lambda e . u_b per tick (e the unit vector from the corner to the nearest
point of the segment, lambda its position on the segment), and u = s (w_obs + w_col + w_con + w_com
+ w_led) with s the saturation factor, so each term's share is exact (the leader's u is its own).

``safety`` (why eq. 5.2 / 5.3 break at w = 0.5-0.6 m): the tick of the smallest separation and of
the smallest clearance, the pair, whether the leader is in it, whether the pair is a G_sigma edge
(w_col acts only along G_sigma, eq. 5.35), where the leader's input points, and each term of the
follower's input at that tick. ``pair`` prints the history of one pair (``--agents``, leader
first) over ``--span`` seconds: how fast each closes on the other and the second one's terms.

    python benchmarks/reproduction/indoor_traces.py split --widths 070 080 --seeds 30
    python benchmarks/reproduction/indoor_traces.py safety --widths 050 060 --seeds 30
    python benchmarks/reproduction/indoor_traces.py split --widths 080 --seed-list 10 15 --json out.json
    python benchmarks/reproduction/indoor_traces.py pair --widths 050 --seed-list 24 --agents 0 5 --span 5 6.2
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from swarmscene import api
from swarmscene.methods.indoor.control import psi_com, psi_con, w_col, w_led, w_obs
from swarmscene.methods.indoor.graphs import max_rank, virtual_leader

TERMS = ("obs", "col", "con", "com", "led")
CORRIDOR_AXIS = 5.0  # the L's corner on the corridor axis is (5, 0) (methods.indoor.maps.l_corridor)
D_C, D_O, D_L, D_N = 0.3, 0.1, 0.05, 1.0  # Table 5.1


@dataclass
class Trace:
    """Per-tick record of one run (positions before the tick's move)."""

    width: float
    seed: int
    leader: int
    t: list[float] = field(default_factory=list)
    r: list[np.ndarray] = field(default_factory=list)
    u: list[np.ndarray] = field(default_factory=list)  # applied displacement per tick, m
    terms: list[np.ndarray] = field(default_factory=list)  # (5, N, 2) unsaturated terms, m
    scale: list[np.ndarray] = field(default_factory=list)  # (N,) saturation factor s of eq. 5.30
    g_n: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    g_sigma: list[set] = field(default_factory=list)
    rank: list[np.ndarray] = field(default_factory=list)  # rho_bar used at the tick
    connected: list[bool] = field(default_factory=list)
    clearance: list[np.ndarray] = field(default_factory=list)  # (N,) obstacle distance, m
    metrics: dict = field(default_factory=dict)


def fly(overrides: list[str], seed: int, width: float) -> Trace:
    """Run one scenario, recording every tick (see the module docstring)."""
    sim = api.build([*overrides, f"seed={seed}", "output.trajectory=false", "output.summary=false"])
    formation, gains = sim.formation, sim.formation.gains
    tr = Trace(width, seed, formation.leader)
    rank_before = [formation.rho_bar.copy()]

    def record(s) -> None:
        snap = formation.snapshot
        r = snap.r
        rho = rank_before[-1]
        l, has = virtual_leader(r, snap.g_sigma, rho)  # noqa: E741 (l_i, eq. 5.24-5.25)
        pg = snap.pair_geometry
        terms = np.stack([w_obs(r, snap.o, gains), w_col(r, pg, gains),
                          pg.sum(psi_con(pg.length, gains)), pg.sum(psi_com(pg.length, gains)),
                          w_led(r, l, has, gains)])
        w = terms.sum(axis=0)
        norm = np.linalg.norm(w, axis=1)
        scale = np.where(norm > gains.u_sat, gains.u_sat / np.maximum(norm, 1e-300), 1.0)
        u = s.world.pos[:, :2] - r
        tr.t.append(s.world.t - gains.T_s)
        tr.r.append(r)
        tr.u.append(u)
        tr.terms.append(terms)
        tr.scale.append(scale)
        tr.g_n.append((snap.g_n.i, snap.g_n.j))
        src, dst = snap.g_sigma.directed()
        tr.g_sigma.append(set(zip(src.tolist(), dst.tolist(), strict=True)))
        tr.rank.append(rho)
        tr.clearance.append(np.minimum(snap.obstacle_distance, 10.0))
        tr.connected.append(max_rank(snap.g_n, formation.leader)[0] < len(r))
        rank_before.append(formation.rho_bar.copy())

    tr.metrics = json.loads(json.dumps(sim.run(progress=record).metrics, default=float))
    return tr


def inner_corner(width: float) -> np.ndarray:
    """The L corridor's inner corner (x, y), m, for a corridor ``width`` m wide."""
    return np.array([CORRIDOR_AXIS - width / 2, width / 2])


def segment_clearance(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, ...]:
    """Distance of point p from segments a-b (K, 2), the nearest point's lambda and the unit e."""
    ab = b - a
    lam = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12),
                  0.0, 1.0)
    q = a + lam[:, None] * ab
    d = q - p
    dist = np.linalg.norm(d, axis=1)
    return dist, lam, d / np.maximum(dist, 1e-12)[:, None]


def crossing_links(tr: Trace, k: int) -> tuple[np.ndarray, np.ndarray]:
    """G_n links at tick k with one end in each leg of the L (they pass the inner corner)."""
    i, j = tr.g_n[k]
    r = tr.r[k]
    corner = inner_corner(tr.width)
    east = lambda v: (r[v, 1] < corner[1]) & (r[v, 0] < corner[0])  # noqa: E731
    north = lambda v: (r[v, 0] > corner[0]) & (r[v, 1] > corner[1])  # noqa: E731
    keep = (east(i) & north(j)) | (east(j) & north(i))
    return i[keep], j[keep]


def corner_profile(tr: Trace) -> dict:
    """The smallest clearance of a corner-crossing G_n link from the inner corner over the run
    (never below d_l: such a link leaves G_n), how many ticks had one under d_l + 0.05 m, the
    abreast fraction (G_n links of the east leg joining agents side by side: lateral gap > d_c,
    longitudinal < d_c) and the inner-hug fraction (agent-ticks in the first metre of the north
    leg within 0.25 m of its inner wall)."""
    corner = inner_corner(tr.width)
    worst, close, abreast, east_total, hug, north_total = np.inf, 0, 0, 0, 0, 0
    for k in range(len(tr.t)):
        r = tr.r[k]
        north = (r[:, 1] > corner[1]) & (r[:, 1] < corner[1] + 1.0) & (r[:, 0] > corner[0])
        hug += int((north & (r[:, 0] - corner[0] <= 0.25)).sum())
        north_total += int(north.sum())
        i, j = crossing_links(tr, k)
        if len(i):
            c = segment_clearance(tr.r[k][i], tr.r[k][j], corner)[0].min()
            worst = min(worst, c)
            close += int(c < D_L + 0.05)
        r = tr.r[k]
        gi, gj = tr.g_n[k]
        leg = (r[gi, 0] > 0.0) & (r[gi, 0] < corner[0]) & (r[gj, 0] > 0.0) & (r[gj, 0] < corner[0])
        dx, dy = np.abs(r[gi, 0] - r[gj, 0]), np.abs(r[gi, 1] - r[gj, 1])
        abreast += int((leg & (dy > D_C) & (dx < D_C)).sum())
        east_total += int(leg.sum())
    return {"min_corner_link_clearance": float(worst), "ticks_under_0.1": close,
            "abreast_links_fraction": abreast / max(east_total, 1),
            "inner_hug_fraction": hug / max(north_total, 1)}


def split_report(tr: Trace, window: float) -> dict | None:
    """The first split: the cut links, their geometry, and what closed the corner clearance."""
    if all(tr.connected):
        return None
    k = tr.connected.index(False)
    if k == 0:
        return {"t": 0.0, "note": "disconnected at start"}
    prev = k - 1
    r_now = tr.r[k]
    reach = _reached(tr, prev)
    lost_now = ~_reached(tr, k)
    i, j = tr.g_n[prev]
    cut = lost_now[i] != lost_now[j]
    a = np.where(lost_now[i[cut]], i[cut], j[cut])  # the lost end
    b = np.where(lost_now[i[cut]], j[cut], i[cut])
    corner = inner_corner(tr.width)
    clear, _, _ = segment_clearance(r_now[a], r_now[b], corner)
    pick = int(np.argmin(clear))
    a, b = int(a[pick]), int(b[pick])
    start = max(0, k - int(round(window / (tr.t[1] - tr.t[0]))))
    share = np.zeros(len(TERMS) + 1)  # five follower terms, then the leader's input
    for s in range(start, k):
        _, lam, e = segment_clearance(tr.r[s][[a]], tr.r[s][[b]], corner)
        for end, weight in ((a, 1.0 - lam[0]), (b, lam[0])):
            if end == tr.leader:
                share[-1] += weight * e[0] @ tr.u[s][end]
            else:
                share[:-1] += weight * tr.scale[s][end] * (tr.terms[s][:, end] @ e[0])
    c0 = segment_clearance(tr.r[start][[a]], tr.r[start][[b]], corner)[0][0]
    c1 = segment_clearance(r_now[[a]], r_now[[b]], corner)[0][0]
    offset = lambda v: _wall_offsets(r_now[v], tr.width)  # noqa: E731
    ahead = tr.g_sigma[prev]
    return {
        "t": tr.t[k], "lost": int(lost_now.sum()), "reached_before": int(reach.sum()),
        "link": [a, b], "rank_bar": [int(tr.rank[prev][a]), int(tr.rank[prev][b])],
        "length": float(np.linalg.norm(r_now[b] - r_now[a])), "corner_clearance": float(c1),
        "corner_clearance_window_start": float(c0),
        "a_pos": r_now[a].round(3).tolist(), "b_pos": r_now[b].round(3).tolist(),
        "a_inner_offset": offset(a), "b_inner_offset": offset(b),
        "a_sigma_neighbours": sorted(d for s, d in ahead if s == a),
        "closing_by_term": dict(zip([*TERMS, "leader"], share.round(4).tolist(), strict=True)),
        "a_terms": {n: tr.terms[prev][m, a].round(4).tolist() for m, n in enumerate(TERMS)},
        "b_terms": {n: tr.terms[prev][m, b].round(4).tolist() for m, n in enumerate(TERMS)},
        "a_g_n_degree": int(((i == a) | (j == a)).sum()),
        "b_abreast": _abreast(tr.r[prev], b),
        "cut_links": int(cut.sum()),
    }


def _abreast(r: np.ndarray, b: int) -> list | None:
    """The agent beside b (within 0.15 m along the north leg, 0.3-0.6 m across), if any."""
    dx, dy = r[:, 0] - r[b, 0], np.abs(r[:, 1] - r[b, 1])
    side = np.flatnonzero((np.abs(dx) > D_C) & (np.abs(dx) < 0.6) & (dy < 0.15))
    return [int(side[0]), r[side[0]].round(3).tolist()] if side.size else None


def _reached(tr: Trace, k: int) -> np.ndarray:
    from swarmscene.methods.indoor.graphs import EdgeList

    i, j = tr.g_n[k]
    return max_rank(EdgeList(len(tr.r[k]), i, j), tr.leader)[1]


def _wall_offsets(p: np.ndarray, width: float) -> float:
    """Distance of a point from the nearest inner wall of the L (y = w/2 east, x = 5 - w/2 north)."""
    corner = inner_corner(width)
    if p[0] < corner[0] and p[1] < corner[1]:
        return float(round(corner[1] - p[1], 3))
    if p[1] > corner[1] and p[0] > corner[0]:
        return float(round(p[0] - corner[0], 3))
    return float(round(np.linalg.norm(p - corner), 3))


def safety_report(tr: Trace) -> dict:
    """The ticks of the smallest separation and clearance, with the pair and the terms there."""
    seps, pairs = [], []
    for r in tr.r:
        d = np.linalg.norm(r[:, None] - r[None], axis=2)
        np.fill_diagonal(d, np.inf)
        flat = int(np.argmin(d))
        seps.append(d.flat[flat])
        pairs.append(divmod(flat, len(r)))
    k = int(np.argmin(seps))
    a, b = pairs[k]
    r = tr.r[k]
    out = {"min_separation": float(seps[k]), "t_sep": tr.t[k], "pair": [a, b],
           "leader_in_pair": tr.leader in (a, b),
           "pair_in_g_sigma": [(a, b) in tr.g_sigma[k], (b, a) in tr.g_sigma[k]],
           "pos": [r[a].round(3).tolist(), r[b].round(3).tolist()]}
    if tr.leader in (a, b):
        f = b if a == tr.leader else a
        to_f = r[f] - r[tr.leader]
        u_l = tr.u[k][tr.leader]
        out["leader_speed_toward_follower"] = float(u_l @ to_f / np.linalg.norm(to_f))
        out["follower"] = int(f)
        out["follower_terms"] = {n: tr.terms[k][m, f].round(4).tolist() for m, n in enumerate(TERMS)}
        out["follower_u"] = tr.u[k][f].round(4).tolist()
        out["follower_u_toward_leader"] = float(tr.u[k][f] @ (-to_f) / np.linalg.norm(to_f))
        out["follower_clearance"] = float(tr.clearance[k][f])
    clear = np.array([c.min() for c in tr.clearance])
    kc = int(np.argmin(clear))
    v = int(np.argmin(tr.clearance[kc]))
    out.update({"min_clearance": float(clear[kc]), "t_clear": tr.t[kc], "agent": v,
                "agent_is_leader": v == tr.leader, "agent_pos": tr.r[kc][v].round(3).tolist(),
                "agent_terms": {n: tr.terms[kc][m, v].round(4).tolist() for m, n in enumerate(TERMS)},
                "agent_u": tr.u[kc][v].round(4).tolist(),
                "nearest_agent_distance": float(np.delete(
                    np.linalg.norm(tr.r[kc] - tr.r[kc][v], axis=1), v).min()),
                "nearest_agent_is_leader": int(np.argsort(
                    np.linalg.norm(tr.r[kc] - tr.r[kc][v], axis=1))[1]) == tr.leader})
    return out


def pair_history(tr: Trace, a: int, b: int, start: float, end: float, every: int = 5) -> list[dict]:
    """Tick by tick (every ``every`` ticks) between ``start`` and ``end`` s: the pair's positions and
    separation, the approach speed of each (m per step, positive toward the other), b's
    clearance and non-zero terms, and whether (a, b) is a G_sigma edge."""
    rows = []
    for k, t in enumerate(tr.t):
        if not (start <= t <= end) or k % every:
            continue
        r = tr.r[k]
        d = r[b] - r[a]
        dist = float(np.linalg.norm(d))
        rows.append({
            "t": round(t, 2), "a": r[a].round(3).tolist(), "b": r[b].round(3).tolist(),
            "separation": round(dist, 3), "a_toward_b": round(float(tr.u[k][a] @ d) / dist, 4),
            "b_toward_a": round(float(tr.u[k][b] @ -d) / dist, 4),
            "b_clearance": round(float(tr.clearance[k][b]), 3), "edge_in_g_sigma": (a, b) in tr.g_sigma[k],
            "b_terms": {n: tr.terms[k][m, b].round(3).tolist() for m, n in enumerate(TERMS)
                        if np.any(tr.terms[k][m, b])},
        })
    return rows


def main(argv: list[str] | None = None) -> None:
    """Fly the L corridor per width and seed and print one JSON line per run (split, safety or pair)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["split", "safety", "pair"])
    parser.add_argument("--agents", type=int, nargs=2, default=[0, 5], help="pair: a b")
    parser.add_argument("--span", type=float, nargs=2, default=[5.0, 6.2], help="pair: from, to (s)")
    parser.add_argument("--widths", nargs="+", default=["070", "080"])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--seed-list", type=int, nargs="*", default=None)
    parser.add_argument("--candidates", default="neighbours", help="deactivation_candidates")
    parser.add_argument("--window", type=float, default=0.5, help="s before the split")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    seeds = args.seed_list if args.seed_list is not None else list(range(args.seeds))
    out = []
    for w in args.widths:
        width = int(w) / 100
        overrides = ["scenario=indoor_l_corridor", f"environment=indoor_l_corridor_w{w}",
                     f"formation.deactivation_candidates={args.candidates}",
                     f"avoidance.deactivation_candidates={args.candidates}"]
        for seed in seeds:
            if args.what == "pair":
                tr = fly([*overrides, f"clock.duration={args.span[1] + 0.1}"], seed, width)
                for row in pair_history(tr, *args.agents, *args.span):
                    print(json.dumps(row), flush=True)
                continue
            tr = fly(overrides, seed, width)
            row = {"width": width, "seed": seed, "success": tr.metrics["indoor.success"],
                   "min_separation": tr.metrics["min_separation"],
                   "min_clearance": tr.metrics["min_clearance"]}
            if args.what == "split":
                row.update(corner_profile(tr))
                row["split"] = split_report(tr, args.window)
            elif not (row["min_separation"] >= D_C and row["min_clearance"] >= D_O):
                row["safety"] = safety_report(tr)
            out.append(row)
            print(json.dumps(row), flush=True)
            if args.json is not None:
                args.json.parent.mkdir(parents=True, exist_ok=True)
                args.json.write_text(json.dumps(out, indent=1))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
