"""The plugin manager factory and registry: built-ins, entry points, broken plugins, names."""

from __future__ import annotations

import types
import warnings

import pluggy
import pytest

from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core import registry as registry_module
from swarmscene.core.errors import PluginError
from swarmscene.core.hookspecs import hookimpl
from swarmscene.core.plugin import Avoidance, PluginParams
from swarmscene.core.registry import Registry, make_plugin_manager


def test_builtins_register_every_kind():
    pm, reg = make_plugin_manager(BUILTIN_PLUGINS, load_entry_points=False)
    assert {"static_shape"} <= set(reg.names("formation"))
    assert {"none", "potential", "cem"} <= set(reg.names("avoidance"))
    assert {"single_integrator", "double_integrator"} <= set(reg.names("dynamics"))
    assert {c.__name__ for c in reg.observers} >= {"SafetyMonitor", "TrajectoryRecorder"}


def test_each_call_builds_its_own_manager():
    pm1, _ = make_plugin_manager(BUILTIN_PLUGINS, load_entry_points=False)
    pm2, _ = make_plugin_manager(BUILTIN_PLUGINS, load_entry_points=False)
    pm1.register(types.SimpleNamespace(), name="only-in-pm1")
    assert pm1.has_plugin("only-in-pm1") and not pm2.has_plugin("only-in-pm1")


class Dup(Avoidance):
    name = "potential"


def test_duplicate_name_names_both_sources():
    reg = Registry()
    from swarmscene.plugins.avoidance.potential import Potential

    reg.register("avoidance", Potential)
    with pytest.raises(PluginError, match="registered twice: by .*Potential and by .*Dup"):
        reg.register("avoidance", Dup)


def test_unknown_name_lists_valid():
    _, reg = make_plugin_manager(BUILTIN_PLUGINS, load_entry_points=False)
    with pytest.raises(PluginError, match=r"unknown avoidance 'nope' \(valid: .*\bcem\b.*\bnone\b.*\bpotential\b"):
        reg.get("avoidance", "nope")


def test_class_without_params_model_is_refused():
    class Bad(Avoidance):
        name = "bad"
        Params = dict  # type: ignore[assignment]

    with pytest.raises(PluginError, match="Params must subclass PluginParams"):
        Registry().register("avoidance", Bad)


class FakeEntryPoint:
    def __init__(self, name, target, dist="fakedist"):
        self.name, self._target, self.value = name, target, f"{dist}.module"
        self.dist = types.SimpleNamespace(name=dist, version="3.1.4")

    def load(self):
        if isinstance(self._target, Exception):
            raise self._target
        return self._target


def test_broken_third_party_plugin_is_skipped_with_a_warning(monkeypatch):
    good = types.SimpleNamespace()

    class Extra(Avoidance):
        name = "extra"

        class Params(PluginParams):
            pass

    @hookimpl
    def swarmscene_register_avoidances(register):
        register(Extra)

    good.swarmscene_register_avoidances = swarmscene_register_avoidances

    class Crashes(Avoidance):
        name = "potential"  # shadows a built-in: refused at registration

    bad_registration = types.SimpleNamespace()

    @hookimpl
    def swarmscene_register_avoidances_bad(register):
        register(Crashes)

    bad_registration.swarmscene_register_avoidances = swarmscene_register_avoidances_bad
    eps = [
        FakeEntryPoint("broken", ImportError("no module named 'missing_dep'"), dist="brokendist"),
        FakeEntryPoint("good", good, dist="gooddist"),
        FakeEntryPoint("shadow", bad_registration, dist="shadowdist"),
    ]
    monkeypatch.setattr(registry_module, "entry_points", lambda group: eps)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pm, reg = make_plugin_manager(BUILTIN_PLUGINS)
    messages = [str(w.message) for w in caught]
    assert any("'brokendist:broken'" in m and "missing_dep" in m for m in messages)
    assert any("'shadowdist:shadow'" in m and "registered twice" in m for m in messages)
    assert "extra" in reg.names("avoidance")
    assert reg.get("avoidance", "potential").__module__.endswith("avoidance.potential")


def test_disabled_plugin_is_not_loaded(monkeypatch):
    monkeypatch.setattr(registry_module, "entry_points", lambda group: [FakeEntryPoint("x", ImportError("boom"))])
    monkeypatch.setenv("SWARMSCENE_DISABLE_PLUGINS", "fakedist:x")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_plugin_manager(BUILTIN_PLUGINS)


def test_misspelt_hook_fails_loudly(monkeypatch):
    typo = types.SimpleNamespace()

    @hookimpl
    def swarmscene_register_formation(register):  # missing the final "s"
        pass

    typo.swarmscene_register_formation = swarmscene_register_formation
    monkeypatch.setattr(registry_module, "entry_points", lambda group: [FakeEntryPoint("typo", typo)])
    with pytest.raises(pluggy.PluginValidationError, match="swarmscene_register_formation"):
        make_plugin_manager(BUILTIN_PLUGINS)


def _third_party_avoidance(name="extra"):
    """A module object registering one avoidance class named ``name``."""

    class Extra(Avoidance):
        """Extra avoidance: a one-line description.

        More text that the plugin list leaves out.
        """

        class Params(PluginParams):
            pass

    Extra.name = name
    module = types.SimpleNamespace()

    @hookimpl
    def swarmscene_register_avoidances(register):
        register(Extra)

    module.swarmscene_register_avoidances = swarmscene_register_avoidances
    return module


def test_each_class_knows_the_distribution_that_registered_it(monkeypatch):
    eps = [FakeEntryPoint("good", _third_party_avoidance(), dist="gooddist")]
    monkeypatch.setattr(registry_module, "entry_points", lambda group: eps)
    _, reg = make_plugin_manager(BUILTIN_PLUGINS)
    assert reg.sources[("avoidance", "extra")] == "gooddist:good"
    assert reg.distributions == {"gooddist:good": ("gooddist", "3.1.4")}
    assert reg.sources[("avoidance", "potential")] == "swarmscene.plugins.avoidance.potential"


def test_misspelt_disabled_name_warns_and_lists_the_installed_plugins(monkeypatch):
    eps = [FakeEntryPoint("good", _third_party_avoidance(), dist="gooddist")]
    monkeypatch.setattr(registry_module, "entry_points", lambda group: eps)
    monkeypatch.setenv("SWARMSCENE_DISABLE_PLUGINS", "gooddist:good, goodist:good")
    with pytest.warns(RuntimeWarning) as caught:
        _, reg = make_plugin_manager(BUILTIN_PLUGINS)
    messages = [str(w.message) for w in caught]
    assert messages == [
        "swarmscene: SWARMSCENE_DISABLE_PLUGINS names 'goodist:good', which no installed plugin is "
        "(installed: gooddist:good)"
    ]
    assert "extra" not in reg.names("avoidance")  # the correctly spelt entry still blocks


def test_the_manifest_versions_name_every_plugin_distribution(monkeypatch):
    from swarmscene.runs import outputs

    eps = [FakeEntryPoint("good", _third_party_avoidance(), dist="gooddist")]
    monkeypatch.setattr(registry_module, "entry_points", lambda group: eps)
    versions = outputs.package_versions()
    assert versions["gooddist"] == "3.1.4"
    assert versions["numba"] and versions["swarmscene"] and versions["python"]


def _hookimpls(pm: pluggy.PluginManager) -> list[tuple]:
    return sorted((caller.name, impl.plugin_name, impl.function.__module__, impl.function.__qualname__,
                   impl.wrapper, impl.hookwrapper, impl.tryfirst, impl.trylast)
                  for caller in pm.hook.__dict__.values() if isinstance(caller, pluggy.HookCaller)
                  for impl in caller.get_hookimpls())


def test_the_managers_quick_look_at_a_module_finds_what_pluggy_finds(monkeypatch):
    """``_PluginManager`` answers a module's non-function names itself and keeps pluggy's answer
    for each function (pluggy's per-name static lookup is most of a manager's cost); the hook
    implementations are pluggy's own, for the built-ins, the allkinds test package, and a module
    holding every shape pluggy accepts, also after that module's values change."""
    import tests.swarmscene_allkinds.plugin as allkinds

    odd = types.ModuleType("odd_plugin")

    @hookimpl(tryfirst=True)
    def swarmscene_run_start(sim):  # a plain function, marked
        pass

    class Holder:
        @hookimpl
        def swarmscene_run_end(self, sim, metrics):  # a bound method, marked
            pass

    odd.swarmscene_run_start = swarmscene_run_start
    odd.swarmscene_run_end = Holder().swarmscene_run_end
    odd.unmarked = lambda: None
    odd.constant, odd.Holder, odd.module = 3, Holder, types
    modules = [*BUILTIN_PLUGINS, allkinds.__name__]
    ours, _ = make_plugin_manager(modules, load_entry_points=False)
    ours.register(odd, name="odd")
    monkeypatch.setattr(registry_module, "_PluginManager", pluggy.PluginManager)
    plain, _ = make_plugin_manager(modules, load_entry_points=False)
    plain.register(odd, name="odd")
    found = _hookimpls(ours)
    assert found == _hookimpls(plain)
    assert {name for name, plugin, *_ in found if plugin == "odd"} == {"swarmscene_run_start",
                                                                "swarmscene_run_end"}
    # a module that now holds other values (reloaded, patched) is answered for them, not from memory
    odd.swarmscene_run_start = lambda sim: None  # unmarked
    odd.swarmscene_run_end = hookimpl(lambda sim, metrics: None)  # another function, marked
    monkeypatch.undo()
    again, _ = make_plugin_manager([], load_entry_points=False)
    again.register(odd, name="odd")
    monkeypatch.setattr(registry_module, "_PluginManager", pluggy.PluginManager)
    plain_again, _ = make_plugin_manager([], load_entry_points=False)
    plain_again.register(odd, name="odd")
    assert _hookimpls(again) == _hookimpls(plain_again)
    assert {name for name, plugin, *_ in _hookimpls(again) if plugin == "odd"} == {"swarmscene_run_end"}


def test_the_managers_quick_look_at_a_plugin_instance_finds_what_pluggy_finds():
    """``_PluginManager`` answers an instance's names from its own ``__dict__`` and its type's MRO,
    keeping pluggy's answer per class and function: the hook implementations are pluggy's own
    for every object a run registers (the presets' plugins and observers) and for an instance
    holding every shape pluggy accepts or refuses, a property that must not run included, also
    after its class's method is replaced."""
    from swarmscene import api
    from swarmscene.core import hookspecs

    class Base:
        @hookimpl(trylast=True)
        def swarmscene_run_start(self, sim):  # inherited, marked
            pass

    class Odd(Base):
        __slots__ = ("slotted",)  # beside Base's __dict__

        @hookimpl
        def swarmscene_run_end(self, sim, metrics):
            pass

        @staticmethod
        @hookimpl
        def swarmscene_step_end(sim):
            pass

        @property
        def swarmscene_event(self):  # a property is not run, and not a hook
            raise AssertionError("pluggy's lookup must not run a property")

        def unmarked(self):
            pass

    odd = Odd()
    odd.slotted = hookimpl(lambda sim, event: None)  # a slot's value, marked: pluggy's own lookup takes it
    odd.own = 3

    def plain_manager() -> pluggy.PluginManager:
        pm = pluggy.PluginManager(hookspecs.PROJECT)
        pm.add_hookspecs(hookspecs)
        return pm

    sims = [api.build(api.compose([f"scenario={preset}", "output.summary=false"]))
            for preset in ("default", "vrb_airshow", "indoor_corridor", "cem_six_vehicle")]
    objects = [plugin for sim in sims for plugin in sim.pm.get_plugins() if not isinstance(plugin, types.ModuleType)]
    assert len(objects) >= 12  # the runs' plugin instances and observers
    def compare(plugins: list) -> set[str]:
        ours, _ = make_plugin_manager([], load_entry_points=False)
        plain = plain_manager()
        for k, plugin in enumerate(plugins):
            ours.register(plugin, name=f"p{k}")
            plain.register(plugin, name=f"p{k}")
        names = {f"p{k}" for k in range(len(plugins))}  # (ours also holds the core observer modules)
        found = [impl for impl in _hookimpls(ours) if impl[1] in names]
        assert found == _hookimpls(plain)
        return {name for name, plugin, *_ in found if plugin == f"p{len(plugins) - 1}"}

    assert compare([*objects, odd]) == {"swarmscene_run_start", "swarmscene_run_end", "swarmscene_step_end", "slotted"}
    Odd.swarmscene_run_end = lambda self, sim, metrics: None  # now unmarked: asked again, not remembered
    assert compare([odd]) == {"swarmscene_run_start", "swarmscene_step_end", "slotted"}


def test_the_managers_memory_of_pluggys_answers_keeps_no_plugin_class_alive():
    """The answers are kept per function under a weak key: a plugin class made at run time (a
    test's, a factory's), whose methods refer back to it (``super()``), goes once nothing else
    holds it."""
    import gc
    import weakref

    def made() -> weakref.ref:
        class Made:
            @hookimpl
            def swarmscene_run_start(self, sim):
                super().__init__  # noqa: B018  (a __class__ cell: the method refers to its class)

        pm, _ = make_plugin_manager([], load_entry_points=False)
        pm.register(Made(), name="made")
        assert [impl.plugin_name for impl in pm.hook.swarmscene_run_start.get_hookimpls()] == ["made"]
        return weakref.ref(Made)

    gone = made()
    gc.collect()
    assert gone() is None
