"""The grid of a sweep, and its one check: every distinct override validated before it runs.

Before a job starts, the overrides it brings are checked, so that a mistake stops the sweep with one
line instead of showing up as a failed job half-way through: every distinct override of the grid,
numbers included, is composed *and* validated by the engine's schema
(``swarmscene.core.validation.validate``, as ``api.load``) in the first job that has it. In Hydra's grid
order that job is the first job with only this one override changed, so the line names the job and
the override:
``job 1 (avoidance.K=0): avoidance.K: must be >= 1 (got 0)``.

It stays fast because composition is the expensive part (~70 ms for this config tree; Hydra's own
basic sweeper composes every job up front, hydra#1324): config-group overrides (``scenario=...``)
are composed once per distinct set, and plain values (``seed=17``, ``avoidance.K=0``) are set in
that composed config's data the way Hydra sets them (in a copy of the config itself when it holds
interpolations, or for ``+``/``~`` overrides and lists), then validated (~0.5 ms each). A grid of up
to :data:`UPFRONT` distinct overrides is checked whole before the first job; a larger one (10,000
seeds) batch by batch, each batch checked before it is launched, so its first job starts at once
(:class:`GridCheck`).
"""

from __future__ import annotations

import copy
import itertools
import sys
from collections.abc import Sequence
from typing import Any, cast

VALIDATE = ("each_value", "all")
ON_INVALID = ("stop", "record")
UPFRONT = 1000
"""Distinct overrides checked before the first job; a grid with more is checked batch by batch."""


# -- the grid ---------------------------------------------------------------------------------
def expand(
    params: dict[str, Any] | None,
    arguments: Sequence[str],
    parser: Any,
    cases: Sequence[Sequence[str]] | None = None,
    plain_params: bool = True,
) -> tuple[list[str], list[list[str]]]:
    """The grid as given (one ``key=values`` string per key) and every job's overrides, in order.

    As Hydra's basic sweeper: ``params`` first, then ``arguments`` (the command line), a later
    entry of the same key replacing an earlier one in place; the jobs are the product of the
    keys' values, the first key varying slowest. With ``cases``, each case's overrides come
    first and the jobs are ``cases x product`` (cases are dropped when ``arguments`` set a key
    that a case sets). With ``plain_params`` the ``params`` and ``cases`` are read as the command
    line reads its overrides (``swarmscene.composition.searchpath.plain_overrides``); Hydra's basic sweeper
    does not, so its check passes False.
    """
    lines = [f"{k}={v}" for k, v in (params or {}).items()]
    if plain_params:
        from ..composition.searchpath import plain_overrides

        lines = plain_overrides(lines)  # as the command line's: `a.b: 1,2` sets a.b, default or not
    parsed = parser.parse_overrides([*lines, *arguments])
    final: dict[str, Any] = {}
    for override in parsed:
        final[override.get_key_element()] = override
    values = []
    for key, override in final.items():
        if override.is_sweep_override():
            if not override.is_discrete_sweep():
                from ..core.errors import ConfigError

                kind = override.value_type.name.lower().replace("_sweep", "")
                raise ConfigError([
                    f"{override.key_or_group}: a grid sweep takes a list of values (a,b,c / range / choice / "
                    f"glob), not an {kind} (got {shown(_as_given(override))!r}): use an optimising sweeper"
                ])
            values.append([f"{key}={v}" for v in override.sweep_string_iterator()])
        else:
            values.append([f"{key}={override.get_value_element_as_str()}"])
    grid = [_as_given(o) for o in final.values()]
    product = [list(combo) for combo in itertools.product(*values)]
    case_lists = [[str(o) for o in case] for case in (cases or [])]
    if plain_params and case_lists:
        from ..composition.searchpath import plain_overrides

        case_lists = [plain_overrides(case) for case in case_lists]
    if case_lists:
        given = {o.get_key_element() for o in parser.parse_overrides(list(arguments))}
        case_keys = {o.get_key_element() for case in case_lists for o in parser.parse_overrides(case)}
        if given & case_keys:
            case_lists = []
    if not case_lists:
        return grid, product
    grid = ["cases=" + " | ".join(" ".join(case) for case in case_lists), *grid]
    return grid, [[*case, *combo] for case in case_lists for combo in product]


def _as_given(override: Any) -> str:
    return override.input_line or f"{override.get_key_element()}={override.get_value_element_as_str()}"


def jobs_to_validate(jobs: Sequence[Sequence[str]]) -> list[tuple[int, list[str]]]:
    """The jobs whose check covers every distinct override, with the overrides each one brings.

    The first job is checked with all its overrides; after it, the first job holding an override
    not seen yet (in Hydra's grid order: the first job with just that override changed).
    """
    seen: set[str] = set()
    chosen = []
    for index, overrides in enumerate(jobs):
        new = [o for o in overrides if o not in seen]
        if new:
            seen.update(new)
            chosen.append((index, new if index else list(overrides)))
    return chosen


# -- the check --------------------------------------------------------------------------------
class JobCheck:
    """Composes and validates jobs of one sweep, each config-group set composed once."""

    def __init__(self, config_loader: Any, master: Any) -> None:
        from hydra.core.override_parser.overrides_parser import OverridesParser

        from ..builtins import BUILTIN_PLUGINS
        from ..core.registry import make_plugin_manager
        from .compose import extends_search_path

        self.loader = config_loader
        self.master = master
        self.parser = OverridesParser.create(config_loader=config_loader)
        self.registry = make_plugin_manager(BUILTIN_PLUGINS)[1]  # the installed plugins, as api.plugins()
        self.composed: dict[tuple[str, ...], Any] = {}
        self._groups: dict[str, bool] = {}
        self.whole = extends_search_path(master)  # groups the repository cannot tell: Hydra composes

    def _is_group(self, override: Any) -> bool:
        if override.package is not None or self.whole:
            return True
        name = override.key_or_group
        if name not in self._groups:
            self._groups[name] = bool(self.loader.repository.group_exists(name))
        return self._groups[name]

    def data(self, overrides: Sequence[str]) -> dict[str, Any]:
        """The job's composed config as plain data (no ``hydra`` node), as the job will see it."""
        from omegaconf import OmegaConf, open_dict

        from .compose import _apply_values, parse

        parsed = parse(list(overrides))
        groups = tuple(o.input_line for o in parsed if self._is_group(o))
        values = [o for o in parsed if not self._is_group(o)]
        cfg, plain = self._compose(groups)
        if plain is not None and all(_settable(o, plain) for o in values):
            data = plain
            for override in values:
                data = _with_value(data, override.key_or_group.split("."), override.value())
            return data
        cfg = copy.deepcopy(cfg)
        _apply_values(values, cfg)  # as Hydra applies the overrides that are not group choices
        with open_dict(cfg):
            del cfg["hydra"]
        return cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=True))  # the root is a mapping

    def _compose(self, groups: tuple[str, ...]) -> tuple[Any, dict[str, Any] | None]:
        """The config composed with these config-group overrides (once), and its plain data when
        it holds no interpolation (then a plain value is set in the data directly, exactly as
        Hydra would set it in the config, for a fraction of the cost of copying the config)."""
        from omegaconf import OmegaConf

        if groups not in self.composed:
            cfg = self.loader.load_sweep_config(self.master, list(groups))
            composed = cast("dict[str, Any]", OmegaConf.to_container(cfg, resolve=False))
            task = {k: v for k, v in composed.items() if k != "hydra"}
            self.composed[groups] = (cfg, None if "${" in repr(task) else task)
        return self.composed[groups]

    def reads_hydra(self, overrides: Sequence[str]) -> bool:
        """Whether the job's config reads ``${hydra:...}`` (description='job ${hydra:job.num}'):
        such a value resolves in the job alone, whose launch sets ``HydraConfig``, so the job is
        checked when it runs, not here."""
        from .compose import parse

        try:
            parsed = parse(list(overrides))
            if any("${hydra:" in str(o.value()) for o in parsed if not self._is_group(o)):
                return True
            cfg, _ = self._compose(tuple(o.input_line for o in parsed if self._is_group(o)))
        except Exception:  # an override or composition error: problems() reports it, naming the job
            return False
        return "${hydra:" in repr({k: v for k, v in cfg.items_ex(resolve=False) if k != "hydra"})

    def problems(self, overrides: Sequence[str]) -> tuple[str, list[str]]:
        """(``"compose"`` or ``"invalid"`` or ``""``, the problem lines) of one job."""
        from ..composition.hydra_errors import hydra_error_line
        from ..core.errors import ConfigError
        from ..core.validation import validate

        if self.reads_hydra(overrides):
            return "", []
        try:
            data = self.data(overrides)
        except Exception as exc:  # Hydra's composition errors, reworded
            return "compose", [hydra_error_line(exc) or " ".join(f"{type(exc).__name__}: {exc}".split())]
        try:
            validate({k: v for k, v in data.items() if k != "hydra"}, self.registry)  # as api.load
        except ConfigError as exc:
            return "invalid", exc.lines
        return "", []


def _settable(override: Any, plain: dict[str, Any]) -> bool:
    """A plain value (``a.b=v`` or ``++a.b=v``, v not a list or mapping) at a key that holds a plain
    value or, for ``++``, does not exist yet: setting it in the data is what Hydra does."""
    from hydra.core.override_parser.types import OverrideType

    if override.package is not None or override.type not in (OverrideType.CHANGE, OverrideType.FORCE_ADD):
        return False
    value = override.value()
    if isinstance(value, (dict, list)) or override.is_sweep_override():
        return False
    if isinstance(value, str) and "${" in value:  # an interpolation (environment.seed='${seed}'): the
        return False  # config resolves it, the data would keep its text
    node: Any = plain
    for part in override.key_or_group.split("."):
        if not isinstance(node, dict):
            return False
        if part not in node:
            return override.type == OverrideType.FORCE_ADD  # a plain change of a missing key: Hydra's error
        node = node[part]
    return not isinstance(node, (dict, list))


def _with_value(data: dict[str, Any], path: list[str], value: Any) -> dict[str, Any]:
    """``data`` with ``value`` at ``path``: the mappings along the path copied, the rest shared."""
    out = dict(data)
    out[path[0]] = value if len(path) == 1 else _with_value(data.get(path[0]) or {}, path[1:], value)
    return out


def shown(override: str) -> str:
    """An override as the user wrote it: the command line spells plain values ``++a.b=v``."""
    return override[2:] if override.startswith("++") else override


def _key(override: str) -> str:
    return override.partition("=")[0].lstrip("+~")


def _swept_keys(jobs: Sequence[Sequence[str]]) -> set[str]:
    """Keys with more than one value over the jobs (the job's own name for itself)."""
    values: dict[str, set[str]] = {}
    for job in jobs:
        for override in job:
            values.setdefault(_key(override), set()).add(override)
    return {k for k, v in values.items() if len(v) > 1}


class GridCheck:
    """The checks of one grid, job range by job range; an override checked once is not checked again.

    ``check(start, stop)`` raises ConfigError naming the job and the override when a checked job is
    invalid. With ``on_invalid="record"`` a job the schema rejects is only reported (one line on
    stderr): it will run, fail and be recorded; composition errors always stop the sweep.
    """

    def __init__(self, check: JobCheck, jobs: Sequence[Sequence[str]], validate: str = "each_value",
                 on_invalid: str = "stop") -> None:
        self.job_check = check
        self.jobs = jobs
        self.validate = validate
        self.on_invalid = on_invalid
        self.swept = _swept_keys(jobs)
        self.seen: set[str] = set()

    def distinct(self) -> int:
        """How many distinct overrides the grid holds."""
        return len({o for job in self.jobs for o in job})

    def check(self, start: int, stop: int) -> None:
        """Validate jobs ``start`` to ``stop - 1`` before they launch (``validate``: the jobs that
        bring a value not seen before, or every job): an invalid one stops the sweep with a
        ConfigError, one line per problem, or with ``on_invalid=record`` is announced and runs, to
        fail and be recorded."""
        from ..core.errors import ConfigError

        for index in range(start, min(stop, len(self.jobs))):
            overrides = self.jobs[index]
            if self.validate == "each_value":
                brought = [o for o in overrides if o not in self.seen]
                if not brought:
                    continue
                self.seen.update(brought)
                if index == 0:
                    brought = list(overrides)
            else:
                brought = list(overrides)
            kind, lines = self.job_check.problems(overrides)
            if not kind:
                continue
            named = [o for o in brought if _key(o) in self.swept] or list(brought)
            label = f"job {index} ({' '.join(shown(o) for o in named)})"
            if kind == "invalid" and self.on_invalid == "record":
                print(f"swarmscene: {label} will fail (on_invalid=record: it is recorded): {lines[0]}", file=sys.stderr)
                continue
            raise ConfigError([f"{label}: {line}" for line in lines])
