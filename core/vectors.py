"""Small vectorised helpers shared by the kernel and plugins."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from scipy.spatial import cKDTree


def clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """Scale each row of ``v`` (N, k) down so that none is longer than ``limit``; shorter rows
    (and zero rows) are returned unchanged. The saturation of thesis eq. 4.21 and 5.30."""
    norm = np.sqrt(np.einsum("...i,...i->...", v, v))[..., None]  # one C call per step (hot path)
    return v * np.minimum(1.0, limit / np.maximum(norm, 1e-300))


def wrap(pos: np.ndarray, lo: np.ndarray | float, size: np.ndarray) -> np.ndarray:
    """Positions folded into the periodic box [lo, lo + size) (per column of ``lo``/``size``)."""
    q = np.mod(pos - lo, size)
    q[q >= size] = 0.0  # np.mod of a tiny negative can round up to exactly `size`
    return q + lo if np.any(lo) else q


def min_pair_distance(points: np.ndarray, tree: "cKDTree | None" = None) -> float:
    """Smallest distance between two of ``points`` (N, D), m; ``inf`` for fewer than two.

    One 2-nearest query of a k-d tree (``tree``, if given, must be over ``points``). The one
    implementation behind the safety monitor's fallback, CEM's theorem preconditions and the
    thesis' collision condition (eq. 5.2).
    """
    if len(points) < 2:
        return float("inf")
    from scipy.spatial import cKDTree

    tree = cKDTree(points) if tree is None else tree
    dist, _ = tree.query(points, k=2)
    return float(dist[:, 1].min())
