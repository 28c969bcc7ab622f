"""Guardrails: every YAML composes and validates, every plugin honours its kind's contract,
every module imports on its own, core never imports plugins, every plugin module is registered."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarmscene import api
from swarmscene.builtins import BUILTIN_PLUGINS
from swarmscene.core.plugin import PluginParams
from swarmscene.core.setpoint import Setpoints

ROOT = Path(__file__).resolve().parents[1]
_, REGISTRY = api.plugins()


def group_options(group: str) -> list[str]:
    return sorted(p.stem for p in (ROOT / "scenarios" / group).glob("*.yaml"))


@pytest.mark.parametrize("scenario", group_options("scenario"))
def test_every_scenario_composes_and_validates(scenario):
    api.load([f"scenario={scenario}"], REGISTRY)


@pytest.mark.parametrize(
    "override",
    [f"{g}={o}" for g in ("swarm", "environment", "formation", "avoidance", "dynamics", "events") for o in group_options(g)],
)
def test_every_group_option_composes(override):
    data = api.compose([override])
    assert data[override.split("=")[0]] is not None or override.startswith("events")


@pytest.mark.parametrize("kind", ["formation", "avoidance", "dynamics"])
def test_every_plugin_declares_name_and_documented_params(kind):
    for name in REGISTRY.names(kind):
        cls = REGISTRY.get(kind, name)
        assert cls.name == name
        assert issubclass(cls.Params, PluginParams)
        assert cls.Params.model_config.get("extra") == "forbid"
        for field, info in cls.Params.model_fields.items():
            assert info.description, f"{kind} {name}: option {field!r} has no description"
        yaml = ROOT / "scenarios" / kind / f"{name}.yaml"
        assert yaml.exists(), f"{kind} {name} has no {yaml.relative_to(ROOT)}"


def test_none_avoidance_passes_setpoints_through():
    from swarmscene.testing import _build

    cls = REGISTRY.get("avoidance", "none")
    sp = Setpoints.hold(np.zeros((6, 3)))
    assert _build(cls, cls.Params(), None).adjust(None, None, sp) is sp


def test_every_plugin_module_is_a_builtin():
    registering = set()
    for path in (ROOT / "plugins").rglob("*.py"):
        if path.name.startswith("_"):
            continue  # __init__ and the templates
        tree = ast.parse(path.read_text())
        if any(isinstance(node, ast.FunctionDef) and node.name.startswith("swarmscene_register_") for node in tree.body):
            rel = path.relative_to(ROOT).with_suffix("").as_posix().replace("/", ".")
            registering.add(f"swarmscene.{rel}")
    assert registering == set(BUILTIN_PLUGINS)


def test_core_never_imports_plugins():
    for path in (ROOT / "core").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                for name in names:
                    assert "plugins" not in name.split("."), f"{path.name} imports {name}"


def all_modules() -> list[str]:
    mods = []
    for folder, package in (
        ("core", "swarmscene.core"), ("methods", "swarmscene.methods"),
        ("plugins", "swarmscene.plugins"), ("swarmscene", "swarmscene"),
    ):
        for path in (ROOT / folder).rglob("*.py"):
            rel = path.relative_to(ROOT / folder).with_suffix("").parts
            if rel[-1] == "__init__":
                rel = rel[:-1]
            mods.append(".".join((package, *rel)))
    return sorted(mods)


def test_every_module_imports_on_its_own():
    from concurrent.futures import ThreadPoolExecutor

    def try_import(module: str) -> str | None:
        proc = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True)
        return None if proc.returncode == 0 else f"{module}: {proc.stderr.strip().splitlines()[-1]}"

    with ThreadPoolExecutor(max_workers=2) as pool:
        failures = [f for f in pool.map(try_import, all_modules()) if f]
    assert not failures, failures


def group_file_options(kind: str, name: str) -> dict:
    """The options of the plugin's own group YAML (what `<kind>=<name>` gives), without `name`."""
    import yaml

    data = yaml.safe_load((ROOT / "scenarios" / kind / f"{name}.yaml").read_text()) or {}
    return {k: v for k, v in data.items() if k != "name"}


@pytest.mark.parametrize(
    "kind, name",
    [(kind, name) for kind in ("formation", "avoidance", "dynamics") for name in REGISTRY.names(kind)],
)
def test_every_builtin_passes_the_public_contract_checks(kind, name):
    """The checks third-party authors run (swarmscene.testing) hold for every registered plugin."""
    from swarmscene import testing

    check = {"formation": testing.check_formation, "avoidance": testing.check_avoidance,
             "dynamics": testing.check_dynamics}[kind]
    check(REGISTRY.get(kind, name), group_file_options(kind, name))


def test_the_contract_checks_catch_a_plugin_that_breaks_the_rules():
    """A check that cannot fail is no check: an avoidance that edits its input in place, moves a
    failed agent and draws unseeded noise is refused, rule by rule."""
    from swarmscene.core.plugin import Avoidance
    from swarmscene.testing import check_avoidance

    class InPlace(Avoidance):
        name = "in_place"

        def adjust(self, world, sensing, sp):
            sp.vel *= 0.5
            return sp

    class MovesFailed(Avoidance):
        name = "moves_failed"

        def adjust(self, world, sensing, sp):
            out = sp.copy()
            out.pos += 0.1
            return out

    class Unseeded(Avoidance):
        name = "unseeded"

        def adjust(self, world, sensing, sp):
            out = sp.copy()
            out.vel[world.healthy] += np.random.default_rng().normal(size=(int(world.healthy.sum()), 3))
            return out

    for cls, rule in ((InPlace, "modified its input"), (MovesFailed, "failed agent"), (Unseeded, "deterministic")):
        with pytest.raises(AssertionError, match=rule):
            check_avoidance(cls)


def _single_integrator():
    return REGISTRY.get("dynamics", "single_integrator")


def test_the_dynamics_checks_catch_a_model_that_breaks_each_rule():
    """Each promise of docs/plugins.md for dynamics models, broken by one variant of the single
    integrator (which keeps every other rule), is refused with the rule's words."""
    from swarmscene.core.setpoint import Mode
    from swarmscene.testing import check_dynamics

    base = _single_integrator()

    class IgnoresVelocityMode(base):
        name = "ignores_velocity"

        def control(self, world, sp):
            as_position = sp.copy()
            as_position.mode[as_position.mode == Mode.VELOCITY] = Mode.POSITION
            super().control(world, as_position)

    class IgnoresFeedForward(base):
        name = "ignores_feed_forward"

        def control(self, world, sp):
            no_ff = sp.copy()
            tracking = no_ff.mode == Mode.TRACK
            no_ff.vel[tracking] = 0.0
            super().control(world, no_ff)

    class IgnoresIntegratedWind(base):
        name = "ignores_wind"
        wind_coupling = "integrated"

    class CountsCarriedWindTwice(base):
        name = "counts_wind_twice"

        def step(self, world, dt):
            super().step(world, dt)
            if world.wind is not None:
                world.pos += world.wind * dt

    class SharedAcrossInstances(base):
        name = "shared_state"
        command = np.zeros((6, 3))  # one array on the class: every instance writes it

        def initialize(self, world):
            pass

        def control(self, world, sp):
            super().control(world, sp)
            SharedAcrossInstances.command[:] = self.u

        def step(self, world, dt):
            world.pos += SharedAcrossInstances.command * dt
            world.vel[:] = SharedAcrossInstances.command

    for cls, rule in (
        (IgnoresVelocityMode, "VELOCITY setpoint"),
        (IgnoresFeedForward, "TRACK ignores its feed-forward"),
        (IgnoresIntegratedWind, "ignores world.wind"),
        (CountsCarriedWindTwice, "count twice"),
        (SharedAcrossInstances, "share state"),
    ):
        with pytest.raises(AssertionError, match=rule):
            check_dynamics(cls)


def test_the_checks_catch_shared_state_in_a_formation_and_an_avoidance():
    from swarmscene.core.plugin import Avoidance, Formation
    from swarmscene.testing import check_avoidance, check_formation

    class FirstWorldWins(Formation):
        """Holds the slots of the first world any instance saw (kept on the class)."""

        name = "first_world_wins"
        slots = None

        def setpoints(self, world, sensing):
            if FirstWorldWins.slots is None:
                FirstWorldWins.slots = world.pos.copy()
            return Setpoints.hold(FirstWorldWins.slots)

    class RemembersOnTheClass(Avoidance):
        """Slows agents by the swarm's first spread any instance saw (a cache kept on the class)."""

        name = "remembers"
        first_spread: dict = {}

        def adjust(self, world, sensing, sp):
            spread = RemembersOnTheClass.first_spread.setdefault(world.n, float(np.ptp(world.pos[:, 0])))
            out = sp.copy()
            out.vel[world.healthy] /= 1.0 + spread
            return out

    with pytest.raises(AssertionError, match="share state"):
        check_formation(FirstWorldWins)
    with pytest.raises(AssertionError, match="share state"):
        check_avoidance(RemembersOnTheClass)


def test_a_cross_field_check_must_name_its_option():
    """``refused`` options are refused with a line naming ``<kind>.<option>``: a model validator
    that raises without the option's name fails the check, one that names it passes."""
    from pydantic import Field, model_validator

    from swarmscene.core.plugin import Avoidance
    from swarmscene.testing import check_avoidance

    def make(message):
        class Ranges(Avoidance):
            name = "ranges"

            class Params(PluginParams):
                inner: float = Field(1.0, gt=0, description="inner radius, m")
                outer: float = Field(2.0, gt=0, description="outer radius, m")

                @model_validator(mode="after")
                def _ordered(self):
                    if self.outer <= self.inner:
                        raise ValueError(message)
                    return self

            def adjust(self, world, sensing, sp):
                return sp.copy()

        return Ranges

    bad = {"inner": 3.0, "outer": 2.0}
    check_avoidance(make("outer: must exceed inner"), refused={"outer": bad})
    with pytest.raises(AssertionError, match="must name avoidance.outer"):
        check_avoidance(make("outer radius must exceed inner radius"), refused={"outer": bad})
    with pytest.raises(AssertionError, match="accepted"):
        check_avoidance(make("outer: must exceed inner"), refused={"outer": {"inner": 1.0, "outer": 5.0}})


@pytest.mark.parametrize("kind", ["formation", "avoidance", "dynamics"])
def test_each_template_is_a_working_plugin(kind):
    """A copy of plugins/<kind>/_template.py runs as is: it registers its class, which passes the
    contract checks of its kind."""
    from swarmscene import testing

    module = importlib.import_module(f"swarmscene.plugins.{kind}._template")
    hook = getattr(module, f"swarmscene_register_{kind}s" if kind != "dynamics" else "swarmscene_register_dynamics")
    registered = []
    hook(registered.append)
    (cls,) = registered
    getattr(testing, f"check_{kind}")(cls)


def test_the_packaged_example_is_the_avoidance_template_renamed():
    """docs/examples/swarmscene-slowdown's plugin is plugins/avoidance/_template.py with its names
    changed, so the template is known to work as a separately installed package."""
    template = (ROOT / "plugins" / "avoidance" / "_template.py").read_text()
    example = (ROOT / "docs" / "examples" / "swarmscene-slowdown" / "swarmscene_slowdown" / "plugin.py").read_text()
    code = template[template.index("from __future__"):]
    assert example[example.index("from __future__"):] == code.replace("MyAvoidance", "Slowdown").replace(
        "my_avoidance", "slowdown")


def test_each_promise_is_a_named_check_reported_by_name():
    """The checks are listed by kind, one per promise, and a broken promise is reported under its
    name: an avoidance that edits its input fails ``avoidance.input_untouched`` and nothing else."""
    from swarmscene.core.plugin import Avoidance
    from swarmscene.testing import ContractError, check_avoidance, list_checks

    names = [name for name, _ in list_checks("avoidance")]
    assert names[0] == "avoidance.params"  # the gate
    assert {"avoidance.input_untouched", "avoidance.failed_rows_kept", "avoidance.deterministic",
            "avoidance.no_shared_state"} <= set(names)
    for kind in ("formation", "avoidance", "dynamics", "disturbance", "event", "generator", "policy", "observer"):
        listed = list_checks(kind)
        assert len(listed) >= 4 and all(n.startswith(f"{kind}.") and promise for n, promise in listed), kind

    class HalvesInPlace(Avoidance):
        name = "halves_in_place"

        def adjust(self, world, sensing, sp):
            out = sp.copy()
            sp.vel *= 0.5
            return out

    with pytest.raises(ContractError) as caught:
        check_avoidance(HalvesInPlace)
    failed = [o.check for o in caught.value.outcomes if o.status == "failed"]
    assert failed == ["avoidance.input_untouched"]
    assert "[avoidance.input_untouched] halves_in_place: adjust() modified its input setpoints" in str(caught.value)
    outcomes = check_avoidance(REGISTRY.get("avoidance", "none"))
    assert [o.check for o in outcomes] == names and {o.status for o in outcomes} == {"passed"}


def test_a_plugin_declares_an_expected_failure_with_its_reason():
    """``xfail_checks`` (check name -> reason), as scikit-learn's ``_xfail_checks``: the check still
    runs and its failure is reported as expected; a listed check that passes, an unknown name or a
    missing reason fail the run."""
    from swarmscene.core.plugin import Avoidance
    from swarmscene.testing import ContractError, check_avoidance

    class Jitter(Avoidance):
        """Adds unseeded noise on purpose (a hardware-in-the-loop stand-in)."""

        name = "jitter"
        xfail_checks = {"avoidance.deterministic": "adds the radio's own noise, not drawn from ctx.rng"}

        def adjust(self, world, sensing, sp):
            out = sp.copy()
            out.vel[world.healthy] += np.random.default_rng().normal(size=(int(world.healthy.sum()), 3))
            return out

    outcomes = {o.check: o for o in check_avoidance(Jitter)}
    assert outcomes["avoidance.deterministic"].status == "xfailed"
    assert "adds the radio's own noise" in outcomes["avoidance.deterministic"].message
    assert outcomes["avoidance.rows_valid"].status == "passed"

    class Honest(Avoidance):
        name = "honest"
        xfail_checks = {"avoidance.deterministic": "thought it was random"}

        def adjust(self, world, sensing, sp):
            return sp.copy()

    with pytest.raises(ContractError, match=r"\[avoidance.deterministic\] honest: listed in xfail_checks "
                                            r"\(thought it was random\) but it passes: remove it"):
        check_avoidance(Honest)
    Honest.xfail_checks = {"avoidance.determinstic": "typo"}
    with pytest.raises(ContractError, match=r"names \['avoidance.determinstic'\].*valid: avoidance.rows_valid"):
        check_avoidance(Honest)
    Honest.xfail_checks = {"avoidance.params": "the gate"}
    with pytest.raises(ContractError, match="not checks that can be expected to fail"):
        check_avoidance(Honest)
    Honest.xfail_checks = {"avoidance.deterministic": " "}
    with pytest.raises(ContractError, match="must map check names to their reasons"):
        check_avoidance(Honest)


def test_a_plugin_that_raises_fails_the_check_that_called_it_by_name():
    from swarmscene.core.plugin import Formation
    from swarmscene.testing import ContractError, check_formation

    class Crashes(Formation):
        name = "crashes"

        def setpoints(self, world, sensing):
            raise ZeroDivisionError("spacing 0")

    with pytest.raises(ContractError) as caught:
        check_formation(Crashes)
    failed = {o.check: o.message for o in caught.value.outcomes if o.status == "failed"}
    assert "formation.setpoints_valid" in failed
    assert "crashes: raised ZeroDivisionError: spacing 0" in failed["formation.setpoints_valid"]


def test_the_plugin_guide_lists_every_named_check():
    """docs/plugins.md's table of checks is the list the checks register (python -m swarmscene.tools.docgen --checks)."""
    from swarmscene.tools.docgen import checks_table

    assert checks_table() in (ROOT / "docs" / "plugins.md").read_text(), "run: python -m swarmscene.tools.docgen --checks"
