"""Hydra's composition errors, reworded as the engine's one-line messages."""

from __future__ import annotations

import re

_NOT_IN_STRUCT = re.compile(r"Could not override '([^']+)'")
_APPEND_HINT = re.compile(r"use \+([^=\s]+)=(\S*)")
_MISSING_GROUP_OPTION = re.compile(r"Could not find '([^'/]+(?:/[^'/]+)*)/([^'/]+)'")


def hydra_error_line(exc: BaseException) -> str | None:
    """One line ``key: problem (got value)`` for a Hydra composition error, else ``None``."""
    from hydra.errors import (
        ConfigCompositionException,
        InstantiationException,
        MissingConfigException,
        OverrideParseException,
    )

    if isinstance(exc, InstantiationException) and isinstance(exc.__cause__, ValueError):
        return str(exc.__cause__).splitlines()[0]  # a plugin of Hydra's (sweeper) refused its options
    message = str(exc)
    if isinstance(exc, MissingConfigException):
        match = _MISSING_GROUP_OPTION.search(message)
        if match:
            group, option = match.groups()
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
            return f"{key}: unknown key (got {value!r})"
        return " ".join(message.split())
    return None
