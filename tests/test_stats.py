"""swarmscene.sweeps.stats: intervals over seeds (issue #26, "intervals ignore bounds").

Exact values for the Student-t interval and Wilson's; the percentile bootstrap of a quantity that
cannot be negative stays inside [min, max] of the values (so never below zero) and is the same on
every call (a fixed seed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmscene.sweeps.stats import BOOTSTRAP, lower_bound, mean_ci, mean_interval, wilson


def test_student_t_interval_exact():
    mean, low, high, n = mean_interval([1.0, 2.0, 3.0, 4.0])
    half = 3.182446305284263 * math.sqrt(5.0 / 3.0) / 2.0  # t_{0.975, 3} s / sqrt(n), s^2 = 5/3
    assert (mean, n) == (2.5, 4)
    assert low == pytest.approx(2.5 - half, rel=1e-12) and high == pytest.approx(2.5 + half, rel=1e-12)
    assert mean_ci([1.0, 2.0, 3.0, 4.0])[1] == pytest.approx(half, rel=1e-12)


def test_student_t_goes_below_zero_where_the_bootstrap_does_not():
    """The issue's case: a smallest separation of 0.00015 m whose t interval reached -0.00023 m."""
    x = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.00454]
    _, t_low, _, _ = mean_interval(x)
    mean, low, high, n = mean_interval(x, bounded=True)
    assert t_low < 0.0
    assert low >= 0.0 and min(x) <= low <= mean <= high <= max(x) and n == 10


@pytest.mark.parametrize("seed", range(5))
def test_bootstrap_stays_within_the_values_and_is_deterministic(seed):
    x = np.random.default_rng(seed).exponential(1.0, size=int(3 + 7 * seed))
    first, again = mean_interval(x, bounded=True), mean_interval(list(x), bounded=True)
    assert first == again
    mean, low, high, _ = first
    assert x.min() <= low <= mean <= high <= x.max()


def test_bootstrap_exact_for_two_values():
    """Resamples of (0, 1) have means 0, 1/2, 1 with probabilities 1/4, 1/2, 1/4: the 2.5 and 97.5
    percentiles of 10,000 of them are 0 and 1."""
    assert BOOTSTRAP == 10_000
    assert mean_interval([0.0, 1.0], bounded=True) == (0.5, 0.0, 1.0, 2)


def test_degenerate_inputs():
    assert mean_interval([3.0, 3.0, 3.0], bounded=True) == (3.0, 3.0, 3.0, 3)
    mean, low, high, n = mean_interval([2.0, None, float("nan")])
    assert (mean, n) == (2.0, 1) and math.isnan(low) and math.isnan(high)
    assert math.isnan(mean_interval([])[0])


def test_wilson_exact():
    assert wilson(0, 30) == (0.0, pytest.approx(0.11351, abs=1e-5))
    assert wilson(30, 30) == (pytest.approx(0.88649, abs=1e-5), 1.0)
    low, high = wilson(2, 30)
    assert low == pytest.approx(0.018477, abs=1e-6) and high == pytest.approx(0.213235, abs=1e-6)
    assert all(math.isnan(v) for v in wilson(0, 0))


@pytest.mark.parametrize("metric", ["min_separation", "collisions", "violations.separation.first_time",
                                    "cem.min_pair_distance", "cem.max_speed", "cem.max_speed_actual",
                                    "cem.tracking_error_max", "cem.psi_drift_max", "cem.handback_time",
                                    "vrb.tracking_rms", "disturbances.wind.peak_speed", "step_ms_median"])
def test_non_negative_metrics(metric):
    assert lower_bound(metric) == 0.0


@pytest.mark.parametrize("metric", ["min_clearance", "cem.min_actual_clearance", "cem.min_exclusion_margin",
                                    "value", "outdoor.heading_error"])
def test_signed_metrics_get_no_bound(metric):
    assert lower_bound(metric) is None


def test_a_signed_heavy_tailed_quantity_gets_an_interval_within_its_values():
    """Nine seeds at 0 and one far out: Student t reaches below every value observed (a mean of these
    runs cannot), so the interval is the percentile bootstrap, inside [min, max]."""
    from swarmscene.sweeps.stats import mean_ci, mean_interval

    values = [0.0] * 9 + [1.0e-3]
    mean, half, _ = mean_ci(values)
    assert mean - half < min(values)  # what the table printed before
    mean, low, high, n = mean_interval(values, within_values=True)
    assert n == 10 and min(values) <= low <= mean <= high <= max(values)
    spread = list(np.linspace(0.0, 1.0, 30))  # a t interval inside the values stays Student t
    m, h, _ = mean_ci(spread)
    assert mean_interval(spread, within_values=True) == (m, m - h, m + h, 30)


def test_the_grouped_table_shows_a_renamed_metric_under_its_new_name_only():
    from swarmscene.sweeps import tables

    assert "cem.theorem1_holds" in tables.renamed_metrics()
    rows = [{"job": str(k), "status": "complete", "seed": k, "success": True, "cem.theorem1_holds": False,
             "cem.theorem1_precondition_met": False, "min_separation": 1.0 + k} for k in range(2)]
    text = tables.markdown(rows, "t")
    assert "cem.theorem1_precondition_met (rate)" in text and "cem.theorem1_holds" not in text
