"""The run summary's verdict lines (swarmscene/views/summary.py, issue #26): every line states its limit and
scope, preconditions print as ``met`` / ``not met``, checks that do not apply print ``n/a``, ``success``
carries its reason and a ``mission`` line, and a method that does not avoid by design says so."""

from __future__ import annotations

import pytest

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.registry import make_plugin_manager
from swarmscene.core.simulation import Simulation
from swarmscene.views.summary import FAIL, MET, NA, NOT_MET, OK, summary_text, verdicts


def run(overrides: list[str]):
    pm, registry = make_plugin_manager(BUILTIN_PLUGINS, load_entry_points=False)
    sim = Simulation(api.load(overrides, registry), pm, registry.observers)
    result = sim.run()
    return sim, result, {name: (status, detail) for name, status, detail in verdicts(sim, result.metrics)}


def status_lines(text: str) -> list[str]:
    return [line for line in text.splitlines()[3:] if not line.startswith("  outputs:")]


def test_nominal_cem_preset_prints_no_fail_and_names_its_preconditions():
    sim, result, v = run(["scenario=cem_six_vehicle"])
    text = summary_text(sim, result, None)
    assert " FAIL " not in text and "success True (no engine limit violated, mission complete)\n" in text
    assert v["cem.theorem1_precondition_met"][0] == NOT_MET  # conservative for the paper's own formation
    assert v["cem.theorem2_precondition_met"][0] == MET
    assert "cem.theorem1_holds" not in v and result.metrics["cem.theorem1_holds"] is False  # kept, not printed
    assert v["clearance"] == (NA, "no obstacles in this environment")  # an open map
    assert v["mission"][0] == OK
    assert v["cem.clearance_holds"] == (OK, "healthy to failed vehicles min 1.35 m vs a_f + eps = 0.96 m, x-y, "
                                            "from the first activation to the end of the run")
    sep_status, sep = v["separation"]
    assert sep_status == OK and sep.startswith("min 1.35 m vs 0.56 m, all pairs (failed vehicles included), "
                                               "sampled once per guidance tick")
    assert "line of sight not considered" in v["connectivity"][1]
    # one status column: every line starts with a status padded to the widest ("not met")
    for line in status_lines(text):
        assert line[2:10].rstrip() in (OK, FAIL, NA, MET, NOT_MET) and line[9] == " "


def test_a_run_that_does_not_complete_says_why():
    sim, result, v = run(["scenario=cem_six_vehicle", "clock.duration=10"])
    assert v["mission"] == (FAIL, "not complete when the run stopped at 10 s (stopped by duration)")
    assert "success False (failed: mission)" in summary_text(sim, result, None)


def test_cem_holding_control_is_the_reason_the_mission_did_not_complete():
    sim, result, v = run(["scenario=cem_six_vehicle", "events.0.at=21.34234639497493"])
    status, detail = v["mission"]
    assert status == FAIL and detail.endswith("CEM kept control from 32.1 s: a formation setpoint, or the path to "
                                              "it, lay within a_p of a failed vehicle (hand_back_rule=clear_path: the agents "
                                              "stay safe but do not return to the formation)")
    assert v["cem.clearance_holds"][0] == OK and v["separation"][0] == OK


def test_old_hand_back_rule_prints_the_violation_with_its_first_time_and_agents():
    sim, result, v = run(["scenario=cem_six_vehicle", "events.0.at=21.34234639497493", "avoidance.hand_back_rule=passed"])
    assert v["cem.clearance_holds"][0] == FAIL and "; first at 32.61 s (agents 4, 0)" in v["cem.clearance_holds"][1]
    assert v["separation"][0] == FAIL and "first at 32.75 s (agents 0, 4)" in v["separation"][1]
    assert ("success False (failed: separation; not counted by success: FAIL cem.clearance_holds)"
            in summary_text(sim, result, None)) and v["mission"][0] == OK


def test_flocking_says_boids_do_not_avoid_by_design():
    sim, result, v = run(["scenario=flocking", "clock.duration=20"])
    status, detail = v["separation"]
    assert status == FAIL and detail.endswith("reynolds_flocking does not avoid collisions by design")
    assert v["mission"][0] == NA


def test_multi_failure_theorem_2_does_not_apply():
    _, _, v = run(["scenario=cem_multi_failure", "clock.duration=9"])
    assert v["cem.theorem2_precondition_met"] == (NA, "Theorem 2 covers one failed vehicle at every activation")
    assert v["cem.theorem1_precondition_met"][0] == MET


@pytest.mark.parametrize("scenario", ["cem_two_vehicle", "vrb_airshow", "outdoor_square"])
def test_paper_presets_print_no_fail_line(scenario):
    sim, result, _ = run([f"scenario={scenario}"])
    text = summary_text(sim, result, None)
    assert " FAIL " not in text and "success True" in text, text


def test_success_names_the_fail_lines_it_does_not_count():
    """success counts the engine's limits and the mission; a plugin's FAIL is named beside it, so the
    header never reads "safe" above a FAIL line (review of issue #26: the lead failing at 19.0 s)."""
    sim, result, v = run(["scenario=cem_six_vehicle", "events.0.at=19.0", "avoidance.hand_back_rule=passed"])
    assert v["cem.clearance_holds"][0] == FAIL and v["separation"][0] == OK and v["mission"][0] == OK
    assert ("success True (no engine limit violated, mission complete; not counted by success: FAIL "
            "cem.clearance_holds)") in summary_text(sim, result, None)


def test_a_measured_bound_that_was_not_kept_prints_fail_even_when_no_theorem_claims_it():
    """cem.separation_holds is measured: FAIL when the healthy pairs came closer than 2 (delta + eps),
    whether or not a theorem's precondition was met (then the line says the bound was not claimed)."""
    from types import SimpleNamespace

    from swarmscene.plugins.avoidance.cem import CEM
    from swarmscene.views.summary import plugin_verdicts

    _, result, _ = run(["scenario=cem_six_vehicle", "clock.duration=13"])
    m = {**result.metrics, "cem.min_pair_distance": 0.81, "cem.separation_holds": False,
         "cem.violations.separation.first_time": 9.5, "cem.violations.separation.agents": [1, 2]}
    sim = SimpleNamespace(avoidance=CEM.__new__(CEM))
    for met1, met2 in ((False, False), (True, False), (False, True)):
        got = dict((k, (s, d)) for k, s, d in plugin_verdicts(
            sim, {**m, "cem.theorem1_precondition_met": met1, "cem.theorem2_precondition_met": met2}))
        status, detail = got["cem.separation_holds"]
        assert status == FAIL and detail.startswith("healthy pairs min 0.81 m vs 2 (delta + eps) = 1.36 m")
        assert detail.endswith("; first at 9.50 s (agents 1, 2)")
        assert ("not claimed here" in detail) == (not (met1 or met2))


def test_a_check_with_nothing_to_check_prints_n_a():
    """cem_two_vehicle has one healthy agent: no pair for the separation or either theorem."""
    _, _, v = run(["scenario=cem_two_vehicle", "clock.duration=3"])
    assert v["cem.separation_holds"] == (NA, "fewer than two healthy agents, no pair to measure")
    assert v["cem.theorem1_precondition_met"] == (NA, "Theorem 1 (eq. 7-8) bounds pairs of healthy agents: fewer than two")
    assert v["cem.theorem2_precondition_met"] == (NA, "Theorem 2 (eq. 16) bounds pairs of healthy agents: fewer than two")
    assert v["cem.clearance_holds"][0] == OK


def test_cem_lines_before_any_failure_print_n_a():
    _, _, v = run(["scenario=cem_six_vehicle", "clock.duration=1"])  # the lead fails at 2 s
    for key in ("cem.separation_holds", "cem.clearance_holds", "cem.theorem1_precondition_met"):
        assert v[key] == (NA, "CEM never activated (no vehicle failed)")


def test_vrb_safety_line_states_its_limit_and_scope():
    _, _, v = run(["scenario=vrb_airshow"])
    assert v["vrb.safety_holds"] == (OK, "min 0.648 m vs s_i + s_j = 2 formation.clearance = 0.6 m (Problem 4), "
                                         "nearest pairs in 3-D, every guidance tick during transformations only "
                                         "(formations held between them: the separation line)")
