"""Intervals over seeds: of a mean (Student-t, or a percentile bootstrap for bounded quantities)
and of a rate (Wilson).

A Student-t interval is symmetric about the mean, so for a quantity that cannot be negative (a
distance, a count, a time) it can reach below zero, which no run could give (a smallest separation
of ``0.00015 [-0.00023, 0.00053]`` m). For those quantities (:func:`lower_bound`) the interval is
the percentile bootstrap of the mean: the 2.5 and 97.5 percentiles of the means of ``BOOTSTRAP``
resamples drawn with replacement, from a fixed seed so the same runs give the same table. Its ends
are means of the observed values, so they stay inside what the quantity can take. On request
(``within_values``: the reproduction report, 30 or more seeds) a signed quantity gets the bootstrap
too where its Student-t interval reaches past the smallest or largest value observed (a heavy
tail: one seed far from the others), so no interval lies outside every run. Like every interval
of a handful of seeds it is approximate; with few seeds it is narrower than Student-t.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

BOOTSTRAP = 10_000
"""Resamples of the percentile bootstrap."""
BOOTSTRAP_SEED = 0

NON_NEGATIVE = ("collisions", "clearance_violations", "steps", "duration", "agents", "healthy_at_end",
                "wall_time", "realtime_factor", "step_ms_median", "min_separation", "min_pair_distance",
                "max_speed", "max_speed_actual", "tracking_error_max", "psi_drift_max", "_time", "_count",
                "_ms", "_distance", "_rms", "_speed")
"""Metric names (a key's last dotted part, or its ending) of quantities that cannot be negative:
counts, durations and times, distances between agents, speeds (``cem.max_speed_actual``,
``disturbances.wind.peak_speed``), RMS errors, CEM's largest tracking error and streamline drift (an
absolute value). A signed quantity (a clearance, which is negative inside an obstacle; a margin such
as ``cem.min_exclusion_margin``) is not listed, and gets the Student-t interval."""


def lower_bound(metric: str) -> float | None:
    """0.0 when the metric cannot be negative (:data:`NON_NEGATIVE`), else None."""
    last = metric.rsplit(".", 1)[-1]
    for word in NON_NEGATIVE:
        if last == word or (word.startswith("_") and last.endswith(word)):
            return 0.0
    return None


def _finite(values: Iterable[float | None]) -> np.ndarray:
    return np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)


def mean_ci(values: Iterable[float | None], level: float = 0.95) -> tuple[float, float, int]:
    """Mean and half-width of its Student-t confidence interval (NaN half-width for n < 2)."""
    # The t quantile from scipy.special: importing scipy.stats costs ~0.5 s, serial at a sweep's end.
    from scipy.special import stdtrit

    x = _finite(values)
    n = len(x)
    if n == 0:
        return math.nan, math.nan, 0
    if n == 1:
        return float(x[0]), math.nan, 1
    half = stdtrit(n - 1, 0.5 + level / 2) * x.std(ddof=1) / math.sqrt(n)
    return float(x.mean()), float(half), n


def mean_interval(values: Iterable[float | None], bounded: bool = False,
                  level: float = 0.95, within_values: bool = False) -> tuple[float, float, float, int]:
    """``(mean, low, high, n)`` over the finite values: Student-t, or with ``bounded`` (a quantity
    that cannot be negative) the percentile bootstrap; with ``within_values`` the bootstrap too where
    the t interval would reach past the smallest or largest value (a signed, heavy-tailed quantity
    over many seeds, as in the reproduction report). NaN ends for n < 2; both ends equal the mean
    when every value is the same."""
    x = _finite(values)
    n = len(x)
    if n < 2:
        mean = float(x[0]) if n else math.nan
        return mean, math.nan, math.nan, n
    mean = float(x.mean())
    if np.all(x == x[0]):
        return mean, mean, mean, n
    if not bounded:
        _, half, _ = mean_ci(x, level)
        if not within_values or (x.min() <= mean - half and mean + half <= x.max()):
            return mean, mean - half, mean + half, n
        # A heavy tail (one seed far out) widens the t interval past every value observed, which no
        # mean of these runs could reach: the percentile bootstrap's ends stay within them.
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    means = x[rng.integers(0, n, size=(BOOTSTRAP, n))].mean(axis=1)
    low, high = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return mean, float(min(low, mean)), float(max(high, mean)), n


def wilson(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate (well behaved at 0 and 1, unlike Wald)."""
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    lower = 0.0 if successes == 0 else max(0.0, centre - half)  # exact at the ends (no rounding)
    upper = 1.0 if successes == n else min(1.0, centre + half)
    return lower, upper
