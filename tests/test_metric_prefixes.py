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


def _run_with(observer: type, overrides: list[str]):
    pm, registry = api.plugins()
    registry.observers.append(observer)
    return api.build(overrides, (pm, registry)).run()


def _observer(key: str, prefix: str | None = None) -> type:
    from swarmscene.plugin import hookimpl

    class Writer:
        metric_prefix = prefix

        def __init__(self, sim):
            pass

        @hookimpl
        def swarmscene_run_end(self, sim, metrics):
            metrics[key] = 1.0

    return Writer


@pytest.mark.parametrize(("key", "prefix", "owner"), [
    ("wall_time", None, "the engine's"),  # it silently replaced the engine's timing
    ("min_clearance", None, "the engine's"),  # the safety monitor, called later, silently replaced it
    ("violations.separation.first_time", None, "the engine's"),
    ("cem.max_speed", None, "the namespace of plugin prefix 'cem'"),
    ("close_ticks", None, "the engine's"),
])
def test_a_key_outside_an_observers_namespace_is_refused_naming_it(key, prefix, owner):
    from swarmscene.core.raised import PluginRaised

    with pytest.raises(PluginRaised) as raised:
        _run_with(_observer(key, prefix), ["scenario=cem_six_vehicle", "clock.duration=0.5"])
    assert str(raised.value) == (
        f"observer 'Writer' raised in swarmscene_run_end at t = 0.5 s: MetricKeyError: metrics[{key!r}]: {owner}; "
        "Writer writes dotted keys under a prefix of its own (docs/plugins.md, reserved metric names)")
    metrics = raised.value.result.metrics
    assert metrics["stop_reason"] == "plugin_error" and metrics["success"] is False
    assert key not in metrics or metrics[key] != 1.0


def test_a_declared_prefix_is_held_and_the_observers_own_keys_and_success_pass():
    from swarmscene.core.raised import PluginRaised

    with pytest.raises(PluginRaised, match=r"metrics\['other.x'\]: Writer writes its metrics under 'mine'"):
        _run_with(_observer("other.x", "mine"), ["clock.duration=0.5"])
    assert _run_with(_observer("mine.x", "mine"), ["clock.duration=0.5"]).metrics["mine.x"] == 1.0
    assert _run_with(_observer("close.ticks"), ["clock.duration=0.5"]).metrics["close.ticks"] == 1.0
    assert _run_with(_observer("success"), ["clock.duration=0.5"]).metrics["success"] == 1.0


def test_a_chosen_plugin_writes_under_its_metric_prefix_only(monkeypatch):
    from swarmscene.core.raised import PluginRaised
    from swarmscene.plugins.avoidance.cem import CEM

    original = CEM.swarmscene_run_end

    def swarmscene_run_end(self, sim, metrics):
        original(self, sim, metrics)
        metrics["wall_time"] = 0.0

    from swarmscene.plugin import hookimpl

    monkeypatch.setattr(CEM, "swarmscene_run_end", hookimpl(swarmscene_run_end))
    with pytest.raises(PluginRaised) as raised:
        api.build(["scenario=cem_six_vehicle", "clock.duration=0.5"]).run()
    assert str(raised.value).startswith("avoidance 'cem' raised in swarmscene_run_end at t = 0.5 s: MetricKeyError: "
                                        "metrics['wall_time']: CEM writes its metrics under 'cem' (cem.<key>")
