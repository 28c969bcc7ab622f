"""Errors a user can fix, and their one-line wording.

Every problem with a scenario becomes one line ``dotted.key: what is allowed (got value)``; the
command line prints the lines and exits with status 2, without a traceback.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic_core import ErrorDetails


class ConfigError(ValueError):
    """One or more problems with a scenario's configuration, one line each."""

    def __init__(self, lines: list[str]) -> None:
        self.lines = list(lines)
        super().__init__("\n".join(self.lines))


class PluginError(RuntimeError):
    """A plugin could not be loaded or registered (duplicate name, bad class)."""


class SwarmsceneDeprecationWarning(DeprecationWarning):
    """A name of swarmscene's that works for one more release (an option, an attribute a hook
    reads). Python hides DeprecationWarnings outside ``__main__``; the command line shows this
    category, each distinct warning once, so a user meets it before the name is removed."""


def validate_renamed(data: Any, handler: Callable[[Any], Any], renames: dict[str, str], prefix: str,
                     until: str | None = None) -> Any:
    """Validate ``data`` (a pydantic ``wrap`` model validator's input) whose deprecated keys are
    renamed first (``renames``: old -> new), each with a :class:`SwarmsceneDeprecationWarning` (saying
    the release ``until`` which the old key is read, when given); an old key given wins over the new
    one's value, so that an old command line still overrides a file written in the new spelling. A
    value given under an old name that does not validate is reported under the name the user typed,
    with the new one (``avoidance.n (now avoidance.newton_iterations): must be >= 1``), not under a
    key they never wrote."""
    if not isinstance(data, dict) or not any(old in data for old in renames):
        return handler(data)
    data, typed = dict(data), {}
    for old, new in renames.items():
        if old in data:
            last = f" ({old} is accepted until {until})" if until else ""
            warnings.warn(f"{prefix}.{old} is deprecated: write {prefix}.{new}{last}", SwarmsceneDeprecationWarning,
                          stacklevel=4)
            data[new] = data.pop(old)
            typed[new] = old
    try:
        return handler(data)
    except ValidationError as exc:
        errors: list[Any] = []
        for err in exc.errors(include_url=False):
            loc = tuple(err["loc"])
            if loc and loc[0] in typed:
                loc = (f"{typed[str(loc[0])]} (now {prefix}.{loc[0]})", *loc[1:])
            errors.append({"type": err["type"], "loc": loc, "input": err["input"],
                           **({"ctx": err["ctx"]} if "ctx" in err else {})})
        try:
            renamed = ValidationError.from_exception_data(exc.title, errors)
        except Exception:  # an error type pydantic cannot rebuild (a custom one): keep the original
            raise exc from None
        raise renamed from None


_BOUNDS = {
    "greater_than": ">",
    "greater_than_equal": ">=",
    "less_than": "<",
    "less_than_equal": "<=",
}
_TYPES = {
    "int_type": "an integer",
    "int_parsing": "an integer",
    "int_from_float": "an integer",
    "float_type": "a number",
    "float_parsing": "a number",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
    "string_type": "a string",
    "list_type": "a list",
    "tuple_type": "a list",
    "dict_type": "a mapping",
    "model_type": "a mapping",
    "model_attributes_type": "a mapping",
    "finite_number": "a finite number",
}


def _dotted(loc: tuple[Any, ...], prefix: str) -> str:
    parts = [prefix] if prefix else []
    # Tagged unions add the tag to the location (obstacles.0.circle.radius): drop it.
    parts += [str(p) for p in loc if not (isinstance(p, str) and p in ("polygon", "circle", "wall"))]
    return ".".join(parts) or "<root>"


def _fields_at(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str]:
    """Field names of the (sub)model at ``loc`` (for 'unknown key' messages)."""
    current: Any = model
    for part in loc:
        if isinstance(part, int) or not (isinstance(current, type) and issubclass(current, BaseModel)):
            continue
        field = current.model_fields.get(part)
        if field is None:
            break
        annotation = field.annotation
        inner = [a for a in getattr(annotation, "__args__", ()) if isinstance(a, type)]
        current = annotation if isinstance(annotation, type) else (inner[0] if inner else None)
    if isinstance(current, type) and issubclass(current, BaseModel):
        return list(current.model_fields)
    return []


def _describe(err: ErrorDetails, model: type[BaseModel]) -> str:
    kind, ctx = err["type"], err.get("ctx") or {}
    if kind in _BOUNDS:
        bound = next(iter(ctx.values()))
        return f"must be {_BOUNDS[kind]} {bound}"
    if kind in _TYPES:
        return f"must be {_TYPES[kind]}"
    if kind == "missing":
        return "is required"
    if kind == "extra_forbidden":
        valid = _fields_at(model, tuple(err["loc"][:-1]))
        return "unknown key" + (f" (valid keys: {', '.join(valid)})" if valid else "")
    if kind == "literal_error":
        return f"must be one of {ctx.get('expected', '')}"
    if kind in ("too_short", "too_long"):
        word = "at least" if kind == "too_short" else "at most"
        count = ctx.get("min_length", ctx.get("max_length"))
        return f"must have {word} {count} item(s)"
    if kind == "union_tag_invalid":
        return f"unknown type (valid: {ctx.get('expected_tags', '')})"
    if kind == "union_tag_not_found":
        return f"needs a '{ctx.get('discriminator', 'type').strip(chr(39))}' key"
    if kind == "value_error":
        return str(ctx.get("error", err["msg"])).removeprefix("Value error, ")
    return err["msg"][0].lower() + err["msg"][1:]


def format_validation_error(
    exc: ValidationError, model: type[BaseModel], data: Any, prefix: str = ""
) -> list[str]:
    """One line per pydantic error: ``dotted.key: what is allowed (got value)``."""
    lines = []
    for err in exc.errors(include_url=False):
        message = _describe(err, model)
        key = _dotted(tuple(err["loc"]), prefix)
        if err["type"] == "value_error" and ":" in message and not err["loc"]:
            # A model-level check names its key relative to its model: `vision: ...` in a
            # formation's Params is `formation.vision: ...` to the user.
            if prefix and not message.startswith(f"{prefix}."):
                message = f"{prefix}.{message}"
            lines.append(message)
            continue
        got = "" if err["type"] == "missing" else f" (got {err['input']!r})"
        lines.append(f"{key}: {message}{got}")
    return lines
