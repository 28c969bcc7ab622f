"""Differential flatness of the quadrotor (Mellinger and Kumar 2011), the heading convention.

The flat outputs σ = (p, ψ) and their derivatives (velocity, acceleration a, jerk j, snap s, yaw
rate ψ̇ and yaw acceleration ψ̈) determine the attitude R, body rates ω, angular acceleration α and
the collective thrust of a quadrotor exactly (the "endogenous transformation" the VRB paper uses in
section III to turn every vehicle's flat outputs into feed-forward inputs of an SE(3) controller).
World frame z up (core/state.py), body frame front-left-up, thrust along +z_b.

Heading convention: the body x axis is chosen perpendicular to y_c = (-sin ψ, cos ψ, 0), i.e.
x_b = (y_c × z_b) / |y_c × z_b|, y_b = z_b × x_b. Its horizontal projection then points exactly along
ψ, so ψ is the ZYX (yaw-pitch-roll) Euler yaw of R, the sequence the thesis uses (eq. 3.1-3.2).
(Mellinger and Kumar project x_c = (cos ψ, sin ψ, 0) instead, which makes ψ a ZXY yaw.) The
construction is singular only at ±90° of roll.

The ``quadrotor`` dynamics computes the feed-forward once per guidance tick in compiled code:
:func:`kernels.flat_rates` (ω and α of (a, j, s, ψ, ψ̇, ψ̈)); the heading vector y_c below is
computed here with numpy once per tick and passed to it. The numpy form of the whole construction
(attitude, rates, thrust and open-loop inputs) is the tests' oracle, tests/oracles/quadrotor.py.
"""

from __future__ import annotations

import numpy as np


def heading_vector(yaw: np.ndarray) -> np.ndarray:
    """y_c = (-sin ψ, cos ψ, 0) (N, 3): the horizontal direction the body x axis is kept normal to."""
    return np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], axis=1)
