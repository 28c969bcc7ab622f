"""The reproduction report (benchmarks/reproduction/reproduce.py) and the paper claims it checks.

Fast: every claim in benchmarks/reproduction/claims/ is well formed and every reading composes into a valid
scenario; the report's statistics and verdicts are exact on hand-made results. Slow (``pytest -m
slow tests/test_reproduction.py``): every claim's default reading is re-run on all its seeds and
must hold within the tolerance the claim states (or, declared ``expect: misses``, still miss it).
"""

from __future__ import annotations

import math
import sys
from functools import cache
from pathlib import Path

import pytest
import script_modules

from swarmscene import api

ROOT = Path(__file__).resolve().parents[1]


reproduce = script_modules.load("reproduce", ROOT / "benchmarks" / "reproduction" / "reproduce.py")
CLAIMS = reproduce.load_claims()


def test_claims_exist_for_every_paper():
    assert {c.paper for c in CLAIMS} == {"cem", "vrb", "thesis"}


@pytest.mark.parametrize("claim", CLAIMS, ids=lambda c: c.id)
def test_every_reading_composes(claim):
    """A typo in a claim's overrides or reading fails here, not after an hour of runs."""
    for reading in claim.readings:
        job = claim.jobs(reading)[0]
        if job.function is not None:
            module, name = job.function.split(":")
            sys.path.insert(0, str(ROOT / "benchmarks" / "reproduction"))
            try:
                assert callable(getattr(__import__(module, fromlist=[name]), name))
            finally:
                sys.path.remove(str(ROOT / "benchmarks" / "reproduction"))
        else:
            api.load([*job.overrides, f"seed={job.seed}"])


def _claim(**kw):
    base = dict(id="x", paper="cem", where="Fig. 1", quantity="q", paper_value=1.0,
                overrides=["scenario=default"], metric="m", seeds=4)
    return reproduce.Claim(**{**base, **kw})


def _results(claim, values, reading=None):
    jobs = claim.jobs(reading or claim.default_reading)
    return {job.key: {"m": v} for job, v in zip(jobs, values, strict=True)}


def test_rate_gets_wilson_interval_and_tolerance_verdict():
    claim = _claim(paper_value=1.0, tolerance=0.3)
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [True, True, True, False]))
    assert out.rate and out.mean == 0.75 and not out.deterministic
    # Wilson 95 % for 3/4: centre (0.75 + z^2/8) / (1 + z^2/4), half-width by the textbook formula.
    z = 1.959963984540054
    centre = (0.75 + z * z / 8) / (1 + z * z / 4)
    half = z * math.sqrt(0.75 * 0.25 / 4 + z * z / 64) / (1 + z * z / 4)
    assert out.low == pytest.approx(centre - half, abs=1e-12)
    assert out.high == pytest.approx(centre + half, abs=1e-12)
    # Within the stated tolerance (|0.75 - 1| <= 0.3), yet the interval [0.30, 0.95] excludes 1.
    assert out.holds and not out.contains_paper


def test_equal_claim_mean_interval_and_verdicts():
    claim = _claim(paper_value=2.4, tolerance=0.05)
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [2.0, 2.2, 2.4, 2.6]))
    assert out.mean == pytest.approx(2.3)
    sd = math.sqrt(sum((v - 2.3) ** 2 for v in [2.0, 2.2, 2.4, 2.6]) / 3)
    half = 3.182446305284263 * sd / 2  # t(0.975, 3) * s / sqrt(4)
    assert (out.low, out.high) == pytest.approx((2.3 - half, 2.3 + half))
    assert out.worst == 2.0  # farthest from the paper's 2.4
    assert not out.holds and out.contains_paper  # |2.3 - 2.4| > 0.05, yet 2.4 is inside the interval
    wider = _claim(paper_value=2.4, tolerance=0.15)
    assert reproduce.evaluate(wider, wider.default_reading, _results(wider, [2.0, 2.2, 2.4, 2.6])).holds


def test_bounds_judge_the_worst_seed():
    upper = _claim(relation="<=", paper_value=1.6)
    out = reproduce.evaluate(upper, upper.default_reading, _results(upper, [1.2, 1.5, 1.59, 1.61]))
    assert out.worst == 1.61 and not out.holds and not out.contains_paper
    lower = _claim(relation=">=", paper_value=0.3, tolerance=0.05)
    out = reproduce.evaluate(lower, lower.default_reading, _results(lower, [0.4, 0.31, 0.26, 0.5]))
    assert out.worst == 0.26 and out.holds and not out.contains_paper


def test_identical_seeds_are_marked_deterministic_with_no_interval():
    claim = _claim(paper_value=2.16, tolerance=0.0)
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [2.16] * 4))
    assert out.deterministic and out.low == out.high == 2.16 and out.holds


def test_a_missing_metric_fails_the_claim():
    claim = _claim(paper_value=1.0, tolerance=1.0)
    results = _results(claim, [1.0, 1.0, 1.0, 1.0])
    del results[next(iter(results))]["m"]
    out = reproduce.evaluate(claim, claim.default_reading, results)
    assert out.missing == 1 and not out.holds


def test_a_known_miss_must_say_why():
    with pytest.raises(ValueError, match="expect: misses needs a note"):
        _claim(expect="misses")
    assert _claim(expect="misses", note="eq. 4 is not kept exactly").expect == "misses"


def test_each_distinct_run_is_run_once():
    """Claims that read the same runs share them (keys are the overrides and the seed)."""
    a = _claim(id="a", metric="m")
    b = _claim(id="b", metric="other")
    keys = {j.key for c in (a, b) for j in c.jobs(c.default_reading)}
    assert len(keys) == 4


def test_non_negative_quantity_gets_a_bootstrap_interval_that_stays_above_zero():
    """Issue #26: a smallest separation of 0.00015 m had the t interval [-0.00023, 0.00053]."""
    values = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0015]
    signed = _claim(paper_value=0.0, relation=">=", seeds=10)
    distance = _claim(paper_value=0.0, relation=">=", seeds=10, metric="min_separation")
    t = reproduce.evaluate(signed, signed.default_reading, _results(signed, values))
    boot = reproduce.evaluate(distance, distance.default_reading,
                              {k: {"min_separation": v["m"]} for k, v in _results(signed, values).items()})
    assert 0.0 <= boot.low <= boot.mean <= boot.high <= max(values)
    # The signed claim's t interval reached below every seed too (issue #36): 10 seeds, a heavy
    # tail, so it is the bootstrap's as well.
    assert min(values) <= t.low
    forced = _claim(paper_value=0.0, relation=">=", seeds=10, bounded=True)
    assert reproduce.evaluate(forced, forced.default_reading, _results(forced, values)).low >= 0.0


def test_one_run_claim_reports_the_share_of_seeds_reaching_the_paper():
    claim = _claim(paper_value=2.4, tolerance=0.3, one_run=True, seeds=4)
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [2.0, 2.4, 2.5, 2.2]))
    assert out.reach == 3  # within 0.3 of 2.4
    low, high = reproduce.wilson(3, 4)
    assert reproduce._ours(out).endswith(
        f"; within tolerance of paper in 3 of 4 seeds (75.0 % [{100 * low:.1f}, {100 * high:.1f}])")
    bound = _claim(paper_value=2.4, relation=">=", one_run=True, seeds=4)
    assert reproduce.evaluate(bound, bound.default_reading, _results(bound, [2.0, 2.4, 2.5, 2.2])).reach == 2


def test_one_flight_is_judged_on_the_share_of_seeds_not_on_the_mean():
    """A figure of one flight: the mean of these seeds is exactly the paper's 2.4, yet only one seed
    in four flies within 0.3 of it: it does not hold. And the reverse: a mean outside the
    tolerance with three seeds in four within it holds."""
    claim = _claim(paper_value=2.4, tolerance=0.3, one_run=True, seeds=4)
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [1.8, 1.9, 2.5, 3.4]))
    assert out.mean == pytest.approx(2.4) and out.reach == 1 and not out.holds
    assert out.contains_paper  # the paper's flight lies within the range of ours
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [2.2, 2.2, 2.2, -1.0]))
    assert abs(out.mean - 2.4) > 0.3 and out.reach == 3 and out.holds
    far = reproduce.evaluate(claim, claim.default_reading, _results(claim, [1.0, 1.1, 1.2, 1.3]))
    assert not far.holds and not far.contains_paper


def test_unprinted_paper_value_is_marked_and_the_tolerance_has_its_own_column():
    """The paper column is the paper's number only: our tolerance, printed beside it as "± x",
    read as the paper's uncertainty."""
    assert reproduce._paper(_claim(printed=False, tolerance=0.1), rate=True) == "100.0 % †"
    assert reproduce._paper(_claim(tolerance=0.1), rate=True) == "100.0 %"
    assert reproduce._tolerance(_claim(tolerance=0.1), rate=True) == "± 10.0 %"
    assert reproduce._tolerance(_claim(relation=">=", tolerance=1.4e-6, unit="m"), rate=False) == "1.4e-06 m"
    assert reproduce._tolerance(_claim(relation=">="), rate=False) == "0"
    claim = _claim(paper_value=2.4, tolerance=0.3, unit="m/s")
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, [2.3, 2.4, 2.5, 2.4]))
    text = reproduce.markdown([out], {"date": "d", "commit": "c", "runs": 4, "cached": 0, "minutes": 0.0, "jobs": 1})
    header = next(line for line in text.splitlines() if line.startswith("| claim |"))
    row = next(line for line in text.splitlines() if line.startswith("| q (`x`)"))
    assert header.split(" | ")[2:4] == ["paper", "tolerance"]
    assert row.split(" | ")[2:4] == ["2.4 m/s", "± 0.3 m/s"]


def test_the_reading_a_shipped_scenario_flies_is_marked_where_it_is_not_the_first():
    claim = _claim(readings={"literal": [], "calibrated": ["x=1"]}, shipped="calibrated")
    assert reproduce._reading(claim, "calibrated") == "calibrated (shipped)"
    assert reproduce._reading(claim, "literal") == "literal"
    with pytest.raises(ValueError, match="shipped: not one of its readings"):
        _claim(shipped="other")
    vrb = {c.id: c for c in CLAIMS}["vrb_fig8_distance_field_off"]
    assert vrb.shipped != vrb.default_reading and "calibrated" in vrb.shipped


def test_readings_of_the_text_are_marked_as_such():
    """Issue #36: numbers the papers do not print are the report's †, each with its note."""
    by_id = {c.id: c for c in CLAIMS}
    for cid in ("cem_theorem2_holds", "cem_two_vehicle_clearance", "thesis_outdoor_min_separation",
                "cem_multi_failure_separation", "cem_multi_failure_commands_outside_a_p",
                "cem_fig10_k2_below_k1", "cem_fig10_k5_below_k2"):
        assert not by_id[cid].printed and by_id[cid].note.strip(), cid


def test_fig_5_13_is_quoted_as_printed_and_claims_nothing_at_0_7_m():
    """The thesis: effective "for widths larger than 0.7m", LOS interrupted "for widths smaller than
    0.7 m": no success claim at w = 0.7 m itself."""
    by_id = {c.id: c for c in CLAIMS}
    assert "thesis_indoor_straight_w070_success" not in by_id and "thesis_indoor_l_w070_success" not in by_id
    for width in ("080", "090"):
        assert by_id[f"thesis_indoor_straight_w{width}_success"].paper_value == 1.0
    text = " ".join(r["printed"] for r in reproduce.load_departures())
    assert '"for widths larger than 0.7m, the proposed solution was effective"' in text
    assert ">= 0.7" not in (ROOT / "benchmarks" / "reproduction" / "claims" / "thesis_indoor.yaml").read_text()


def test_kept_rows_are_re_evaluated_not_re_run(tmp_path):
    """--keep: the rows --only leaves out come from the earlier JSON, with their own run commit."""
    claim = _claim(paper_value=2.4, tolerance=0.3, one_run=True)
    stored = {"meta": {"commit": "abc1234"},
              "outcomes": [{"id": "x", "reading": "as printed", "rate": False, "values": [2.1, 2.4, 2.5], "missing": 1}]}
    path = tmp_path / "old.json"
    path.write_text(__import__("json").dumps(stored))
    out = reproduce.kept_outcomes(path, [claim])[("x", "as printed")]
    assert out.run == "abc1234" and out.values == [2.1, 2.4, 2.5] and out.missing == 1 and out.reach == 3
    assert not out.holds  # a missing run still fails the claim


def test_a_renamed_metric_still_reads_with_a_warning():
    with pytest.warns(DeprecationWarning, match="metric cem.theorem1_holds is renamed cem.theorem1_precondition_met"):
        claim = _claim(metric="cem.theorem1_holds")
    assert claim.metric == "cem.theorem1_holds"


def test_departures_table_lists_every_entry_with_its_option():
    rows = reproduce.load_departures()
    assert len(rows) >= 10
    whats = " ".join(r["what"] for r in rows)
    for needle in ("hand-back", "branch guard", "eq. 1 with several failures", "psi_obs", "psi_con",
                   "surrogate leaders", "edge deactivation", "doors", "Fig. 5.17", "settling bands",
                   "lambda_max", "eq. 7", "eq. 9", "spline", "respectively", "eq. 4.1", "rounding",
                   "position control", "eq. 4.10", "rooms around the corridors"):
        assert needle in whats
    table = reproduce.departures_table(rows)
    assert table[0] == "## Departures from the papers as printed" and len(table) == len(rows) + 9
    assert all(line.count(" | ") == 5 for line in table[6:-1] if line.startswith("| "))


@cache
def _runs(jobs: tuple) -> dict:
    return reproduce.run_jobs(jobs, n_jobs=2, progress=False)


@pytest.mark.slow
@pytest.mark.parametrize("claim", CLAIMS, ids=lambda c: c.id)
def test_claim_verdict_in_its_default_reading(claim):
    jobs = tuple(claim.jobs(claim.default_reading))
    out = reproduce.evaluate(claim, claim.default_reading, _runs(jobs))
    assert out.holds == (claim.expect == "holds"), (
        f"{claim.id} expected to {claim.expect.rstrip('s')}: "
        f"{claim.id}: paper {claim.relation} {claim.paper_value} (tolerance {claim.tolerance}), "
        f"ours mean {out.mean:.4g} [{out.low:.4g}, {out.high:.4g}], worst {out.worst:.4g}, "
        f"{out.missing} runs without the metric"
    )


def _one_function_claim_per_module():
    """(claim, reading) for each module of function claims, the reading with the most arguments."""
    chosen = {}
    for claim in CLAIMS:
        if claim.function is None:
            continue
        module = claim.function.split(":")[0]
        reading = max(claim.readings, key=lambda r: len(claim.readings[r]))
        if len(claim.readings[reading]) >= len(chosen.get(module, (None, ()))[1]):
            chosen[module] = (claim, claim.readings[reading], reading)
    # A module whose functions fly scenarios (fig_10_cem: two CEM flights a seed) is slow.
    return [pytest.param(claim, reading, marks=[pytest.mark.slow] if module in FLYING_MODULES else [])
            for module, (claim, _, reading) in chosen.items()]


FLYING_MODULES = {"fig_10_cem"}


@pytest.mark.parametrize(("claim", "reading"), _one_function_claim_per_module(),
                         ids=lambda x: getattr(x, "id", x))
def test_a_function_claims_command_runs_from_the_repository_root(claim, reading):
    """The report's command for a function claim (benchmarks/reproduction/, issue #27) runs as
    printed, from the root, and prints the value the report computes for seed 0."""
    import os
    import subprocess

    command = claim.command(reading)
    assert command.startswith("PYTHONPATH=benchmarks/reproduction python -c ")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    done = subprocess.run(command, shell=True, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    expected = reproduce.run_job(claim.jobs(reading)[0])["value"]
    printed = done.stdout.strip().splitlines()[-1]
    if isinstance(expected, bool):  # a rate's function prints True or False
        assert printed == str(expected)
    else:
        assert float(printed) == pytest.approx(expected, rel=1e-12)


def test_a_signed_heavy_tailed_quantity_keeps_its_interval_within_the_seeds():
    """29 seeds at zero and one far out: the t interval of the mean reached below the smallest
    value any seed gave; the report's interval stays within the seeds."""
    values = [0.0] * 29 + [1e-3]
    claim = _claim(paper_value=0.0, relation=">=", seeds=30)
    out = reproduce.evaluate(claim, claim.default_reading, _results(claim, values))
    from swarmscene.sweeps.stats import mean_ci

    mean, half, _ = mean_ci(values)
    assert mean - half < min(values)
    assert min(values) <= out.low <= out.mean <= out.high <= max(values)
