"""Every documented numeric and boolean option, at its boundary values, either runs or is refused
with the one-line ConfigError: nothing else is raised, nothing hangs, memory is not exhausted.

The options are enumerated from the models themselves (the engine schema's sections and every
registered plugin's Params), so a new option or a new plugin is covered without editing this file.
Each case runs through the Python API (``swarmscene.api.run``) on a scenario that selects the
plugin, with a very short duration; ``signal.alarm`` turns a hang into a failure and an address
space limit turns a runaway allocation into a MemoryError (a failure here, not a dead machine).
"""

from __future__ import annotations

import copy
import resource
import signal
import types
import typing
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from swarmscene import api
from swarmscene.core.config import ScenarioConfig
from swarmscene.core.errors import ConfigError
from swarmscene.core.plugin import PLUGIN_KINDS

CASE_SECONDS = 30
"""A case taking longer than this has hung (the longest legitimate case builds in a few seconds)."""
ADDRESS_SPACE = 12 * 2**30
"""Address-space limit while the cases run, bytes."""
BOUNDARY_VALUES = [
    0, -0.0, 1, -1, 1e308, -1e308, 5e-324, -5e-324, float("nan"), float("inf"), -float("inf"),
    2**63, -(2**63), True, False, None, "x", [1.0],
]
SCENARIOS = Path(api.__file__).resolve().parent.parent / "scenarios" / "scenario"
ENGINE_SECTIONS = ("swarm", "clock", "safety", "comm", "termination", "output")


def _scalar(annotation: Any) -> bool:
    """int, float or bool, possibly optional (``float | None``)."""
    if annotation in (int, float, bool):
        return True
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        return len(args) == 1 and _scalar(args[0])
    return False


def scalar_fields(model: type[BaseModel], prefix: tuple[str, ...]) -> list[tuple[str, ...]]:
    """Dotted paths of every int/float/bool field of ``model``, nested models included."""
    paths = []
    for name, field in model.model_fields.items():
        annotation = field.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            paths += scalar_fields(annotation, (*prefix, name))
        elif _scalar(annotation):
            paths.append((*prefix, name))
    return paths


@cache
def registry() -> Any:
    return api.plugins()[1]


@cache
def base(kind: str, name: str) -> dict[str, Any]:
    """Composed data of a scenario that selects plugin ``name`` of ``kind`` and validates: the
    default scenario with that choice, else the first preset that chooses it."""
    candidates = [[f"{kind}={name}"]]
    candidates += [[f"scenario={p.stem}"] for p in sorted(SCENARIOS.glob("*.yaml"))]
    candidates += [[f"scenario={p.stem}", f"{kind}={name}"] for p in sorted(SCENARIOS.glob("*.yaml"))]
    for overrides in candidates:
        try:
            data = api.compose(overrides)
            if data[kind]["name"] != name:
                continue
            api.load(short(data), registry())
            return data
        except ConfigError:
            continue
    raise AssertionError(f"no shipped scenario validates with {kind}={name}")


def short(data: dict[str, Any]) -> dict[str, Any]:
    data = copy.deepcopy(data)
    data.setdefault("clock", {})
    period = data["clock"].get("guidance_period", 0.1)
    data["clock"]["duration"] = 3 * period
    data.setdefault("output", {})["trajectory"] = False
    return data


def cases() -> list[tuple[str, str, tuple[str, ...]]]:
    """(kind, plugin name, dotted path) of every scalar option; kind "" for the engine's."""
    found = [("", "", path) for path in scalar_fields(ScenarioConfig, ()) if path[0] in (*ENGINE_SECTIONS, "seed")]
    for kind in PLUGIN_KINDS:
        for name in registry().names(kind):
            params = registry().get(kind, name).Params
            found += [(kind, name, (kind, *path)) for path in scalar_fields(params, ())]
    return found


CASES = cases()


def set_path(data: dict[str, Any], path: tuple[str, ...], value: Any) -> None:
    node = data
    for key in path[:-1]:
        node = node.setdefault(key, {})
    node[path[-1]] = value


class Hung(Exception):
    pass


def _alarm(signum: int, frame: Any) -> None:
    raise Hung(f"no answer within {CASE_SECONDS} s")


@pytest.fixture(scope="module")
def limits():
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = ADDRESS_SPACE if hard == resource.RLIM_INFINITY else min(ADDRESS_SPACE, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    previous = signal.signal(signal.SIGALRM, _alarm)
    yield
    signal.signal(signal.SIGALRM, previous)
    resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def run_case(kind: str, name: str, path: tuple[str, ...], value: Any) -> str:
    """'ran' or 'refused'; raises anything else (the property's failure)."""
    data = short(base(kind, name) if kind else base("formation", api.compose([])["formation"]["name"]))
    set_path(data, path, value)
    signal.alarm(CASE_SECONDS)
    try:
        api.run(data)
        return "ran"
    except ConfigError as exc:
        assert exc.lines and all(line and "\n" not in line for line in exc.lines), exc.lines
        return "refused"
    finally:
        signal.alarm(0)


def test_every_plugin_and_section_is_covered():
    kinds = {(kind, name) for kind, name, _ in CASES if kind}
    assert kinds == {(k, n) for k in PLUGIN_KINDS for n in registry().names(k) if registry().get(k, n).Params.model_fields}
    assert {path[0] for kind, _, path in CASES if not kind} == {*ENGINE_SECTIONS, "seed"}


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(case=st.sampled_from(CASES), value=st.sampled_from(BOUNDARY_VALUES))
def test_boundary_values_run_or_give_one_line(limits, case, value):
    kind, name, path = case
    run_case(kind, name, path, value)


@pytest.mark.parametrize(
    ("path", "value", "line"),
    [
        (("swarm", "n"), True, "swarm.n: must be a number, not true/false (got True)"),
        (("clock", "duration"), 1e12, "clock.duration: must be <= 1000000000.0 (got 1000000000000.0)"),
        (("clock", "duration"), 1e8,
         "clock.duration: at most 10000000 guidance ticks of clock.guidance_period = 0.1 s (got 100000000.0: 1e+09 ticks)"),
        (("clock", "guidance_period"), 1e-300, "clock.physics_step: must divide clock.guidance_period = 1e-300 (got 0.02)"),
        (("clock", "physics_step"), 5e-324, "clock.physics_step: must be >= clock.guidance_period / 10000 (got 5e-324)"),
        (("output", "trajectory_buffer_mb"), 1e308, None),
    ],
)
def test_named_inputs_get_their_line(limits, path, value, line):
    data = short(api.compose([]))
    set_path(data, path, value)
    if path == ("output", "trajectory_buffer_mb"):  # a buffer the whole record fits in: runs
        data["output"]["trajectory"] = True
        assert api.run(data).metrics["steps"] == 3
        return
    with pytest.raises(ConfigError) as info:
        api.run(data)
    assert info.value.lines == [line]


def test_a_period_of_1e_300_is_a_bounded_number_of_ticks(limits):
    data = short(api.compose([]))
    data["clock"].update(guidance_period=1e-300, physics_step=None, duration=30.0)
    with pytest.raises(ConfigError) as info:
        api.run(data)
    assert info.value.lines == ["clock.duration: at most 10000000 guidance ticks of clock.guidance_period = 1e-300 s "
                                "(got 30.0: 3e+301 ticks)"]


def test_a_run_that_does_not_fit_in_memory_is_refused_before_it_is_built(monkeypatch):
    """Estimate (core.resources.estimated_memory): 256 MiB + 16 KiB per agent + 8 B per tick + the frames
    held in memory (here streamed: one chunk of 54 frames of 100,000 x 49 B within 256 MiB)."""
    from swarmscene.core import resources

    monkeypatch.setattr(resources, "machine_memory", lambda: 2**29)
    data = api.compose(["swarm.n=100000", "swarm.start.layout=line"])
    expected = 256 * 2**20 + 100_000 * 16 * 1024 + 8 * 450 + 54 * 100_000 * 49 + 8 * 451
    with pytest.raises(ConfigError) as info:
        api.run(data)
    assert info.value.lines == [
        f"swarm.n: the run needs an estimated {expected / 2**30:.3g} GiB of memory, the machine has 0.5 GiB "
        "(got swarm.n = 100000, 450 ticks, output.trajectory_buffer_mb = 256.0)"]
    monkeypatch.setattr(resources, "machine_memory", lambda: expected)  # exactly enough: it is checked, not run
    data["clock"]["duration"] = 0.1
    data["output"]["trajectory"] = False
    assert api.load(data).config.swarm.n == 100_000
