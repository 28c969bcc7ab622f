"""swarmscene-bench (docs/suite.md): the v1 tasks are >= 20 in >= 4 families, composed, validated
and frozen (their hash is the shipped one; an edit is detected); runs are scored by the documented
rule and refused when they changed their task; the statistics are rliable's, recomputed from the
written marl-eval JSON; the shipped reference results cover every task x method x seed and their
statistics recompute from the shipped scores."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from rliable import metrics as rl_metrics
from rliable.library import score_distributions
from scipy import stats as scipy_stats

from swarmscene import api
from swarmscene.core.task import FAMILIES, TaskConfig
from swarmscene.suite import definition, results, score, stats

ROOT = Path(__file__).resolve().parents[1]
V1 = definition.frozen("v1")


def test_v1_has_at_least_twenty_tasks_in_at_least_four_families_each_scored_and_seeded():
    assert V1["suite"] == "swarmscene-bench" and V1["version"] == "v1"
    assert len(V1["tasks"]) >= 20
    families = {}
    for task_id, entry in V1["tasks"].items():
        task = TaskConfig.model_validate(entry["definition"]["task"])  # the schema holds the record
        assert task.id == task_id and task.version == "v1"
        assert task.horizon == entry["definition"]["clock"]["duration"]  # the fixed horizon is the run's
        assert task.seeds == list(range(10))
        families.setdefault(task.family, []).append(task_id)
    assert set(families) == set(FAMILIES) and all(len(v) >= 3 for v in families.values())


def test_v1_still_composes_to_its_frozen_definitions_and_hash():
    """The shipped record is what the task files compose to now: a changed task fails here."""
    assert definition.tasks("v1") == sorted(V1["tasks"])
    assert definition.changed_tasks("v1") == []
    assert definition.version_hashes(definition.tasks("v1"))["sha256"] == V1["sha256"]
    assert definition.digest({t: e["definition"] for t, e in V1["tasks"].items()}) == V1["sha256"]


def test_an_edited_task_changes_its_hash_and_the_version_hash(monkeypatch):
    edited = json.loads(json.dumps(V1["tasks"]["dense_swap_ring"]["definition"]))
    edited["clock"]["duration"] = 29.0
    real = definition.definition
    monkeypatch.setattr(definition, "definition", lambda t: edited if t == "dense_swap_ring" else real(t))
    assert definition.changed_tasks("v1") == ["dense_swap_ring"]


def test_a_task_definition_leaves_out_the_method_and_the_seed():
    d = V1["tasks"]["dense_swap_ring"]["definition"]
    assert "avoidance" not in d and "seed" not in d
    assert d["task"]["score"]["metric"] == "duration" and d["observers"] == {"swarmlab": {}}


def test_the_sweep_preset_runs_every_v1_task():
    preset = yaml.safe_load((ROOT / "scenarios" / "sweep" / "suite_v1.yaml").read_text())
    params = preset["hydra"]["sweeper"]["params"]
    assert sorted(params["task"].split(",")) == sorted(V1["tasks"])
    assert len(params["avoidance"].split(",")) >= 4 and params["seed"] == "range(0,10)"


@pytest.mark.parametrize(("raw", "success", "want"), [
    (14.0, True, (14.0, 1.0, True)),       # the best value
    (10.0, True, (10.0, 1.0, True)),       # beyond best: clipped
    (27.0, True, (27.0, 0.5, True)),       # half-way; 27 <= 30 passes
    (35.0, True, (35.0, 5 / 26, False)),   # slower than the pass threshold
    (20.0, False, (20.0, 0.0, False)),     # not a success: 0, and no pass
    (None, True, (40.0, 0.0, False)),      # undefined: the worst value
])
def test_normalised_score_and_pass_rule(raw, success, want):
    rule = {"worst": 40.0, "best": 14.0, "higher_is_better": False, "zero_unless_success": True, "pass_threshold": 30.0}
    assert score.normalised_score(raw, rule, success) == pytest.approx(want)


def test_higher_is_better_without_success_gate():
    rule = {"worst": 0.0, "best": 1.5, "higher_is_better": True, "zero_unless_success": False, "pass_threshold": 0.56}
    assert score.normalised_score(0.75, rule, False) == pytest.approx((0.75, 0.5, True))
    assert score.normalised_score(0.5, rule, True) == pytest.approx((0.5, 1 / 3, False))


def test_a_run_is_scored_against_its_task_and_refused_when_it_changed_it(tmp_path):
    result = api.run(["task=dense_swap_ring", "avoidance=orca", "seed=3", "output.summary=false"],
                     output_dir=tmp_path / "a")
    got = score.score_run(tmp_path / "a")
    assert isinstance(got, score.RunScore)
    rule = V1["tasks"]["dense_swap_ring"]["definition"]["task"]["score"]
    raw, normalised, passed = score.normalised_score(result.metrics["duration"], rule, result.metrics["success"])
    assert (got.task, got.method, got.seed, got.version) == ("dense_swap_ring", "orca", 3, "v1")
    assert (got.raw, got.normalised, got.passed) == (raw, normalised, passed)
    assert 0 < got.normalised <= 1 and got.success
    api.run(["task=dense_swap_ring", "avoidance=orca", "clock.duration=5", "output.summary=false"],
            output_dir=tmp_path / "b")
    refused = score.score_run(tmp_path / "b")
    assert refused == score.Unscored(str(tmp_path / "b"), "clock.duration: differs from task 'dense_swap_ring' of v1")
    api.run(["task=dense_swap_ring", "avoidance=orca", "seed=11", "output.summary=false"], output_dir=tmp_path / "c")
    assert score.score_run(tmp_path / "c").reason == "seed 11 is not one of task 'dense_swap_ring''s seeds"
    api.run(["scenario=swap", "clock.duration=1", "output.summary=false"], output_dir=tmp_path / "d")
    assert score.score_run(tmp_path / "d").reason == "no task section (not a suite run)"


def test_a_run_that_changed_an_option_its_task_leaves_to_defaults_is_not_scored(tmp_path):
    """The frozen definition holds what a task file sets; a scored run must also use every other
    option as the task gives it, the plugins' and observers' defaults included (a wider arrival
    tolerance scored the swap at its best, a sparser observer changed the flock's score). The
    method's own options, the seed and the outputs are free."""
    common = ["task=dense_swap_ring", "avoidance=orca", "seed=3", "output.summary=false"]
    api.run([*common, "formation.arrival_tolerance=20"], output_dir=tmp_path / "tol")
    assert score.score_run(tmp_path / "tol").reason == (
        "formation.arrival_tolerance: differs from what task 'dense_swap_ring' of v1 uses in this engine "
        "(its defaults included)")
    api.run([*common, "observers.swarmlab.every=1000"], output_dir=tmp_path / "every")
    assert score.score_run(tmp_path / "every").reason.startswith("observers.swarmlab.every: differs")
    api.run([*common, "avoidance.time_horizon=3.0", "output.trajectory=false"], output_dir=tmp_path / "free")
    free = score.score_run(tmp_path / "free")
    assert isinstance(free, score.RunScore) and free.method == "orca"


def test_a_job_whose_method_raised_scores_the_worst_on_its_task(tmp_path):
    """suite_v1.yaml: "a method that cannot fly a task scores 0 there". A failed job (no
    config.yaml: its task, method and seed composed from its overrides) is scored 0 normalised and
    not passed, so its task stays in every method's numbers; a failed job that names no task, and
    a job folder that is a link, are listed unscored with why."""
    from swarmscene.sweeps import records

    sweep = tmp_path / "sweep"
    for job, overrides in (("0", ["task=dense_swap_ring", "avoidance=cbf", "seed=4"]), ("1", ["scenario=swap"])):
        (sweep / job).mkdir(parents=True)
        records.write_overrides(sweep / job, overrides)
        records.record_failure(sweep / job, RuntimeError("the method raised"), {"seed": 4})
    api.run(["task=dense_swap_ring", "avoidance=orca", "seed=3", "output.summary=false"], output_dir=tmp_path / "run")
    (sweep / "2").symlink_to(tmp_path / "run", target_is_directory=True)
    scored, unscored = score.score_sweep(sweep)
    rule = V1["tasks"]["dense_swap_ring"]["definition"]["task"]["score"]
    assert [(s.task, s.method, s.seed, s.raw, s.normalised, s.passed, s.success) for s in scored] == [
        ("dense_swap_ring", "cbf", 4, float(rule["worst"]), 0.0, False, False)]
    assert {Path(u.run).name: u.reason for u in unscored} == {
        "1": "the job failed; no task section (not a suite run)",
        "2": "a symbolic link (not read: a job's folder is a directory of the sweep)"}


def test_scoring_refuses_a_missing_directory_an_output_link_and_nothing_in_common(tmp_path, capsys):
    """One line and status 1, nothing written: a mistyped sweep directory (it was scored as 'no
    method' beside the reference), a ``suite/`` folder planted as a link out of the sweep, and
    methods that share no task on common seeds (the aggregates were NaN)."""
    from swarmscene.suite.__main__ import main

    assert main(["score", str(tmp_path / "typo")]) == 1 and not (tmp_path / "typo").exists()
    assert capsys.readouterr().err == f"swarmscene: {tmp_path / 'typo'}: not a sweep directory\n"
    sweep = tmp_path / "sweep"
    api.run(["task=dense_swap_ring", "avoidance=orca", "seed=3", "output.summary=false"], output_dir=sweep / "0")
    (tmp_path / "elsewhere").mkdir()
    (sweep / "suite").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    assert main(["score", str(sweep), "--no-reference"]) == 1 and not any((tmp_path / "elsewhere").iterdir())
    assert "not a directory of the sweep (a link or a file is refused" in capsys.readouterr().err
    rows = synthetic_rows(("a",), TASKS5[:1], range(3)) + synthetic_rows(("b",), TASKS5[1:2], range(3))
    with pytest.raises(ValueError, match=r"^no task that every method \(a, b\) ran on the same seeds"):
        stats.summarize(rows)


def test_the_page_refuses_a_missing_page_a_page_without_its_block_and_a_damaged_results_file(tmp_path, capsys):
    """One line and status 1 before any picture is flown or written: a --docs page that is not
    there (the command run outside the repository), one without the generated block (it failed
    with 'substring not found' after drawing every task), and a results.json that is not the
    suite's (a TypeError or KeyError traceback)."""
    from swarmscene.suite.__main__ import main

    results = tmp_path / "sweep" / "suite" / "results.json"
    results.parent.mkdir(parents=True)
    page = tmp_path / "page.md"
    block = "<!-- suite: generated by python -m swarmscene.suite page -->\nold\n<!-- end of suite -->\n"
    cases = [
        ('{"version": "v1", "methods": ["a"], "tasks": []}', None, f"{page}: no such page"),
        ('{"version": "v1", "methods": ["a"], "tasks": []}', "# no block\n", f"{page}: no generated block to replace"),
        ('{"version": ["v1"]}', block, f"{results}: version ['v1'] is not a frozen suite version"),
        ('{"version": "v1", "methods": 3, "tasks": []}', block, f"{results}: 'methods' is not a list of names"),
        ('{"version": "v1", "methods": ["a"], "tasks": []}', block,
         f"{results}: not a complete suite results file (KeyError: 'aggregate')"),
    ]
    for content, text, line in cases:
        results.write_text(content)
        page.unlink(missing_ok=True)
        if text is not None:
            page.write_text(text)
        assert main(["page", str(tmp_path / "sweep"), "--docs", str(page)]) == 1
        assert capsys.readouterr().err.startswith(f"swarmscene: {line}")
        assert not (tmp_path / "page").exists() and (text is None or page.read_text() == text)


TASKS5 = tuple(sorted(V1["tasks"])[:5])


def synthetic_rows(methods=("a", "b", "c"), tasks=TASKS5, seeds=range(10)):
    rng = np.random.default_rng(7)
    rows = []
    for k, m in enumerate(methods):
        for t in tasks:
            for s in seeds:
                x = float(np.clip(rng.normal(0.3 + 0.2 * k, 0.25), 0, 1))
                rows.append({"suite": "swarmscene-bench", "version": "v1", "task": t, "family": "dense", "method": m,
                             "seed": s, "raw": 10 * x, "normalised": x, "passed": x > 0.5, "success": True,
                             "run": f"{m}{t}{s}"})
    return rows


def test_statistics_read_back_from_the_marl_eval_json_with_rliable(tmp_path):
    """The written marl_eval.json, loaded into rliable's (runs x tasks) matrices, gives the table's
    IQM (also scipy's 25 % trimmed mean), mean, probability of improvement and profiles."""
    rows = synthetic_rows()
    summary = stats.summarize(rows, aggregate_reps=500, reps=200)
    results.write_results(tmp_path, rows, [], "v1", summary)
    data = json.loads((tmp_path / "marl_eval.json").read_text())["swarmscene-bench-v1"]
    written = json.loads((tmp_path / "results.json").read_text())
    assert written["sha256"] == V1["sha256"] and written["version"] == "v1"
    tasks = sorted(data)
    matrices = {m: np.array([[data[t][m][f"run_{s}"]["absolute_metrics"]["normalised_score"][0] for t in tasks]
                             for s in range(10)]) for m in ("a", "b", "c")}
    for m, x in matrices.items():
        agg = written["aggregate"][m]
        assert agg["iqm"] == pytest.approx(rl_metrics.aggregate_iqm(x), abs=1e-12)
        assert agg["iqm"] == pytest.approx(scipy_stats.trim_mean(x.ravel(), 0.25), abs=1e-12)
        assert agg["mean"] == pytest.approx(x.mean(), abs=1e-12)
        assert agg["iqm_ci"][0] <= agg["iqm"] <= agg["iqm_ci"][1]
        profile = written["performance_profile"][m]
        np.testing.assert_allclose(profile["fraction"], score_distributions(x, np.array(profile["tau"])), atol=1e-12)
        np.testing.assert_allclose(profile["fraction"], [(x > tau).mean() for tau in profile["tau"]], atol=1e-12)
    for x in matrices:
        for y in matrices:
            if x != y:
                p = written["probability_of_improvement"][f"{x}>{y}"]["p"]
                assert p == pytest.approx(rl_metrics.probability_of_improvement(matrices[x], matrices[y]), abs=1e-12)
    assert written["probability_of_improvement"]["c>a"]["p"] > 0.5
    raw_t1 = np.array([data[TASKS5[0]]["b"][f"run_{s}"]["absolute_metrics"]["score"][0] for s in range(10)])
    assert written["per_task"][TASKS5[0]]["b"]["iqm"] == pytest.approx(scipy_stats.trim_mean(raw_t1, 0.25), abs=1e-12)
    assert "| c |" in (tmp_path / "leaderboard.md").read_text()


def test_a_method_on_fewer_seeds_is_compared_on_the_common_ones():
    rows = synthetic_rows() + [r | {"method": "new"} for r in synthetic_rows(("a",), TASKS5[1:2], range(3))]
    matrices, tasks, seeds = stats.score_matrices(rows)
    assert tasks == [TASKS5[1]] and seeds == [0, 1, 2] and {m: x.shape for m, x in matrices.items()} == {
        "a": (3, 1), "b": (3, 1), "c": (3, 1), "new": (3, 1)}


REFERENCE = results.reference_rows("v1")


def test_the_reference_results_cover_every_task_by_four_methods_by_ten_seeds():
    cells = {(r["task"], r["method"], r["seed"]) for r in REFERENCE}
    methods = {r["method"] for r in REFERENCE}
    assert len(methods) >= 4 and {"none", "orca", "cbf", "potential"} <= methods
    assert cells == {(t, m, s) for t in V1["tasks"] for m in methods for s in range(10)}
    assert len(REFERENCE) == len(cells)
    for r in REFERENCE:
        rule = V1["tasks"][r["task"]]["definition"]["task"]["score"]
        assert 0.0 <= r["normalised"] <= 1.0 and r["version"] == "v1"
        if rule["zero_unless_success"] and not r["success"]:
            assert r["normalised"] == 0.0 and not r["passed"]


def test_the_shipped_statistics_recompute_from_the_shipped_scores_with_rliable():
    shipped = json.loads((ROOT / "docs" / "suite" / "results_v1.json").read_text())
    assert shipped["sha256"] == V1["sha256"] and shipped["tasks"] == sorted(V1["tasks"])
    matrices, tasks, seeds = stats.score_matrices(REFERENCE)
    assert tasks == shipped["tasks"] and seeds == list(range(10))
    for m, x in matrices.items():
        assert shipped["aggregate"][m]["iqm"] == pytest.approx(rl_metrics.aggregate_iqm(x), abs=1e-12)
        assert shipped["aggregate"][m]["mean"] == pytest.approx(x.mean(), abs=1e-12)


def test_the_vectorised_intervals_agree_with_rliables_own_bootstrap():
    """The intervals are rliable's stratified bootstraps drawn in one numpy pass: the same
    interval as rliable's get_interval_estimates to bootstrap noise (0.01 at 4,000 replications)."""
    from rliable import library as rly

    matrices, _, _ = stats.score_matrices(synthetic_rows())
    mine = stats.aggregates(matrices, reps=4000)["b"]
    _, ci = rly.get_interval_estimates({"b": matrices["b"]}, lambda x: np.array([rl_metrics.aggregate_iqm(x)]),
                                       reps=4000, random_state=np.random.RandomState(1))
    np.testing.assert_allclose(mine["iqm_ci"], ci["b"].ravel(), atol=0.01)
    mine_p = stats.improvement({k: matrices[k] for k in ("a", "c")}, reps=300)["c>a"]
    _, ci = rly.get_interval_estimates({"ca": [matrices["c"], matrices["a"]]}, rl_metrics.probability_of_improvement,
                                       reps=300, random_state=np.random.RandomState(1))
    np.testing.assert_allclose(mine_p["ci"], np.ravel(ci["ca"]), atol=0.03)


def test_the_check_tells_identical_scores_from_close_different_and_missing_ones():
    from swarmscene.suite.check import compare, report

    reference = synthetic_rows(methods=("a", "b"))
    same = [dict(r) for r in reference if r["method"] == "a"]  # method b was not run: not compared
    c = compare(same, reference)
    assert (c.compared, c.identical, c.close, c.different, c.missing) == (50, 50, [], [], [])
    assert c.reproduced and report(c, "v1", 1e-12).endswith("0 different, 0 missing; reproduced")
    same[0]["raw"] *= 1 + 4e-16  # its last bits: within the tolerance
    same[1]["normalised"] = same[1]["normalised"] * (1 + 1e-9) + 1e-9  # beyond it
    same[2]["passed"] = not same[2]["passed"]  # a verdict
    lost = same.pop(3)
    c = compare(same, reference)
    assert (c.compared, c.identical, len(c.close), len(c.different), len(c.missing)) == (49, 46, 1, 2, 1)
    assert not c.reproduced
    text = report(c, "v1", 1e-12)
    assert "NOT reproduced" in text and f"missing: {lost['task']} a seed {lost['seed']}" in text
    assert f"passed {same[2]['passed']} (reference {not same[2]['passed']})" in text
    assert compare(same, reference, partial=True).missing == []



def test_reference_runs_flown_again_reproduce_their_shipped_scores(tmp_path):
    """Two reference runs flown again give the shipped reference's scores; ``python -m swarmscene.suite
    check`` says so. The first is scored on positions: the same float. The second by a swarmlab metric
    (lambda_2, the eigenvalue path): the same float on the machine that made the reference, within
    the check's rtol on another CPU, whose BLAS dot products round differently (docs/suite.md)."""
    from swarmscene.suite.__main__ import main

    for k, job in enumerate((["task=dense_swap_ring", "avoidance=orca", "seed=3"],
                             ["task=coverage_goal_flock", "avoidance=potential", "seed=7"])):
        api.run([*job, "output.summary=false"], output_dir=tmp_path / str(k))
    from swarmscene.suite.check import check_sweep

    reproduced, text = check_sweep(tmp_path, partial=True)
    assert reproduced, text
    head = "swarmscene-bench v1: 2 runs compared with the reference: "
    assert text.startswith((f"{head}2 bit for bit, 0 within rtol 1e-12, 0 different",
                            f"{head}1 bit for bit, 1 within rtol 1e-12 (largest ")), text
    assert "within rtol 1e-12 (largest" not in text or "coverage_goal_flock potential seed 7" in text, text
    assert main(["check", str(tmp_path)]) == 1  # the whole reference: 998 of its runs are missing here
