"""Hydra's composition errors (and YAML and interpolation errors), reworded as the engine's
one-line messages."""

from __future__ import annotations

import re

_NOT_IN_STRUCT = re.compile(r"Could not override '([^']+)'")
_APPEND_HINT = re.compile(r"use \+([^=\s]+)=(\S*)")
_MERGING = re.compile(r"Error merging override (\S+)")
_MISSING_GROUP_OPTION = re.compile(r"Could not find '([^'/]+(?:/[^'/]+)*)/([^'/]+)'")


PLUGIN_EXTRAS = {
    ("hydra/launcher", "joblib"): "joblib", ("hydra/launcher", "ray"): "ray",
    ("hydra/launcher", "submitit_local"): "submitit", ("hydra/launcher", "submitit_slurm"): "submitit",
    ("hydra/sweeper", "optuna"): "optuna",
}
"""Hydra plugins that an extra of swarmscene installs: (group, option) -> the extra. Without it
Hydra reads the option as unknown; the line gives the install command instead."""

ADDED_GROUPS = ("sweep",)
"""Config groups a command adds (``+sweep=cem_k``) rather than chooses: not in the defaults list."""


def hydra_error_line(exc: BaseException) -> str | None:
    """One line ``key: problem (got value)`` for a Hydra composition error, else ``None``."""
    from hydra.errors import (
        ConfigCompositionException,
        InstantiationException,
        MissingConfigException,
        OverrideParseException,
    )

    yaml_line = yaml_error_line(exc)
    if yaml_line is not None:
        return yaml_line
    if isinstance(exc, InstantiationException) and isinstance(exc.__cause__, ValueError):
        return str(exc.__cause__).splitlines()[0]  # a plugin of Hydra's (sweeper) refused its options
    message = str(exc)
    if isinstance(exc, MissingConfigException):
        match = _MISSING_GROUP_OPTION.search(message)
        if match:
            group, option = match.groups()
            extra = PLUGIN_EXTRAS.get((group, option))
            if extra is not None:  # a launcher or sweeper whose Hydra plugin is not installed
                return (f"{group}={option} needs the {extra!r} extra (Hydra's {option} plugin is not "
                        f"installed): pip install 'swarmscene[{extra}]'")
            valid = ", ".join(sorted(exc.options or ()))
            return f"{group.replace('/', '.')}: unknown option {option!r} (valid: {valid})"
        return message.splitlines()[0]
    if isinstance(exc, OverrideParseException):
        text = getattr(exc, "override", "") or ""
        key = text.split("=")[0] or "<override>"
        reason = message.splitlines()[0]
        return f"{key}: cannot parse override: {reason} (got {text!r})"
    if isinstance(exc, ConfigCompositionException):
        match = _NOT_IN_STRUCT.search(message)
        if match:
            key = match.group(1)
            hint = _APPEND_HINT.search(message)
            value = hint.group(2) if hint else "?"
            if key in ADDED_GROUPS:  # a group outside the defaults list is added with a plus
                return f"{key}: not in the defaults list: add it with a plus, +{key}={value} (got {key}={value})"
            return f"{key}: unknown key (got {value!r})"
        merging = _MERGING.search(message)
        if merging and exc.__cause__ is not None:
            key, _, value = merging.group(1).lstrip("+~").partition("=")
            cause = " ".join(str(exc.__cause__).split("\n")[0].split())
            return f"{key}: cannot set this key: {cause} (got {value!r})"
        return " ".join(message.split())
    return resolution_error_line(exc)


def yaml_error_line(exc: BaseException | None) -> str | None:
    """``file:line: cannot parse YAML: problem`` for a YAML file that does not parse, else None."""
    import yaml

    while exc is not None and not isinstance(exc, yaml.YAMLError):
        exc = exc.__cause__ or exc.__context__
    if exc is None:
        return None
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    if mark is None:
        return f"cannot parse YAML: {problem}"
    where = f"{mark.name}:{mark.line + 1}:{mark.column + 1}"
    context = getattr(exc, "context", None)
    started = getattr(exc, "context_mark", None)
    tail = f" ({context} started at line {started.line + 1})" if context and started is not None else ""
    return f"{where}: cannot parse YAML: {problem}{tail}"


def resolution_error_line(exc: BaseException | None) -> str | None:
    """``key: cannot resolve ${...}: reason`` for an interpolation that does not resolve, else None."""
    from omegaconf.errors import OmegaConfBaseException

    while exc is not None and not isinstance(exc, OmegaConfBaseException):
        exc = exc.__cause__
    if exc is None or not getattr(exc, "full_key", None):
        return None
    reason = _first_line(getattr(exc, "msg", None) or str(exc))
    if reason.endswith(":"):  # "KeyError raised while resolving interpolation: " and nothing after
        reason = reason[:-1] + " (the resolver gave no message)"
    return f"{exc.full_key}: cannot resolve the value: {reason or type(exc).__name__ + ' (no message)'}"


def _first_line(text: str) -> str:
    """The first line of ``text`` with its spaces collapsed ('' for no text)."""
    lines = text.splitlines()
    return " ".join(lines[0].split()) if lines else ""
