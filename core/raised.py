"""A plugin that raises during a run: which plugin, which of its methods, and when.

The kernel calls plugins (formation, avoidance, dynamics, disturbance models, event kinds,
policies) and the plugin manager calls observers' lifecycle hooks. When one of them raises, the
run cannot go on, but what it recorded so far is worth keeping, and the user needs to know whose
code failed: the exception type alone ("ZeroDivisionError: division by zero") names nothing. The
origin is read from the traceback: the outermost frame that runs a method of a plugin object
(or a hook function of a plugin module registered on the manager) is the call the engine made.
"""

from __future__ import annotations

from types import ModuleType, TracebackType
from typing import TYPE_CHECKING, Any

from .disturbances.base import Disturbance
from .events import EventKindPlugin
from .generators import MapGenerator
from .plugin import Avoidance, Dynamics, Formation, Policy

if TYPE_CHECKING:  # pragma: no cover
    from .result import RunResult

_KINDS: tuple[tuple[type, str], ...] = (
    (Formation, "formation"),
    (Avoidance, "avoidance"),
    (Dynamics, "dynamics"),
    (Disturbance, "disturbance model"),
    (EventKindPlugin, "event kind"),
    (MapGenerator, "map generator"),
    (Policy, "policy"),
)


class PluginRaised(RuntimeError):
    """A plugin raised during a run. The message is one line naming the plugin's kind, name, the
    method and the simulated time; ``__cause__`` is the plugin's own exception (its traceback), and
    ``result`` what the run recorded up to the tick that failed (``stop_reason`` ``plugin_error``,
    ``success`` False), so a caller can still write it, marked failed."""

    reason = "plugin-error"

    def __init__(self, line: str, result: RunResult) -> None:
        super().__init__(line)
        self.result = result


def origin(exc: BaseException, observers: list[Any], hook_modules: dict[str, str]) -> str | None:
    """``"<kind> '<name>' raised in <method>"`` for the plugin whose method raised ``exc``, else None.

    Args:
        exc: the exception, with its traceback.
        observers: the run's observer instances (named ``observer <ClassName>``).
        hook_modules: module name -> plugin name, for plugins registered on the manager as modules
            (their lifecycle hooks are plain functions).
    """
    tb: TracebackType | None = exc.__traceback__
    while tb is not None:
        frame = tb.tb_frame
        method = frame.f_code.co_name
        owner = frame.f_locals.get("self")
        named = _named(owner, observers) if owner is not None else None
        if named is None and owner is None:
            module = frame.f_globals.get("__name__")
            if module in hook_modules:
                named = f"plugin {hook_modules[module]!r}"
        if named is not None:
            return f"{named} raised in {method}" + zero_options(exc, owner)
        tb = tb.tb_next
    return None


ARITHMETIC = (ZeroDivisionError, FloatingPointError, OverflowError)


def zero_options(exc: BaseException, plugin: Any, prefix: str | None = None) -> str:
    """`` (with formation.spacing = 0)`` naming the plugin's numeric options set to zero (whose
    default is not zero) when ``exc`` is arithmetic (a division by zero, an overflow): the likely
    cause is an option the user set, which the plugin's name alone does not tell; '' otherwise."""
    params = getattr(plugin, "params", None)
    fields = getattr(type(params), "model_fields", None)
    if not isinstance(exc, ARITHMETIC) or not fields:
        return ""
    if prefix is None:
        prefix = next((kind for base, kind in _KINDS[:3] if isinstance(plugin, base)), "option")
    zero = [f"{prefix}.{name} = 0" for name, field in fields.items()
            if isinstance(getattr(params, name, None), (int, float)) and not isinstance(getattr(params, name), bool)
            and getattr(params, name) == 0 and field.default != 0]  # set so, not a default of 0
    return f" (with {', '.join(zero)})" if zero else ""


def _named(owner: Any, observers: list[Any]) -> str | None:
    if isinstance(owner, type) or isinstance(owner, ModuleType):
        return None
    for base, kind in _KINDS:
        if isinstance(owner, base):
            name = getattr(owner, "name", None) or type(owner).__name__
            return f"{kind} {name!r}"
    if any(owner is obs for obs in observers):
        return f"observer {type(owner).__name__!r}"
    return None


def describe(exc: BaseException, where: str | None, t: float) -> str:
    """The one line a user reads: who raised, when, and the exception's first line."""
    first = (str(exc).splitlines() or [""])[0]
    reason = f"{type(exc).__name__}: {first}" if first else type(exc).__name__
    who = where if where is not None else "the run raised (in the engine, no plugin on the stack)"
    return f"{who} at t = {t:g} s: {reason}"


class RunFailed(RuntimeError):
    """A run that stopped on a non-finite state or a plugin's exception (its ``__cause__``): its
    outputs up to then are written, marked failed; the message is the run's one-line ``error``
    and ``reason`` error.json's word for it (``non-finite``, ``plugin-error``)."""

    def __init__(self, message: str, reason: str = "non-finite") -> None:
        super().__init__(message)
        self.reason = reason

    @classmethod
    def of(cls, result: RunResult, cause: BaseException | None = None) -> RunFailed:
        """The failure of ``result`` (whose ``error`` is set), caused by ``cause``."""
        failed = cls(result.error or "", "plugin-error" if result.stop_reason == "plugin_error" else "non-finite")
        failed.__cause__ = cause
        return failed
