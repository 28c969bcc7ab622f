"""Named contract checks: one function per promise of a plugin kind, as scikit-learn's
``check_estimator`` yields its checks (issue #35).

A check is a function of a :class:`Subject` (the class under test, its validated options and what
the checks share), registered for its kind with :func:`promise` under the name
``<kind>.<promise>``; its docstring's first line is the promise, in the words docs/plugins.md uses.
:func:`run` runs every check of a kind and reports each by name: a plugin author reads which
promise was broken, not only the first assertion that fired.

The first check of every kind, ``<kind>.params`` (``name`` and ``Params`` as the engine needs them),
is a gate: the other checks need the validated options, so its failure stops the run at once.

A plugin that knowingly breaks a promise says so on its class, with the reason, as scikit-learn's
``_xfail_checks`` tag does::

    class MyAvoidance(Avoidance):
        name = "my_avoidance"
        xfail_checks = {"avoidance.deterministic": "reads the flight controller's hardware RNG"}

Such a check still runs: its failure is reported as expected (with the reason), and a check that is
listed but passes fails the run (the list must stay true). A listed name that no check has fails the
run too, naming the valid ones. The gate cannot be listed.
"""

from __future__ import annotations

import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

__all__ = ["Check", "ContractError", "Outcome", "Subject", "checks_of", "promise", "run"]


@dataclass
class Subject:
    """What every check of one run sees: the class, its validated options, and shared work.

    Attributes:
        cls: the plugin class under test.
        params: its validated options (the gate's result).
        environment: the map the checks fly in (None: open).
        class_state: copies of the class's data attributes taken before any check ran (the
            no-shared-state promise compares against them, whichever checks ran before it).
    """

    cls: type[Any]
    params: Any
    environment: Any = None
    class_state: dict[str, Any] = field(default_factory=dict)
    _memo: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The plugin's registered name (the checks' messages start with it)."""
        return str(getattr(self.cls, "name", self.cls.__name__))

    def memo(self, key: str, make: Callable[[], Any]) -> Any:
        """``make()`` once per subject: a flight or rollout that several promises read.

        A rollout that fails raises again for every check that reads it (each names the promise
        it could not check)."""
        if key not in self._memo:
            try:
                self._memo[key] = (True, make())
            except AssertionError as exc:
                self._memo[key] = (False, exc)
        ok, value = self._memo[key]
        if not ok:
            raise AssertionError(str(value))
        return value


@dataclass(frozen=True)
class Check:
    """One promise of a kind: ``name`` (``<kind>.<promise>``), the promise in words, the function."""

    name: str
    promise: str
    function: Callable[[Subject], None]


@dataclass(frozen=True)
class Outcome:
    """What one check found: ``passed``, ``failed`` or ``xfailed`` (an expected failure), and why."""

    check: str
    status: Literal["passed", "failed", "xfailed"]
    message: str = ""


class ContractError(AssertionError):
    """One or more promises broken: the message lists each failed check by name.

    Attributes:
        outcomes: every check's :class:`Outcome`, passed ones included.
    """

    def __init__(self, message: str, outcomes: list[Outcome]) -> None:
        super().__init__(message)
        self.outcomes = outcomes


_CHECKS: dict[str, list[Check]] = {}


def promise(kind: str, name: str) -> Callable[[Callable[[Subject], None]], Callable[[Subject], None]]:
    """Register the decorated function as the check ``<kind>.<name>`` (in the order registered)."""

    def register(function: Callable[[Subject], None]) -> Callable[[Subject], None]:
        doc = (function.__doc__ or "").strip().split("\n\n")[0]
        _CHECKS.setdefault(kind, []).append(Check(f"{kind}.{name}", " ".join(doc.split()), function))
        return function

    return register


def checks_of(kind: str) -> list[Check]:
    """The named checks of ``kind``, the gate first."""
    return list(_CHECKS.get(kind, []))


def run(kind: str, subject: Subject) -> list[Outcome]:
    """Run every check of ``kind`` on ``subject`` (the gate already passed); return the outcomes.

    Raises:
        ContractError: a check failed that was not declared in the class's ``xfail_checks``, a
            declared one passed, or ``xfail_checks`` names a check that does not exist.
    """
    checks = checks_of(kind)
    expected = _expected_failures(subject, checks)
    outcomes = [Outcome(checks[0].name, "passed")]  # the gate, passed before the subject was built
    for check in checks[1:]:
        try:
            check.function(subject)
        except AssertionError as exc:
            outcomes.append(_failed(check, str(exc), expected))
        except Exception as exc:  # a plugin that raises is a broken promise too, named as such
            where = traceback.extract_tb(exc.__traceback__)[-1]
            text = f"{subject.name}: raised {type(exc).__name__}: {exc} (at {where.filename}:{where.lineno})"
            outcomes.append(_failed(check, text, expected))
        else:
            if check.name in expected:
                outcomes.append(Outcome(check.name, "failed", (
                    f"{subject.name}: listed in xfail_checks ({expected[check.name]}) but it passes: "
                    "remove it from the list")))
            else:
                outcomes.append(Outcome(check.name, "passed"))
    failed = [o for o in outcomes if o.status == "failed"]
    if failed:
        lines = "\n".join(f"[{o.check}] {o.message}" for o in failed)
        raise ContractError(f"{len(failed)} of {len(checks)} {kind} checks failed:\n{lines}", outcomes)
    return outcomes


def _failed(check: Check, message: str, expected: dict[str, str]) -> Outcome:
    if check.name in expected:
        return Outcome(check.name, "xfailed", f"expected ({expected[check.name]}): {message}")
    return Outcome(check.name, "failed", message)


def _expected_failures(subject: Subject, checks: list[Check]) -> dict[str, str]:
    """The class's ``xfail_checks`` (check name -> reason), each name known and not the gate."""
    declared = getattr(subject.cls, "xfail_checks", None) or {}
    if not isinstance(declared, dict) or not all(
            isinstance(k, str) and isinstance(v, str) and v.strip() for k, v in declared.items()):
        raise ContractError(f"{subject.name}: xfail_checks must map check names to their reasons "
                            f"(got {declared!r})", [])
    names = [c.name for c in checks]
    unknown = sorted(set(declared) - set(names[1:]))
    if unknown:
        raise ContractError(f"{subject.name}: xfail_checks names {unknown}, which are not checks that can be "
                            f"expected to fail (valid: {', '.join(names[1:])})", [])
    return dict(declared)
