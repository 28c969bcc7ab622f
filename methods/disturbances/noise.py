"""Sensing noise: a first-order Gauss-Markov position error (the ``sensing_noise`` model).

    e(k+1) = a e(k) + sqrt(1 - a^2) sigma xi,   a = exp(-T_s / tau),   xi ~ N(0, I)

A stationary process of standard deviation sigma and correlation time tau sampled every T_s
(tau = 0: white, a = 0). Started from N(0, sigma^2), it is stationary from the first sample.
"""

from __future__ import annotations

import math

import numpy as np


def correlation(guidance_period: float, tau: float) -> float:
    """a = exp(-T_s / tau), the error's correlation from one tick to the next (0 when tau is 0)."""
    return math.exp(-guidance_period / tau) if tau > 0 else 0.0


def gauss_markov_step(error: np.ndarray, a: float, std: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """e(k+1) = a e(k) + sqrt(1 - a^2) sigma xi for errors ``error`` (N, 3), ``std`` sigma per axis (3,)."""
    return a * error + math.sqrt(1.0 - a * a) * std * rng.standard_normal(error.shape)
