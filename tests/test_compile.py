"""swarmscene-compile: which runs warm numba's cache, and how each is cut short."""

from __future__ import annotations

from pathlib import Path

from swarmscene import api
from swarmscene.runs.build import WARM_UP, shortened
from swarmscene.tools import compile as warm


def test_every_preset_and_each_dynamics_with_a_large_swarm_is_warmed():
    presets = {p.stem for p in (Path(warm.__file__).parents[2] / "scenarios" / "scenario").glob("*.yaml")}
    labels = [label for label, _ in warm.warmups()]
    assert {label.removeprefix("scenario=") for label in labels if label.startswith("scenario=")} == presets
    large = [overrides for label, overrides in warm.warmups() if "swarm.n=64" in overrides]
    assert sorted(o[0] for o in large) == ["dynamics=double_integrator", "dynamics=quadrotor", "dynamics=single_integrator"]
    assert "observers=[swarmlab]" in labels  # the observer's compiled pass


def test_events_move_to_the_first_ticks_and_the_run_ends_just_after_the_last():
    data = api.compose(["scenario=cem_multi_failure"])  # failures at 1 s and 4 s, 60 s long, T = 0.01 s
    cut = shortened(data)
    assert [e["at"] for e in cut["events"]] == [0.1, 0.15]
    assert cut["clock"]["duration"] == 0.15 + WARM_UP
    assert cut["output"]["trajectory"] is False and cut["output"]["summary"] is False
    assert data["events"][0]["at"] == 1.0 and data["clock"]["duration"] == 60.0  # the input is untouched
    api.load(cut)  # still a valid scenario
    plain = shortened(api.compose(["scenario=swap"]))  # no events: a short run
    assert plain["events"] == [] and plain["clock"]["duration"] == WARM_UP
