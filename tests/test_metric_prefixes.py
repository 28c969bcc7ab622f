"""The metric naming rule of core/hookspecs.py (swarmscene_run_end) is what the code does: every
dotted metric of a run starts with a chosen plugin's ``metric_prefix`` or is the engine's own."""

from __future__ import annotations

from pathlib import Path

import pytest

from swarmscene import api

ROOT = Path(__file__).resolve().parents[1]
PRESETS = sorted(p.stem for p in (ROOT / "scenarios" / "scenario").glob("*.yaml"))
ENGINE_PREFIXES = {"violations", "events"}  # events.<k>.*: the draws of random events


@pytest.mark.parametrize("preset", PRESETS)
def test_every_plugin_metric_carries_its_plugins_prefix(preset):
    sim = api.build([f"scenario={preset}", "clock.duration=2", "output.trajectory=false"])
    result = sim.run()
    allowed = set(ENGINE_PREFIXES)
    for plugin in (sim.formation, sim.avoidance, sim.dynamics):
        allowed.add(plugin.metric_prefix or plugin.name)
    dotted = {key.split(".", 1)[0] for key in result.metrics if "." in key}
    assert dotted <= allowed, f"metrics {sorted(dotted - allowed)} carry no chosen plugin's prefix"
