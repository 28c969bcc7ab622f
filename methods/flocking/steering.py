"""Reynolds boids as Mesa's BoidFlockers example steers them (Reynolds 1987; Mesa 3 ``boid_flockers``).

Each boid i keeps a heading d_i and flies at a cruise speed along it. Every guidance tick it looks
at its neighbours N_i, the other boids within ``vision`` (distance <= vision), and steers::

    delta_ij = p_j - p_i                                     (minimum image in a toroidal space)
    c_i = cohere   * sum_{j in N_i} delta_ij                 cohesion: toward the neighbours
    s_i = -separate * sum_{j in N_i, |delta_ij| < separation} delta_ij   separation: away from close ones
    m_i = match    * sum_{j in N_i} d_j                      alignment: the neighbours' headings
    d_i <- d_i + (c_i + s_i + m_i) / |N_i|,   d_i <- d_i / |d_i|          (only when N_i is not empty)

The three sums are one compiled pass over the pairs (:func:`~.kernels.flocking_steer`); this
module holds the rest of the rule: the headings read from the world, the optional goal and
boundary terms, and the turn (:func:`turn_headings`). The periodic space is :mod:`.torus`.

Choices, and why:
- The headings d_j read from the world: d_j = vel_j / speed when the boid moves (so alignment sees
  what the neighbours really do, whatever avoidance and dynamics made of the command), and the
  boid's own last heading when it is still (t = 0, failed vehicles). With a single integrator whose
  ``u_max >= sqrt(2) speed`` this is exactly Mesa's stored ``direction``.
- All boids update at once from the same snapshot (synchronous, vectorised). Mesa activates its
  agents one at a time in random order (``shuffle_do``), each seeing the ones already moved in this
  step; the two differ by that update order only, not by the rule.
- Initial headings are drawn as Mesa draws them: each component uniform in [-1, 1], not normalised.
- Failed boids (``healthy`` False) keep their heading; they still repel the others (separation)
  but are not followed (no cohesion, alignment, nor count in |N_i|). A boid seeing only failed
  boids still keeps clear of them (their separation term over a count of one).
- Planar (Mesa's 2-D space): headings stay in the x-y plane.
"""

from __future__ import annotations

import numpy as np

from .torus import minimum_image


def initial_headings(rng: np.random.Generator, n: int, planar: bool) -> np.ndarray:
    """Headings (n, 3) as Mesa draws them: components uniform in [-1, 1], not normalised."""
    d = np.zeros((n, 3))
    axes = 2 if planar else 3
    d[:, :axes] = rng.uniform(-1.0, 1.0, size=(n, axes))
    return d


def current_headings(vel: np.ndarray, last: np.ndarray, speed: float, planar: bool) -> np.ndarray:
    """d_j (N, 3): measured velocity ``vel`` over the cruise ``speed`` when moving, else ``last``."""
    moving = np.einsum("ij,ij->i", vel, vel) > 0.0
    heading = np.where(moving[:, None], vel * (1.0 / speed), last)
    if planar:
        heading[:, 2] = 0.0
    return heading


def goal_steer(pos: np.ndarray, goal: np.ndarray, weight: float, size: np.ndarray | None = None) -> np.ndarray:
    """``weight`` times the unit vector from each boid to ``goal`` (N, 3); in a torus of ``size``
    (its A periodic axes) the vector is the minimum image."""
    to_goal = np.asarray(goal, dtype=float) - pos
    if size is not None:
        a = len(size)
        to_goal[:, :a] = minimum_image(to_goal[:, :a], size)
    norm = np.linalg.norm(to_goal, axis=1, keepdims=True)
    return weight * to_goal / np.maximum(norm, 1e-12)


def boundary_steer(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray, band: float, weight: float) -> np.ndarray:
    """Back into the box ``[lo, hi]`` (N, 3): zero deeper than ``band`` inside, growing linearly
    to ``weight`` at a face (per unit heading)."""
    inward = np.clip(lo + band - pos, 0.0, None) - np.clip(pos - (hi - band), 0.0, None)
    return weight * inward / band


def turn_headings(
    heading: np.ndarray, last: np.ndarray, healthy: np.ndarray, steer: np.ndarray, count: np.ndarray,
    planar: bool, goal: np.ndarray | None = None, boundary: np.ndarray | None = None,
) -> np.ndarray:
    """d_i <- (d_i + steer_i / |N_i| + goal_i + boundary_i) / |...| for the boids that turn.

    Args:
        heading: (N, 3) the headings d_i read from the world (:func:`current_headings`).
        last: (N, 3) the headings of the previous tick (kept by failed boids).
        healthy: (N,) bool.
        steer: (N, 3) the summed cohesion, separation and alignment (:func:`~.kernels.flocking_steer`);
            divided in place by |N_i|.
        count: (N,) |N_i|.
        planar: headings stay in the x-y plane.
        goal: (N, 3) optional goal term (:func:`goal_steer`): every boid turns.
        boundary: (N, 3) optional boundary term (:func:`boundary_steer`): the boids it pushes turn.

    Returns:
        (N, 3) the new unit headings; unchanged where a boid has nothing to steer by.
    """
    turning = (count > 0) | np.any(steer != 0.0, axis=1)
    steer /= np.maximum(count, 1.0)[:, None]
    if goal is not None:
        steer += goal
        turning[:] = True
    if boundary is not None:
        steer += boundary
        turning |= np.any(boundary != 0.0, axis=1)
    if planar:
        steer[:, 2] = 0.0
    new = heading + steer
    norm = np.sqrt(np.einsum("ij,ij->i", new, new))
    turning &= norm > 0.0
    turning &= healthy  # a failed boid keeps its last heading
    new /= np.where(turning, norm, 1.0)[:, None]
    return np.where(turning[:, None], new, np.where(healthy[:, None], heading, last))
