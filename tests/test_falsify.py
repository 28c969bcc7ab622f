"""The falsifier (+sweep=falsify): its search space, its ranking, and the worst case it writes.

The end-to-end test searches a counter-example that holds by construction: the CEM six-vehicle
case without an avoidance method, where agent 4 flies right behind the lead on its line, so the
lead hovering from t = 10 s is run into (at 14.16 s), while a failure at t = 30 s comes after the
mission has completed (24 s) and changes nothing. The worst case must be the violating trial and
its scenario file must reproduce that run to the bit.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys

import pytest
import yaml

from swarmscene import api
from swarmscene.core.errors import ConfigError
from swarmscene.tools import falsify

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
TIMING = ("wall_time", "realtime_factor", "step_ms_median", "cem.step_ms_median")


def composed(*overrides: str, preset: str = "falsify"):
    from omegaconf import OmegaConf

    return OmegaConf.create(api.compose([f"+sweep={preset}", *overrides]))


def hydra_node(*overrides: str):
    from hydra import compose, initialize_config_module

    from swarmscene.composition.searchpath import register_search_path

    register_search_path()
    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides), return_hydra_config=True).hydra


def new_trial():
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0)).ask()


@pytest.mark.parametrize("scenario, duration, n", [("cem_six_vehicle", 40.0, 6), ("outdoor_square", 400.0, 8)])
def test_the_failure_is_searched_over_the_run_and_every_agent_of_the_scenario(scenario, duration, n):
    config = composed(f"scenario={scenario}")
    assert [dict(e) for e in config.events] == [{"at": 2.0, "agents": [0], "name": "hover"}]  # the preset's
    trial = new_trial()
    falsify.failure_search_space(config, trial)
    time, agent = trial.distributions[falsify.FAILURE_TIME], trial.distributions[falsify.FAILURE_AGENT]
    assert (time.low, time.high) == (0.0, duration)
    assert tuple(agent.choices) == tuple(range(n))
    assert 0.0 <= trial.params[falsify.FAILURE_TIME] <= duration and trial.params[falsify.FAILURE_AGENT] in range(n)


def test_a_key_the_params_or_command_line_name_is_left_to_them():
    trial = new_trial()
    trial.suggest_float("++events.0.at", 20.0, 22.0)  # the command line's spelling of events.0.at
    trial.set_user_attr("seed", 3)
    falsify.failure_search_space(composed("scenario=cem_six_vehicle"), trial)
    assert set(trial.params) == {"++events.0.at", falsify.FAILURE_AGENT}


def test_a_scenario_without_a_searchable_event_is_one_line():
    config = composed("scenario=cem_six_vehicle")
    config.events = []
    with pytest.raises(ConfigError) as exc:
        falsify.failure_search_space(config, new_trial())
    assert exc.value.lines == [
        "events: the falsifier searches the first event's time and agent, so it needs one with a list of "
        "agents, e.g. {at: 2.0, agents: [0], name: hover} (got [])"
    ]
    config.events = [{"at": 2.0, "agents": {"sample": 1}, "name": "hover"}]
    with pytest.raises(ConfigError, match=r"\(got \[\{'at': 2.0, 'agents': \{'sample': 1\}, 'name': 'hover'\}\]\)"):
        falsify.failure_search_space(config, new_trial())


def test_robustness_ranks_a_violation_worst_and_the_deepest_first():
    def trial(k, sep, first=None):
        t = falsify.Trial(trial=k, overrides=[], status="complete", min_separation=sep, separation_limit=0.5)
        t.robustness, t.first_violation = falsify.robustness(sep, 0.5), first
        return t

    assert falsify.robustness(0.3, 0.5) == pytest.approx(-0.2) and math.isnan(falsify.robustness(None, 0.5))
    trials = [trial(0, 1.2), trial(1, 0.4, 9.0), trial(2, 0.1, 7.0), trial(3, 0.1, 5.0), trial(4, 0.6),
              falsify.Trial(trial=5, overrides=[], status="failed")]
    assert falsify.worst(trials).trial == 3  # rho -0.4 twice: the earlier violation is worse
    assert falsify.worst(trials[:2] + trials[4:]).trial == 1  # the only violation beats any safe run
    assert falsify.worst(trials[5:]) is None
    assert falsify.running_worst(trials) == [1.2, 0.4, 0.1, 0.1, 0.1, 0.1]


def test_the_full_space_adds_wind_and_packet_loss_by_their_config_keys():
    failure, full = hydra_node("+sweep=falsify_failure"), hydra_node("+sweep=falsify")
    assert dict(failure.sweeper.params) == {}
    assert dict(full.sweeper.params) == {
        "++disturbances.constant_wind.speed": "interval(0.0, 8.0)",
        "++disturbances.constant_wind.heading": "interval(-180.0, 180.0)",
        "++disturbances.packet_loss.p": "interval(0.0, 0.3)",
    }
    assert composed("scenario=cem_six_vehicle")["disturbances"] == {
        "constant_wind": {"name": "constant_wind"}, "packet_loss": {"name": "packet_loss"}}
    assert full.sweeper.custom_search_space == failure.sweeper.custom_search_space
    assert full.sweep.dir.startswith("multirun/falsify/") and failure.sweep.dir.startswith("multirun/falsify_failure/")


def test_the_random_baseline_is_the_same_study_with_optunas_random_sampler():
    tpe, random = hydra_node("+sweep=falsify"), hydra_node("+sweep=falsify_random")
    assert tpe.sweeper.sampler._target_ == "optuna.samplers.TPESampler"
    assert random.sweeper.sampler._target_ == "optuna.samplers.RandomSampler"
    for key in ("n_trials", "direction", "custom_search_space", "params", "n_jobs"):
        assert tpe.sweeper[key] == random.sweeper[key]
    assert tpe.sweeper.n_trials == 100 and tpe.callbacks.swarmscene_falsify == random.callbacks.swarmscene_falsify


def test_the_worst_case_is_the_violating_trial_and_its_file_reproduces_it(tmp_path):
    study = tmp_path / "study"
    # Two trials of the failure alone, random, the agent fixed to the lead; seed 0 draws both times.
    proc = subprocess.run(
        [*EXE, "+sweep=falsify_failure", "hydra/sweeper/sampler=random", "scenario=cem_six_vehicle",
         "avoidance=none", "hydra.sweeper.n_trials=2",
         '+hydra.sweeper.params={events.0.at: "choice(10.0,30.0)"}', "events.0.agents.0=0",
         "output.trajectory=false", f"hydra.sweep.dir={study}"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    runs = {float(yaml.safe_load((study / str(k) / "config.yaml").read_text())["events"][0]["at"]): k for k in (0, 1)}
    assert set(runs) == {10.0, 30.0}, "the sampler's seed 0 no longer draws both candidates: choose another"
    bad = json.loads((study / str(runs[10.0]) / "metrics.json").read_text())
    safe = json.loads((study / str(runs[30.0]) / "metrics.json").read_text())
    assert safe["min_separation"] == pytest.approx(2.72) and safe["duration"] < 30.0  # the triangle's spacing
    assert bad["min_separation"] < 0.56 and bad["violations.separation.first_time"] == pytest.approx(14.16)

    record = json.loads((study / falsify.WORST_CASE_RECORD).read_text())
    assert record["trial"] == runs[10.0] and record["trials"] == 2 and record["violated"] is True
    assert record["min_separation"] == bad["min_separation"]
    assert record["robustness"] == bad["min_separation"] - 0.56
    assert record["first_violation"] == bad["violations.separation.first_time"]
    assert record["violation_agents"] == bad["violations.separation.agents"] == [0, 4]
    assert record["violating_trials"] == 1 and record["running_worst"][-1] == bad["min_separation"]
    reproduce = f"swarmscene --config-path {study} --config-name worst_case"
    assert record["reproduce"] == reproduce
    assert f"Run it: {reproduce}" in proc.stderr

    scenario = yaml.safe_load((study / falsify.WORST_CASE_FILE).read_text())
    assert scenario["events"] == [{"at": 10.0, "agents": [0], "name": "hover"}]
    assert scenario["avoidance"]["name"] == "none"
    rerun = subprocess.run(
        [*EXE, "--config-path", str(study), "--config-name", "worst_case", f"hydra.run.dir={tmp_path}/rerun"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300,
    )
    assert rerun.returncode == 0, rerun.stderr
    again = json.loads((tmp_path / "rerun" / "metrics.json").read_text())
    assert {k: v for k, v in again.items() if k not in TIMING} == {k: v for k, v in bad.items() if k not in TIMING}


def test_a_studys_trials_flown_as_batches_of_worlds_are_its_one_by_one_trials(tmp_path):
    """The falsifier on the batch launcher grouped by physics, Optuna asking four trials at a time:
    each launch of four trials (other winds, links, failure times and agents) is one batch of
    worlds, and the study (every trial's numbers, the worst case) is the basic launcher's."""
    study = ["+sweep=falsify", "scenario=default", "hydra.sweeper.n_trials=8", "hydra.sweeper.n_jobs=4",
             "clock.duration=4"]
    procs = {}
    for name, launcher in (("basic", []), ("batch", ["hydra/launcher=batch", "hydra.launcher.n_jobs=1",
                                                      "hydra.launcher.group=physics"])):
        procs[name] = subprocess.run([*EXE, *study, *launcher, f"hydra.sweep.dir={tmp_path / name}"],
                                     cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert procs[name].returncode == 0, procs[name].stderr
    launches = [line for line in procs["batch"].stdout.splitlines() if "Batch launcher:" in line]
    assert len(launches) == 2 and all("4 jobs, 4 of them in 1 batches" in line for line in launches)
    for k in range(8):
        one, batched = (json.loads((tmp_path / name / str(k) / "metrics.json").read_text()) for name in ("basic", "batch"))
        assert {key: v for key, v in batched.items() if key not in TIMING} == {
            key: v for key, v in one.items() if key not in TIMING}, k
    worst = {name: json.loads((tmp_path / name / falsify.WORST_CASE_RECORD).read_text()) for name in procs}
    for record in worst.values():
        del record["run_dir"], record["reproduce"]
    assert worst["batch"] == worst["basic"] and worst["basic"]["trials"] == 8


# -- bad options, failed trials, damaged and planted files ---------------------------------------
@pytest.mark.parametrize("override, line", [
    ("hydra.sweeper.n_trials=0",
     "swarmscene: hydra.sweeper.n_trials: the falsifier's budget must be an integer >= 1 (got 0)"),
    ("hydra.sweeper.n_trials=-3",
     "swarmscene: hydra.sweeper.n_trials: the falsifier's budget must be an integer >= 1 (got -3)"),
    ('+hydra.sweeper.params={++disturbances.packet_loss.p: "interval(0.3, 0.1)"}',
     "swarmscene: hydra.sweeper.params.disturbances.packet_loss.p: the interval must have low < high, both "
     "finite (got interval(0.3, 0.1))"),
])
def test_a_bad_budget_or_inverted_bounds_is_one_line_naming_the_option(tmp_path, override, line):
    proc = subprocess.run([*EXE, "+sweep=falsify", "scenario=cem_six_vehicle", override,
                           f"hydra.sweep.dir={tmp_path}/study"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [line]
    assert not (tmp_path / "study").exists()


def test_study_problem_accepts_the_presets_and_names_a_log_interval_at_zero():
    from omegaconf import OmegaConf

    assert falsify.study_problem(hydra_node("+sweep=falsify").sweeper) is None
    assert falsify.study_problem(hydra_node("+sweep=falsify_failure").sweeper) is None
    bad = OmegaConf.create({"n_trials": 5, "params": {"++a.b": "tag(log, interval(0.0, 1.0))"}})
    assert falsify.study_problem(bad) == "hydra.sweeper.params.a.b: a log-scaled interval needs low > 0 " \
                                         "(got tag(log, interval(0.0, 1.0)))"
    assert falsify.study_problem(OmegaConf.create({"n_trials": True})).startswith("hydra.sweeper.n_trials:")


def test_a_non_finite_trial_is_a_failed_trial_and_the_study_goes_on(tmp_path, monkeypatch, capsys):
    """The first trial's state becomes non-finite: it is recorded as failed (Optuna: FAIL), the
    second runs, and the summary and the worst case (the complete trial) are written."""
    import numpy as np

    from swarmscene import cli
    from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

    step, worlds = DoubleIntegrator.step, []

    def failing_step(self, world, dt):
        step(self, world, dt)
        if not worlds or worlds[0] is world:  # the first run only
            worlds[:1] = [world]
            if world.t >= 0.5:
                world.pos[1, 0] = np.nan

    study = tmp_path / "study"
    monkeypatch.setattr(DoubleIntegrator, "step", failing_step)
    monkeypatch.setattr(sys, "argv", [
        "swarmscene", "+sweep=falsify_failure", "hydra/sweeper/sampler=random", "scenario=cem_six_vehicle",
        "avoidance=none", "dynamics=double_integrator", "hydra.sweeper.n_trials=2", "clock.duration=3",
        "output.trajectory=false", f"hydra.sweep.dir={study}"])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    cli.main()
    err = capsys.readouterr().err
    assert "swarmscene: job 0 failed: non-finite state of agent 1" in err, err
    record = json.loads((study / falsify.WORST_CASE_RECORD).read_text())
    assert record["trials"] == 2 and record["complete"] == 1 and record["failed"] == [0] and record["trial"] == 1
    assert (study / falsify.WORST_CASE_FILE).is_file() and (study / "summary.csv").is_file()


def test_a_damaged_trial_is_not_complete_and_a_planted_link_is_replaced(tmp_path):
    """read_trial goes through swarmscene.runs.rundir; worst_case.* are written atomically."""
    study = tmp_path / "study"
    for k, sep in ((0, 0.4), (1, 0.9)):
        run = study / str(k)
        (run / ".hydra").mkdir(parents=True)
        (run / ".hydra" / "overrides.yaml").write_text(f"- events.0.at={k}\n")
        (run / "config.yaml").write_text("# header\nsafety:\n  separation_limit: 0.5\n")
        (run / "metrics.json").write_text(json.dumps({"min_separation": sep}))
        (run / "manifest.json").write_text(json.dumps({"complete": True}))
    (study / "0" / "metrics.json").write_text("[1, 2")  # truncated: trial 0 is damaged
    victim = tmp_path / "victim"
    victim.write_text("precious")
    (study / falsify.WORST_CASE_FILE).symlink_to(victim)
    assert falsify.read_trial(study / "0").status == "damaged"
    record = falsify.write_worst_case(study)
    assert record["trial"] == 1 and record["robustness"] == pytest.approx(0.4)
    assert victim.read_text() == "precious" and not (study / falsify.WORST_CASE_FILE).is_symlink()
    assert yaml.safe_load((study / falsify.WORST_CASE_FILE).read_text()) == {"safety": {"separation_limit": 0.5}}


def test_a_study_whose_every_trial_fails_ends_with_its_tables_not_a_bad_input_line(tmp_path, monkeypatch, capsys):
    """Optuna's sweeper raised "No trials are completed yet" after the last trial: exit 2 (bad
    input) and no table. Now the tables are written and the falsifier says no trial completed."""
    import numpy as np

    from swarmscene import cli
    from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

    step = DoubleIntegrator.step

    def failing_step(self, world, dt):
        step(self, world, dt)
        if world.t >= 0.5:
            world.pos[1, 0] = np.nan

    study = tmp_path / "study"
    monkeypatch.setattr(DoubleIntegrator, "step", failing_step)
    monkeypatch.setattr(sys, "argv", [
        "swarmscene", "+sweep=falsify_failure", "hydra/sweeper/sampler=random", "scenario=cem_six_vehicle",
        "avoidance=none", "dynamics=double_integrator", "hydra.sweeper.n_trials=2", "clock.duration=1",
        "output.trajectory=false", "hydra.callbacks.swarmscene_summary.allow_failed=false",
        f"hydra.sweep.dir={study}"])
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    with pytest.raises(SystemExit) as stop:
        cli.main()
    assert stop.value.code == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("swarmscene: ")]
    assert err[-3:] == [
        "swarmscene: the sweeper stopped: every trial failed, so no best one (Optuna); the sweep's end follows",
        f"swarmscene: 2 of 2 jobs failed; summary in {study / 'summary.md'}",
        f"swarmscene: falsify: no trial completed in {study} (2 failed: their error.json says why); "
        "no worst case to write",
    ]
    rows = list(csv.DictReader((study / "summary.csv").open()))
    assert [r["status"] for r in rows] == ["failed", "failed"]
    assert not (study / falsify.WORST_CASE_FILE).exists()
