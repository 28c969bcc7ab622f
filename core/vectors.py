"""Small vectorised helpers shared by plugins."""

from __future__ import annotations

import numpy as np


def clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """Scale each row of ``v`` (N, k) down so that none is longer than ``limit``; shorter rows
    (and zero rows) are returned unchanged. The saturation of thesis eq. 4.21 and 5.30."""
    norm = np.sqrt(np.einsum("...i,...i->...", v, v))[..., None]  # one C call per step (hot path)
    return v * np.minimum(1.0, limit / np.maximum(norm, 1e-300))
