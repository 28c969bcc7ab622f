"""A JSON Schema of the whole configuration: the engine's sections and every registered plugin's
options (third-party plugins included), for editors and other tools.

    python -m swarmscene.schema > swarmscene.schema.json            # a composed configuration
    python -m swarmscene.schema --partial > swarmscene.partial.json  # hand-written scenario files

Both come from the same pydantic models the engine validates with (:mod:`swarmscene.core.config`
and each plugin's ``Params``). ``formation``, ``avoidance`` and ``dynamics`` are each one of the
registered plugins of their kind, told apart by ``name`` (a ``const``), so an editor completes and
checks the options of the plugin chosen. The full schema describes what the engine validates after
Hydra composition (``swarmscene --cfg job``, ``api.compose``); the partial one describes the files a
user writes (presets, experiment files): every key optional, a Hydra ``defaults`` list and a
``hydra`` node allowed, and a plugin section whose ``name`` comes from the defaults list accepted.
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

from .core.config import ScenarioConfig
from .core.plugin import PLUGIN_KINDS

DIALECT = "http://json-schema.org/draft-07/schema#"
"""Draft 7: the newest the YAML language server supports."""
REF = "#/definitions/{model}"


def scenario_schema(registry: Any | None = None, partial: bool = False) -> dict[str, Any]:
    """The JSON Schema of a configuration, with the plugins of ``registry`` (default: every
    installed plugin); ``partial`` for hand-written scenario files (see the module docstring)."""
    if registry is None:
        from .api import plugins

        _, registry = plugins()
    plugins_by_kind = {kind: [registry.get(kind, n) for n in registry.names(kind)] for kind in PLUGIN_KINDS}
    models = [(ScenarioConfig, "validation")] + [
        (cls.Params, "validation") for classes in plugins_by_kind.values() for cls in classes
    ]
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
        root["properties"][kind] = {
            "description": f"the {kind} plugin, chosen by name ({', '.join(c.name for c in classes)}), and its options",
            "anyOf" if partial else "oneOf": variants,
        }
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
            for value in node.values():
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
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m swarmscene.schema", description=__doc__.splitlines()[0])
    parser.add_argument("--partial", action="store_true", help="schema of hand-written scenario files")
    parser.add_argument("-o", "--output", help="write to this file instead of standard output")
    args = parser.parse_args(argv)
    text = json.dumps(scenario_schema(partial=args.partial), indent=2, allow_nan=False) + "\n"
    if args.output:
        from .core.outputs import atomic_write_bytes

        try:
            atomic_write_bytes(Path(args.output), text.encode("utf-8"))
        except OSError as exc:
            parser.exit(2, f"{parser.prog}: {args.output}: cannot be written ({exc.strerror or exc})\n")
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
