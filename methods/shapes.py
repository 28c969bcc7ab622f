"""Formation shapes: slot offsets of the standard patterns in a formation's body frame."""

from __future__ import annotations

import numpy as np


def shape_offsets(shape: str, n: int, spacing: float) -> np.ndarray:
    """Slot offsets (n, 3) in the formation frame (x forward, y left), centred on their centroid."""
    k = np.arange(n)
    xy = np.zeros((n, 2))
    if shape == "line":  # abreast, perpendicular to the direction of travel
        xy[:, 1] = (k - (n - 1) / 2) * spacing
    elif shape == "grid":
        cols = int(np.ceil(np.sqrt(n)))
        xy[:, 0] = -(k // cols) * spacing
        xy[:, 1] = (k % cols) * spacing
    elif shape == "circle":  # neighbours on the circle are `spacing` apart (chord length)
        radius = spacing / (2 * np.sin(np.pi / n)) if n > 1 else 0.0
        angle = 2 * np.pi * k / max(n, 1)
        xy[:, 0], xy[:, 1] = radius * np.cos(angle), radius * np.sin(angle)
    elif shape == "v":  # apex forward, arms trailing at 45 degrees
        rank = (k + 1) // 2
        side = np.where(k % 2 == 1, 1.0, -1.0)
        xy[:, 0] = -rank * spacing / np.sqrt(2)
        xy[:, 1] = side * rank * spacing / np.sqrt(2)
    elif shape == "triangle":  # filled rows of 1, 2, 3, ... agents, apex forward
        row = np.floor((np.sqrt(8 * k + 1) - 1) / 2).astype(int)
        col = k - row * (row + 1) // 2
        xy[:, 0] = -row * spacing * np.sqrt(3) / 2
        xy[:, 1] = (col - row / 2) * spacing
    else:  # pragma: no cover - Params restricts the choices
        raise ValueError(shape)
    xy -= xy.mean(axis=0)
    return np.column_stack([xy, np.zeros(n)])
