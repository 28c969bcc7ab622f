"""The one validation pass after Hydra composition: composed data in, a :class:`Scenario` or every
problem out.

Hydra composes plain YAML; ``OmegaConf.to_container(resolve=True)`` turns it into plain data;
:func:`validate` checks it in one pass: every name a user chose against the plugin registry
(``validate_choice``: plugins, disturbance models, event kinds, the map generator; an event's or
a disturbance model's ``kind``, the old spelling of its ``name``, is read with a warning:
:mod:`.spelling`), the engine's own keys against :class:`~.config.ScenarioConfig` (its events by
their registered kinds), each chosen plugin's keys against that plugin's ``Params``, then
scenario-level checks (physics step divides the guidance period, events name existing agents,
agents start clear of obstacles and of each other, the run fits the machine: :mod:`.resources`).
Every problem becomes one line ``dotted.key: what is allowed (got value)``, collected in a
:class:`ConfigError`.

Validation builds what it checks (the obstacle footprints, the start positions) once: the returned
:class:`~.config.Scenario` carries them to the simulation, with the effective configuration (every
default resolved) that the run directory records.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from .config import MAX_LENGTH, MAX_SUBSTEPS, MAX_TICKS, Scenario, ScenarioConfig
from .disturbances import effective
from .disturbances.base import Disturbance, DisturbanceParams
from .disturbances.channel import channel_errors
from .errors import ConfigError, format_validation_error
from .events import check_events
from .plugin import PLUGIN_KINDS, PluginParams, shared_option_conflicts
from .registry import validate_choice
from .resources import memory_checks
from .spelling import KIND, NAME, renamed_kind


def effective_config(config: ScenarioConfig, classes: dict[str, Any], params: dict[str, PluginParams],
                     disturbances: dict[str, Any] | None = None) -> dict[str, Any]:
    """The configuration a run uses, every default resolved, as plain data (JSON types) in the
    nested shape of the composed config: the engine schema's fields, then for each plugin kind its
    ``name`` and every field of its Params, then each declared disturbance with every option, each
    observer's options (``config.observers``, validated) and the benchmark task.
    ``disturbances``, ``observers`` and ``task`` are left out when none is declared, so the record
    (and its hash) of such a run is the one it had before they existed."""
    data = config.model_dump(mode="json")
    for kind in PLUGIN_KINDS:
        data[kind] = {"name": classes[kind].name, **params[kind].model_dump(mode="json")}
    if disturbances:
        data["disturbances"] = effective(disturbances)
    if config.observers:
        data["observers"] = {name: _dump(options) for name, options in config.observers.items()}
    if config.task is not None:
        data["task"] = config.task.model_dump(mode="json")
    return data


def _dump(options: Any) -> Any:
    """An observer's validated options as plain data."""
    return options.model_dump(mode="json") if isinstance(options, BaseModel) else options


def validate(data: dict[str, Any], registry: Any) -> Scenario:
    """Validate composed config ``data`` in one pass; raise :class:`ConfigError` listing every problem.

    Args:
        data: plain composed config (no ``hydra`` node).
        registry: a :class:`~swarmscene.core.registry.Registry` (plugin classes by kind and name).

    Returns:
        the :class:`Scenario`, with the obstacles and start positions built while checking it.
    """
    errors: list[str] = []
    data = _spelt_names(data, errors)
    _validate_event_kinds(data.get("events"), registry, errors)
    data = _validate_generator(data, registry, errors)
    try:
        # The registry in the context: each event is checked by its registered kind's rules.
        config = ScenarioConfig.model_validate(data, context={"registry": registry})
    except ValidationError as exc:
        errors += format_validation_error(exc, ScenarioConfig, data)
        config = None
    classes, params = _validate_plugins(data, registry, errors)
    observers = _validate_observers(data.get("observers"), registry, errors)
    if config is not None and observers:
        config = config.model_copy(update={"observers": observers})
    disturbances = validate_disturbances(data.get("disturbances"), errors, registry)
    errors += shared_option_conflicts(params)  # e.g. the thesis' graph parameters, declared twice
    world = None
    if config is not None:
        errors += _scenario_checks(config)
        formation = classes.get("formation")
        if formation is not None and formation.requires_leader and config.swarm.leader is None:
            errors.append(
                f"swarm.leader: formation {formation.name!r} needs a leader "
                f"(an agent index 0..{config.swarm.n - 1})"
            )
        if "dynamics" in classes:
            errors += _rotor_checks(config, classes["dynamics"], registry.classes["event"])
        errors += channel_errors(disturbances, config.swarm.n, config.clock.guidance_period)
        if not errors and len(classes) == len(PLUGIN_KINDS):
            errors += memory_checks(config, classes["dynamics"])
        if not errors:
            world, world_errors = _build_world(config)
            errors += world_errors
    if errors:
        raise ConfigError(errors)
    assert config is not None and world is not None  # without an error both were built
    obstacles, positions, rng_state = world
    return Scenario(
        config=config,
        plugin_classes=classes,
        plugin_params=params,
        data=effective_config(config, classes, params, disturbances),
        composed=data,
        obstacles=obstacles,
        initial_positions=positions,
        rng_state=rng_state,
        disturbances=disturbances,
    )


def validate_disturbances(
    data: Any, errors: list[str], registry: Any
) -> dict[str, tuple[type[Disturbance], DisturbanceParams]]:
    """Validate the ``disturbances`` mapping; append one line per problem to ``errors``.

    Args:
        data: the composed ``disturbances`` section.
        errors: the validation's error lines.
        registry: the plugin :class:`~swarmscene.core.registry.Registry` (kind ``disturbance``).

    Returns:
        each key's model class and validated Params (keys sorted: the order of application).
    """
    if data is None:
        return {}
    if not isinstance(data, dict):
        errors.append(f"disturbances: must be a mapping of name to model (got {data!r})")
        return {}
    out: dict[str, tuple[type[Disturbance], DisturbanceParams]] = {}
    for key in sorted(data):
        node = data[key]
        if not isinstance(node, dict):
            errors.append(f"disturbances.{key}: must be a mapping of options (got {node!r})")
            continue
        name = node.get(NAME, key)
        where = f"disturbances.{key}.{NAME}" if NAME in node else f"disturbances.{key}"
        cls = validate_choice(registry, "disturbance", name, where, errors)
        if cls is None:
            continue
        options = {k: v for k, v in node.items() if k != NAME}
        try:
            out[key] = (cls, cls.Params.model_validate(options))
        except ValidationError as exc:
            errors += format_validation_error(exc, cls.Params, options, prefix=f"disturbances.{key}")
    return out


def _validate_generator(data: dict[str, Any], registry: Any, errors: list[str]) -> dict[str, Any]:
    """``environment.generator`` is a registered map generator; an unknown one is reported here
    once, and the schema then checks the map without it (its parameters unchecked)."""
    env = data.get("environment")
    if not isinstance(env, dict):
        return data
    name = env.get("generator")
    if name is None or validate_choice(registry, "generator", name, "environment.generator", errors):
        return data
    # every known generator's parameters leave with the unknown name: one line, not one per option
    known = set().union(*(cls.Params.model_fields for cls in registry.classes["generator"].values()))
    env = {k: v for k, v in env.items() if k != "generator" and k not in known}
    return {**data, "environment": env}


def _spelt_names(data: dict[str, Any], errors: list[str]) -> dict[str, Any]:
    """``data`` with each event's and disturbance model's plugin name under ``name``: the old
    spelling ``kind`` renamed with a deprecation warning naming its key, both given one error line
    (and ``kind`` dropped, so that nothing else reports it). :mod:`.spelling`."""

    def spelt(node: Any, where: str) -> Any:
        try:
            return renamed_kind(node, where)
        except ValueError as exc:
            errors.append(f"{where}.{KIND}: {exc}")
            return {k: v for k, v in node.items() if k != KIND}

    events, models = data.get("events"), data.get("disturbances")
    if isinstance(events, list) and any(isinstance(e, dict) and KIND in e for e in events):
        data = {**data, "events": [spelt(e, f"events.{k}") for k, e in enumerate(events)]}
    if isinstance(models, dict) and any(isinstance(m, dict) and KIND in m for m in models.values()):
        data = {**data, "disturbances": {key: spelt(m, f"disturbances.{key}") for key, m in models.items()}}
    return data


def _validate_event_kinds(events: Any, registry: Any, errors: list[str]) -> None:
    """Each event's ``name`` is a registered event kind (the schema checks everything else)."""
    if not isinstance(events, list):
        return
    for k, event in enumerate(events):
        if isinstance(event, dict) and NAME in event:
            validate_choice(registry, "event", event[NAME], f"events.{k}.{NAME}", errors)


def _validate_observers(node: Any, registry: Any, errors: list[str]) -> dict[str, BaseModel]:
    """``observers.<name>``: the options of a registered observer that declares a ``name`` and a
    ``Params`` model (observers without options run in every run and take none)."""
    if not isinstance(node, dict) or not node:
        return {}  # a non-mapping is reported by ScenarioConfig
    known = {cls.name: cls for cls in registry.observers
             if isinstance(getattr(cls, "name", None), str) and isinstance(getattr(cls, "Params", None), type)}
    validated: dict[str, BaseModel] = {}
    for name, options in node.items():
        cls = known.get(name)
        if cls is None:
            errors.append(f"observers.{name}: unknown observer with options "
                          f"(valid: {', '.join(sorted(known)) or 'none installed'})")
            continue
        options = {} if options is None else options
        try:
            validated[name] = cls.Params.model_validate(options)
        except ValidationError as exc:
            errors += format_validation_error(exc, cls.Params, options, prefix=f"observers.{name}")
    return validated


def _validate_plugins(data: dict, registry: Any, errors: list[str]) -> tuple[dict, dict]:
    classes: dict[str, Any] = {}
    params: dict[str, PluginParams] = {}
    for kind in PLUGIN_KINDS:
        node = data.get(kind)
        if not isinstance(node, dict) or "name" not in node:
            continue  # ScenarioConfig already reported it
        cls = validate_choice(registry, kind, node["name"], f"{kind}.name", errors)
        if cls is None:
            continue
        options = {k: v for k, v in node.items() if k != "name"}
        try:
            # The registry as context: an option naming another kind's class (avoidance.policy)
            # is checked against it (core.plugin.choose).
            params[kind] = cls.Params.model_validate(options, context={"registry": registry})
            classes[kind] = cls
        except ValidationError as exc:
            errors += format_validation_error(exc, cls.Params, options, prefix=kind)
    return classes, params


def _scenario_checks(config: ScenarioConfig) -> list[str]:
    """Checks across sections that no single field can make (before anything is built)."""
    from .geometry import build_obstacles

    errors: list[str] = _clock_checks(config)
    n = config.swarm.n
    if config.swarm.leader is not None and config.swarm.leader >= n:
        errors.append(f"swarm.leader: must be < swarm.n = {n} (got {config.swarm.leader})")
    errors += check_events(config.events, n)
    errors += build_obstacles(config.environment)[1]
    return errors


def _rotor_checks(config: ScenarioConfig, dynamics: Any, kinds: dict[str, Any]) -> list[str]:
    """An event of a kind declaring ``rotor_fault`` (``motor_failure``) needs a dynamics model with
    rotors, and a rotor it has (the kind's property, not its name: a package's rotor fault too)."""
    errors = []
    rotors = getattr(dynamics, "rotors", 0)
    for k, event in enumerate(config.events):
        kind = kinds.get(event.name)  # None: an unknown kind, already reported (validate_choice)
        if kind is None or not kind.rotor_fault:
            continue
        rotor = event.params.rotor  # type: ignore[attr-defined]  # a rotor_fault kind's Params have it
        if rotors == 0:
            errors.append(f"events.{k}.name: {event.name} needs a dynamics model with rotors "
                          f"(dynamics {dynamics.name!r} has none; e.g. dynamics=quadrotor)")
        elif rotor >= rotors:
            errors.append(f"events.{k}.rotor: must be < {rotors}, the rotors of dynamics "
                          f"{dynamics.name!r} (got {rotor})")
    return errors


def _clock_checks(config: ScenarioConfig) -> list[str]:
    """The physics step divides the guidance period, and the run has a bounded number of ticks."""
    clock = config.clock
    substeps = clock.guidance_period / config.physics_step  # may overflow to inf: no round() before
    if not substeps <= MAX_SUBSTEPS:
        return [f"clock.physics_step: must be >= clock.guidance_period / {MAX_SUBSTEPS} "
                f"(got {config.physics_step})"]
    if abs(substeps - round(substeps)) > 1e-9 * max(1.0, substeps) or round(substeps) < 1:
        return [f"clock.physics_step: must divide clock.guidance_period = {clock.guidance_period} "
                f"(got {config.physics_step})"]
    if clock.duration < clock.guidance_period:
        return [f"clock.duration: must be >= clock.guidance_period = {clock.guidance_period} "
                f"(got {clock.duration})"]
    ticks = clock.duration / clock.guidance_period
    if not ticks <= MAX_TICKS:
        return [f"clock.duration: at most {MAX_TICKS} guidance ticks of clock.guidance_period = "
                f"{clock.guidance_period} s (got {clock.duration}: {ticks:.3g} ticks)"]
    return []


def _build_world(config: ScenarioConfig) -> tuple[tuple | None, list[str]]:
    """The obstacles, the start positions and the generator state after drawing them, or errors."""
    from .geometry import build_obstacles, initial_positions

    obstacles, _ = build_obstacles(config.environment)
    rng = np.random.default_rng(config.seed)
    try:
        pos = initial_positions(config, rng)
    except ValueError as exc:
        return None, [str(exc)]
    errors = _start_checks(config, pos, obstacles)
    pos.flags.writeable = False
    return (obstacles, pos, rng.bit_generator.state), errors


def _start_checks(config: ScenarioConfig, pos: np.ndarray, obstacles: list) -> list[str]:
    from .environment import Environment
    from .vectors import pairs_within

    reach = float(np.abs(pos).max(initial=0.0))
    if not reach <= MAX_LENGTH:  # NaN too
        return [f"swarm.start: positions must lie within {MAX_LENGTH:g} m of the origin on each axis "
                f"(got {reach:.3g} m from swarm.start with swarm.n = {config.swarm.n})"]
    errors: list[str] = []
    env = Environment(obstacles)
    inside = np.flatnonzero(env.clearance(pos) < 0)
    if inside.size:
        errors.append(f"swarm.start: agents {inside.tolist()} start inside an obstacle")
    d_min = config.safety.separation_limit
    if len(pos) > 1 and d_min > 0:
        pairs, _ = pairs_within(pos, d_min)
        if len(pairs):
            msg = (
                f"swarm.start: {len(pairs)} pairs of agents start closer than "
                f"safety.separation_limit = {d_min} m (first: {pairs[0].tolist()})"
            )
            if config.safety.start_overlap == "error":
                errors.append(msg)
            else:
                warnings.warn(msg, stacklevel=2)
    return errors
