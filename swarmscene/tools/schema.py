"""A JSON Schema of the whole configuration: the engine's sections and every registered plugin's
options (third-party plugins included), for editors and other tools.

    python -m swarmscene.tools.schema > swarmscene.tools.schema.json            # a composed configuration
    python -m swarmscene.tools.schema --partial > swarmscene.partial.json  # hand-written scenario files
    python -m swarmscene.tools.schema --group environment                  # one config group's files
    python -m swarmscene.tools.schema --all-groups schemas/                # every group, one file each

Both come from the same pydantic models the engine validates with (:mod:`swarmscene.core.config`
and each plugin's ``Params``). ``formation``, ``avoidance`` and ``dynamics`` are each one of the
registered plugins of their kind, told apart by ``name`` (a ``const``), so an editor completes and
checks the options of the plugin chosen. The other kinds chosen by name come from the registry
too: each event is the event kind its ``name`` names (an enum of the registered kinds, each with its
own fields), each ``disturbances`` entry the model its ``name`` (or key) names, and
``environment.generator`` one of the registered map generators, a plugin's parameters beside the
built-ins'. The full schema describes what the engine validates after
Hydra composition (``swarmscene --cfg job``, ``api.compose``); the partial one describes the files a
user writes (presets, experiment files): every key optional, a Hydra ``defaults`` list and a
``hydra`` node allowed, and a plugin section whose ``name`` comes from the defaults list accepted.
A config-group file holds its group's node, not a whole scenario (a map file the ``environment``
section's fields, a tuning file one method's options): :func:`group_schema` roots the partial
schema at that node (``GROUPS``; docs/editors.md gives each group's editor modeline).
What a schema cannot say (cross-section checks such as agents starting inside an obstacle) is
still checked by the engine. docs/editors.md shows the YAML language server using it.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any

from pydantic.json_schema import GenerateJsonSchema, PydanticJsonSchemaWarning, models_json_schema

from ..core.config import ScenarioConfig
from ..core.plugin import PLUGIN_KINDS

DIALECT = "http://json-schema.org/draft-07/schema#"
"""Draft 7: the newest the YAML language server supports."""
REF = "#/definitions/{model}"


def scenario_schema(registry: Any | None = None, partial: bool = False) -> dict[str, Any]:
    """The JSON Schema of a configuration, with the plugins of ``registry`` (default: every
    installed plugin); ``partial`` for hand-written scenario files (see the module docstring)."""
    if registry is None:
        from ..runs.build import plugins

        _, registry = plugins()
    plugins_by_kind = {kind: [registry.get(kind, n) for n in registry.names(kind)] for kind in PLUGIN_KINDS}
    # Disturbance models and event kinds are the registry's too (a plugin's appear beside the built-ins).
    disturbance_models = [registry.get("disturbance", n) for n in registry.names("disturbance")]
    event_kinds = [registry.get("event", n) for n in registry.names("event")]
    generators = [registry.get("generator", n) for n in registry.names("generator")]
    models = [(ScenarioConfig, "validation")] + [
        (cls.Params, "validation") for classes in plugins_by_kind.values() for cls in classes
    ] + [(cls.Params, "validation") for cls in (*disturbance_models, *event_kinds, *generators)]
    observers = [cls for cls in registry.observers if getattr(cls, "Params", None) is not None
                 and isinstance(getattr(cls, "name", None), str)]  # the observers that take options
    models += [(cls.Params, "validation") for cls in observers]
    with warnings.catch_warnings():  # a default JSON cannot hold (a function) is left out: said here
        warnings.simplefilter("ignore", PydanticJsonSchemaWarning)
        refs, top = models_json_schema(models, ref_template=REF, schema_generator=_Generator)
    defs = top.pop("$defs")
    root = defs.pop(_name(refs[(ScenarioConfig, "validation")]))
    defs.pop("PluginChoice", None)
    for kind, classes in plugins_by_kind.items():
        variants = []
        for cls in classes:
            key = f"{kind}.{cls.name}"
            defs[key] = _variant(kind, cls, defs.pop(_name(refs[(cls.Params, "validation")])))
            variants.append({"$ref": REF.format(model=key)})
        description = f"the {kind} plugin, chosen by name ({', '.join(c.name for c in classes)}), and its options"
        if partial:  # the name may come from the defaults list: see _by_name
            defs[f"{kind}.any"] = _any_method(
                f"{kind} options (the method chosen in the defaults list)",
                f"options of any {kind} plugin; add name: to check them against that plugin's alone",
                [defs[f"{kind}.{c.name}"] for c in classes], "name")
            root["properties"][kind] = {"description": description, **_by_name(kind, [c.name for c in classes])}
        else:
            root["properties"][kind] = {"description": description, "oneOf": variants}
    for cls in disturbance_models:
        defs[f"disturbances.{cls.name}"] = _disturbance(cls, defs.pop(_name(refs[(cls.Params, "validation")])))
    if partial:
        defs["disturbances.any"] = _any_method(
            "options of a disturbance chosen elsewhere",
            "an entry named by another file (disturbances=[gps]): options of any disturbance model",
            [defs[f"disturbances.{c.name}"] for c in disturbance_models], "name")
    root["properties"]["disturbances"] = _disturbances(
        root["properties"]["disturbances"], [c.name for c in disturbance_models], partial)
    _event_kinds(root, defs, event_kinds, refs, partial)
    _map_generators(defs, generators, refs)
    _observers(root, defs, observers, refs)
    schema = {
        "$schema": DIALECT,
        "title": "swarmscene scenario" + (" file" if partial else " (composed)"),
        **root,
        "definitions": defs,
    }
    schema = _finite(_draft7(schema))
    return _partial(schema) if partial else schema


class _Generator(GenerateJsonSchema):
    """pydantic's generator, except that a field JSON Schema cannot describe (a callable, a numpy
    array or another arbitrary type of a third-party plugin's Params) accepts any value, instead
    of failing the whole schema (the engine still validates it); a default JSON cannot hold (a
    function) is left out."""

    def handle_invalid_for_json_schema(self, schema: Any, error_info: str) -> dict[str, Any]:
        return {"description": f"not expressible in JSON Schema ({error_info}); checked by the engine"}


def _finite(node: Any) -> Any:
    """JSON has no Infinity or NaN: a non-finite number is left out (a ``default`` is said in the
    description instead, e.g. ``... (default: inf)``), so the schema is strict JSON."""
    if isinstance(node, list):
        return [_finite(v) for v in node if not _non_finite(v)]
    if not isinstance(node, dict):
        return node
    out = {key: _finite(value) for key, value in node.items() if not _non_finite(value)}
    if _non_finite(node.get("default")):
        note = f"default: {node['default']}"
        out["description"] = f"{out['description']} ({note})" if out.get("description") else note
    return out


def _non_finite(value: Any) -> bool:
    return isinstance(value, float) and not math.isfinite(value)


def _name(ref: dict[str, str]) -> str:
    return ref["$ref"].rsplit("/", 1)[-1]


def _variant(kind: str, cls: Any, params: dict[str, Any]) -> dict[str, Any]:
    """A plugin's Params schema with its ``name`` as a const (the discriminator)."""
    doc = (cls.__doc__ or "").strip().splitlines()
    return {
        **{k: v for k, v in params.items() if k not in ("properties", "required", "title", "description")},
        "title": f"{kind}={cls.name}",
        "description": doc[0] if doc else f"{kind} {cls.name}",
        "type": "object",
        "properties": {"name": {"const": cls.name, "description": f"registered {kind} name"},
                       **params.get("properties", {})},
        "required": ["name", *params.get("required", [])],
        "additionalProperties": False,
    }


def _by_name(kind: str, names: list[str]) -> dict[str, Any]:
    """A plugin section of a hand-written file: with ``name``, exactly that plugin's options (so an
    error names the chosen plugin's key, not the closest of all plugins); without it (the method
    comes from the defaults list, or the file is a tuning file of one method), any option of any
    registered plugin of the kind (``{kind}.any``)."""
    chosen = [{"if": {"properties": {"name": {"const": n}}, "required": ["name"]},
               "then": {"$ref": REF.format(model=f"{kind}.{n}")}} for n in names]
    return {"type": "object", "allOf": [
        *chosen,
        {"if": {"required": ["name"]},
         "then": {"properties": {"name": {"enum": names, "description": f"registered {kind} name"}}},
         "else": {"$ref": REF.format(model=f"{kind}.any")}},
    ]}


def _any_method(title: str, description: str, variants: list[dict[str, Any]], tag: str) -> dict[str, Any]:
    """The options of every variant (the plugins of one kind, the disturbance models) but their
    ``tag``, each key checked against the variants that have it (a key two share must fit one of
    them); an unknown key is refused."""
    options: dict[str, list[dict[str, Any]]] = {}
    for variant in variants:
        for key, prop in variant["properties"].items():
            if key != tag and prop not in options.setdefault(key, []):
                options[key].append(prop)
    return {
        "title": title,
        "description": description,
        "type": "object",
        "properties": {k: v[0] if len(v) == 1 else {"anyOf": v} for k, v in sorted(options.items())},
        "additionalProperties": False,
    }


def _disturbance(cls: Any, params: dict[str, Any]) -> dict[str, Any]:
    """A disturbance model's Params with its ``name`` (optional: it defaults to the entry's key)."""
    doc = (cls.__doc__ or "").strip().splitlines()
    return {
        **{k: v for k, v in params.items() if k not in ("properties", "title", "description")},
        "title": f"disturbances name={cls.name}",
        "description": doc[0] if doc else f"disturbance {cls.name}",
        "type": "object",
        "properties": {"name": {"const": cls.name, "description": "disturbance model"},
                       **params.get("properties", {})},
        "additionalProperties": False,
    }


def _disturbances(node: dict[str, Any], kinds: list[str], partial: bool) -> dict[str, Any]:
    """The ``disturbances`` mapping: each entry is the model its ``name`` names, or, without
    ``name``, the model its key names (``dryden: {}``); an entry of another key needs a name
    (in a hand-written file it may be an entry another file declares, ``gps`` from
    ``disturbances=[gps]``: any model's options)."""
    def entry(default: str | None) -> dict[str, Any]:
        chosen = [{"if": {"properties": {"name": {"const": k}}, "required": ["name"]},
                   "then": {"$ref": REF.format(model=f"disturbances.{k}")}} for k in kinds]
        missing: dict[str, Any]  # the schema an entry without ``name`` must meet
        if default:
            missing = {"$ref": REF.format(model=f"disturbances.{default}")}
        else:
            missing = {"$ref": REF.format(model="disturbances.any")} if partial else {"required": ["name"]}
        return {"type": "object", "allOf": [
            *chosen,
            {"if": {"required": ["name"]}, "then": {"properties": {"name": {"enum": kinds}}}, "else": missing},
        ]}

    return {
        **{k: v for k, v in node.items() if k not in ("additionalProperties", "title")},
        "type": "object",
        "properties": {k: entry(k) for k in kinds},
        "additionalProperties": entry(None),
    }


def _event_kinds(root: dict[str, Any], defs: dict[str, Any], kinds: list[Any], refs: dict[Any, Any],
                 partial: bool) -> None:
    """``events``: each event is the registered kind its ``name`` names (an enum of the registry's
    kinds), with ``at``, ``agents`` and that kind's own fields (its ``Params``) only; the engine's
    one ``EventConfig`` definition, which admits any kind's fields, is replaced by one per kind."""
    base = defs.pop("EventConfig")["properties"]
    own = {cls.name: _name(refs[(cls.Params, "validation")]) for cls in kinds}
    for cls in kinds:
        defs[f"events.{cls.name}"] = _event(cls, base, defs[own[cls.name]])
    for name in set(own.values()):  # kinds without fields of their own share EventParams
        defs.pop(name)
    names = [cls.name for cls in kinds]
    if partial:  # an event whose kind another file gives: any kind's fields
        defs["events.any"] = _any_method(
            "an event whose kind is given elsewhere", "at, agents and the fields of any event kind",
            [defs[f"events.{n}"] for n in names], "name")
    chosen = [{"if": {"properties": {"name": {"const": n}}, "required": ["name"]},
               "then": {"$ref": REF.format(model=f"events.{n}")}} for n in names]
    missing = {"$ref": REF.format(model="events.any")} if partial else {"required": ["name"]}
    item = {"type": "object", "allOf": [*chosen, {
        "if": {"required": ["name"]},
        "then": {"properties": {"name": {"enum": names, "description": "registered event kind"}}},
        "else": missing}]}
    node = root["properties"]["events"]
    root["properties"]["events"] = {**{k: v for k, v in node.items() if k != "items"}, "items": item}


def _map_generators(defs: dict[str, Any], generators: list[Any], refs: dict[Any, Any]) -> None:
    """``environment.generator``: an enum of the registered map generators; a plugin generator's
    parameters join the built-ins' beside it (one flat namespace, as the engine reads them; which
    generator takes which parameter is said in each description and checked by the engine)."""
    props = defs["EnvironmentConfig"]["properties"]
    names = [cls.name for cls in generators]
    props["generator"] = {
        "anyOf": [{"enum": names}, {"type": "null"}], "default": None,
        "description": f"map generator, a registered name: {' | '.join(names)} (null: only the listed obstacles)"}
    own = {_name(refs[(cls.Params, "validation")]) for cls in generators}
    for cls in generators:
        for key, prop in defs[_name(refs[(cls.Params, "validation")])].get("properties", {}).items():
            if key not in props:  # a built-in's parameters are the section's own fields already
                props[key] = {**prop, "description": f"{cls.name}: {prop.get('description', key)}"}
    for name in own:
        defs.pop(name, None)


def _observers(root: dict[str, Any], defs: dict[str, Any], observers: list[Any], refs: Any) -> None:
    """``observers``: each observer that takes options, by name, with its ``Params``."""
    section = root["properties"]["observers"]
    section["properties"] = {}
    for cls in observers:
        key = f"observers.{cls.name}"
        defs[key] = defs.pop(_name(refs[(cls.Params, "validation")]))
        section["properties"][cls.name] = {"$ref": REF.format(model=key)}


def _event(cls: Any, base: dict[str, Any], params: dict[str, Any]) -> dict[str, Any]:
    """An event kind: ``at`` and ``agents`` (every event's), its ``name`` as a const, its Params."""
    doc = (cls.__doc__ or "").strip().splitlines()
    return {
        **{k: v for k, v in params.items() if k not in ("properties", "required", "title", "description")},
        "title": f"events name={cls.name}",
        "description": doc[0] if doc else f"event kind {cls.name}",
        "type": "object",
        "properties": {"at": base["at"], "agents": base["agents"],
                       "name": {"const": cls.name, "description": "registered event kind"},
                       **params.get("properties", {})},
        "required": ["at", "agents", "name", *params.get("required", [])],
        "additionalProperties": False,
    }


def _draft7(node: Any) -> Any:
    """pydantic writes fixed-length arrays (``tuple[float, float]``) as draft 2020-12's
    ``prefixItems``; draft 7 says the same with an array of ``items``."""
    if isinstance(node, list):
        return [_draft7(v) for v in node]
    if not isinstance(node, dict):
        return node
    out = {k: _draft7(v) for k, v in node.items()}
    if "prefixItems" in out:
        out["items"] = out.pop("prefixItems")
        out.setdefault("additionalItems", False)
    return out


def _partial(schema: dict[str, Any]) -> dict[str, Any]:
    """Every key optional, and the Hydra keys a scenario file may hold."""
    out = copy.deepcopy(schema)

    def relax(node: Any) -> None:
        if isinstance(node, dict):
            node.pop("required", None)
            for key, value in node.items():
                if key != "if":  # a condition "name is given" stays one
                    relax(value)
        elif isinstance(node, list):
            for value in node:
                relax(value)

    relax(out)
    out["properties"]["defaults"] = {
        "description": "Hydra defaults list (e.g. '- override /avoidance: cem')",
        "type": "array",
        "items": {"type": ["string", "object"]},
    }
    out["properties"]["hydra"] = {"description": "Hydra's own settings (sweeps, run directories)", "type": "object"}
    task = out.get("definitions", {}).get("TaskConfig")
    if task is not None:  # a task file states its horizon as the run's duration: horizon: ${clock.duration}
        horizon = task["properties"]["horizon"]
        task["properties"]["horizon"] = {"description": horizon.get("description", "horizon"), "anyOf": [
            horizon, {"type": "string", "pattern": r"^\$\{clock\.duration\}$"}]}
    return out


GLOBAL_GROUPS = ("scenario", "sweep", "events", "task")
"""Groups whose files are ``# @package _global_``: they hold top-level keys (the partial schema)."""
SECTION_GROUPS = ("swarm", "environment", "formation", "avoidance", "dynamics", "disturbances", "observers")
"""Groups whose files hold one section's node (``scenarios/config.yaml``'s defaults list)."""
TUNING_GROUPS = tuple(f"tuning/{kind}" for kind in PLUGIN_KINDS)
"""A preset's tuning of one method (``tuning/<kind>/<preset>/<method>.yaml``): the kind's node."""
GROUPS = (*GLOBAL_GROUPS, *SECTION_GROUPS, *TUNING_GROUPS)
_DEFAULTS = {"description": "Hydra defaults list (e.g. '- /tuning/dynamics/outdoor_square/double_integrator@_here_')",
             "type": "array", "items": {"type": ["string", "object"]}}


def group_schema(group: str, registry: Any | None = None) -> dict[str, Any]:
    """The JSON Schema of one config group's files (``GROUPS``). A Hydra config-group file holds
    its group's node: a map file (``environment/*.yaml``) holds the ``environment`` section's
    fields, a tuning file a plugin's options; a ``# @package _global_`` group (presets, sweeps,
    events) holds top-level keys. Each may open with a Hydra ``defaults`` list."""
    if group not in GROUPS:
        raise ValueError(f"unknown group {group!r} (valid: {', '.join(GROUPS)})")
    schema = scenario_schema(registry, partial=True)
    if group in GLOBAL_GROUPS:
        return {**schema, "title": f"swarmscene {group} file (# @package _global_: top-level keys)"}
    section = group.rsplit("/", 1)[-1]
    node, defs = schema["properties"][section], schema["definitions"]
    _allow_defaults(node, defs, set())
    return {"$schema": DIALECT, "title": f"swarmscene {group} file (the {section} section's node)",
            "allOf": [node], "definitions": defs}


def _allow_defaults(node: dict[str, Any], defs: dict[str, Any], seen: set[str]) -> None:
    """Let the group's node (through its ``$ref`` and if/then branches, not its fields) hold a
    ``defaults`` list. Only ever applied to a group schema's own copy of the definitions."""
    if "$ref" in node and _name(node) not in seen:
        seen.add(_name(node))
        _allow_defaults(defs[_name(node)], defs, seen)
    if "properties" in node:
        node["properties"].setdefault("defaults", _DEFAULTS)
    for sub in (*node.get("allOf", []), *node.get("anyOf", []), *node.get("oneOf", [])):
        _allow_defaults(sub, defs, seen)
    for key in ("then", "else"):
        if isinstance(node.get(key), dict):
            _allow_defaults(node[key], defs, seen)


def schema_file_name(group: str | None) -> str:
    """``swarmscene.<group>.schema.json`` (``tuning/avoidance`` -> ``tuning.avoidance``)."""
    return f"swarmscene.{group.replace('/', '.')}.schema.json" if group else "swarmscene.tools.schema.json"


def main(argv: list[str] | None = None) -> None:
    """``python -m swarmscene.tools.schema``: write or print the JSON Schemas (one line and exit 2 on bad input)."""
    parser = argparse.ArgumentParser(prog="python -m swarmscene.tools.schema",
                                     description=" ".join(__doc__.split("\n\n")[0].split()))
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--partial", action="store_true", help="schema of hand-written scenario files")
    which.add_argument("--group", choices=GROUPS, metavar="GROUP",
                       help=f"schema of one config group's files: {', '.join(GROUPS)}")
    which.add_argument("--all-groups", metavar="DIR",
                       help="write every group's schema into DIR (swarmscene.<group>.schema.json, "
                       "tuning/avoidance as tuning.avoidance)")
    parser.add_argument("-o", "--output", help="write to this file instead of standard output")
    args = parser.parse_args(argv)
    if args.all_groups and args.output:
        parser.error("--output names one file; --all-groups writes one file per group into DIR")
    if args.all_groups:
        try:
            Path(args.all_groups).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            parser.exit(2, f"{parser.prog}: {args.all_groups}: cannot be created ({exc.strerror or exc})\n")
        for group in GROUPS:
            _write(parser, str(Path(args.all_groups) / schema_file_name(group)), group_schema(group))
        return
    schema = group_schema(args.group) if args.group else scenario_schema(partial=args.partial)
    _write(parser, args.output, schema)


def _write(parser: argparse.ArgumentParser, output: str | None, schema: dict[str, Any]) -> None:
    text = json.dumps(schema, indent=2, allow_nan=False) + "\n"
    if not output:
        sys.stdout.write(text)
        return
    from ..runs.outputs import atomic_write_bytes

    try:
        atomic_write_bytes(Path(output), text.encode("utf-8"))
    except OSError as exc:
        parser.exit(2, f"{parser.prog}: {output}: cannot be written ({exc.strerror or exc})\n")


if __name__ == "__main__":
    main()
