"""swarmscene's grid sweeper: Hydra's basic sweeper that checks the whole sweep before launching.

Before the first job starts, the sweep is checked as a whole, so that a mistake stops it at once
with one line instead of showing up as a failed job half-way through:

1. its directory: a sweep directory belongs to one grid (``sweep.json`` records the jobs' overrides);
   launching a different grid into it is refused with one line naming both (a re-run of the same
   grid resumes it: jobs already complete for the same config are skipped);
2. every distinct override of the grid, numbers included, is composed *and* validated by the
   engine's schema (``swarmscene.api.load``) in the first job that has it. In Hydra's grid order
   that job is the first job with only this one override changed, so the line names the job and
   the override: ``job 1 (avoidance.K=0): avoidance.K: must be >= 1 (got 0)``.

It stays fast because composition is the expensive part (~0.1 s for this config tree; Hydra's own
basic sweeper composes every job up front, hydra#1324): config-group overrides (``scenario=...``)
are composed once per distinct set, and plain values (``seed=17``, ``avoidance.K=0``) are set in
that composed config's data the way Hydra sets them (in a copy of the config itself when it holds
interpolations, or for ``+``/``~`` overrides and lists), then validated (a few ms each). The
thesis corridor sweep (5 widths x 30 seeds) composes 5 configs and validates 34 jobs up front.

Options (``hydra.sweeper.*``), besides the basic sweeper's ``params`` and ``max_batch_size``:

- ``validate``: ``each_value`` (above) or ``all`` (every job composed and validated);
- ``on_invalid``: ``stop`` (the default) or ``record``: a job the schema rejects is launched anyway
  and recorded as failed with its error (``error.json``), for comparisons in which some
  combinations are known not to apply (``+sweep=methods``); a composition error (an unknown option
  or key) still stops the sweep;
- ``cases``: a list of override lists taken together rather than crossed (Hydra's grid is a
  product only): the jobs are every case times the product of ``params``. A key given on the
  command line that a case also sets replaces the cases (the command line picks the grid).

Selected with ``hydra/sweeper=swarmscene`` (the grid presets in ``scenarios/sweep`` do). With
Hydra's basic sweeper, the summary callback (:class:`swarmscene.sweep.SweepSummary`) makes the
same checks at the start of the multirun.
"""

from __future__ import annotations

import copy
import itertools
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hydra.plugins.sweeper import Sweeper

VALIDATE = ("each_value", "all")
ON_INVALID = ("stop", "record")


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
    line reads its overrides (``swarmscene.searchpath.plain_overrides``); Hydra's basic sweeper
    does not, so its check passes False.
    """
    lines = [f"{k}={v}" for k, v in (params or {}).items()]
    if plain_params:
        from swarmscene.searchpath import plain_overrides

        lines = plain_overrides(lines)  # as the command line's: `a.b: 1,2` sets a.b, default or not
    parsed = parser.parse_overrides([*lines, *arguments])
    final: dict[str, Any] = {}
    for override in parsed:
        final[override.get_key_element()] = override
    values = []
    for key, override in final.items():
        if override.is_sweep_override():
            if not override.is_discrete_sweep():
                from swarmscene.core.errors import ConfigError

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
        from swarmscene.searchpath import plain_overrides

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

        from swarmscene import api

        self.loader = config_loader
        self.master = master
        self.parser = OverridesParser.create(config_loader=config_loader)
        self.registry = api.plugins()[1]
        self.composed: dict[tuple[str, ...], Any] = {}

    def _is_group(self, override: Any) -> bool:
        return override.package is not None or self.loader.repository.group_exists(override.key_or_group)

    def data(self, overrides: Sequence[str]) -> dict[str, Any]:
        """The job's composed config as plain data (no ``hydra`` node), as the job will see it."""
        from hydra._internal.config_loader_impl import ConfigLoaderImpl
        from omegaconf import OmegaConf, open_dict

        parsed = self.parser.parse_overrides(list(overrides))
        groups = tuple(o.input_line for o in parsed if self._is_group(o))
        values = [o for o in parsed if not self._is_group(o)]
        cfg, plain = self._compose(groups)
        if plain is not None and all(_settable(o, plain) for o in values):
            data = plain
            for override in values:
                data = _with_value(data, override.key_or_group.split("."), override.value())
            return data
        cfg = copy.deepcopy(cfg)
        # Hydra applies the overrides that are not config-group choices to the composed config.
        ConfigLoaderImpl._apply_overrides_to_config(values, cfg)
        with open_dict(cfg):
            del cfg["hydra"]
        return OmegaConf.to_container(cfg, resolve=True)

    def _compose(self, groups: tuple[str, ...]) -> tuple[Any, dict[str, Any] | None]:
        """The config composed with these config-group overrides (once), and its plain data when
        it holds no interpolation (then a plain value is set in the data directly, exactly as
        Hydra would set it in the config, for a fraction of the cost of copying the config)."""
        from omegaconf import OmegaConf

        if groups not in self.composed:
            cfg = self.loader.load_sweep_config(self.master, list(groups))
            task = {k: v for k, v in OmegaConf.to_container(cfg, resolve=False).items() if k != "hydra"}
            self.composed[groups] = (cfg, None if "${" in repr(task) else task)
        return self.composed[groups]

    def problems(self, overrides: Sequence[str]) -> tuple[str, list[str]]:
        """(``"compose"`` or ``"invalid"`` or ``""``, the problem lines) of one job."""
        from swarmscene import api
        from swarmscene.core.errors import ConfigError
        from swarmscene.hydra_errors import hydra_error_line

        try:
            data = self.data(overrides)
        except Exception as exc:  # Hydra's composition errors, reworded
            return "compose", [hydra_error_line(exc) or " ".join(f"{type(exc).__name__}: {exc}".split())]
        try:
            api.load(data, self.registry)
        except ConfigError as exc:
            return "invalid", exc.lines
        return "", []


def _settable(override: Any, plain: dict[str, Any]) -> bool:
    """A plain value (``a.b=v`` or ``++a.b=v``, v not a list or mapping) at a key that holds a plain
    value or, for ``++``, does not exist yet: setting it in the data is what Hydra does."""
    from hydra.core.override_parser.types import OverrideType

    if override.package is not None or override.type not in (OverrideType.CHANGE, OverrideType.FORCE_ADD):
        return False
    if isinstance(override.value(), (dict, list)) or override.is_sweep_override():
        return False
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


def check_jobs(
    check: JobCheck, jobs: Sequence[Sequence[str]], validate: str = "each_value", on_invalid: str = "stop"
) -> None:
    """Raise ConfigError naming the job and the override when a checked job is invalid.

    With ``on_invalid="record"`` a job the schema rejects is only reported (one line on stderr):
    it will run, fail and be recorded; composition errors always stop the sweep.
    """
    from swarmscene.core.errors import ConfigError

    swept = _swept_keys(jobs)
    chosen = jobs_to_validate(jobs) if validate == "each_value" else [(i, list(j)) for i, j in enumerate(jobs)]
    for index, brought in chosen:
        kind, lines = check.problems(jobs[index])
        if not kind:
            continue
        named = [o for o in brought if _key(o) in swept] or list(brought)
        label = f"job {index} ({' '.join(shown(o) for o in named)})"
        if kind == "invalid" and on_invalid == "record":
            print(f"swarmscene: {label} will fail (on_invalid=record: it is recorded): {lines[0]}", file=sys.stderr)
            continue
        raise ConfigError([f"{label}: {line}" for line in lines])


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


def prepare(
    config_loader: Any, master: Any, sweep_dir: Path, grid: list[str], jobs: list[list[str]],
    validate: str = "each_value", on_invalid: str = "stop",
) -> None:
    """Everything before the first launch: the directory's grid, the jobs' check, the record."""
    from swarmscene import sweep

    sweep.check_grid_owner(sweep_dir, grid, jobs)
    check_jobs(JobCheck(config_loader, master), jobs, validate, on_invalid)
    sweep.record_grid(sweep_dir, grid, jobs)


# -- the sweeper ------------------------------------------------------------------------------
class SwarmsceneSweeper(Sweeper):
    """Hydra's basic sweeper (grid, ``max_batch_size``) with the checks of the module docstring.

    It uses Hydra's launcher plugins unchanged (basic, joblib, Ray, submitit).
    """

    def __init__(
        self,
        max_batch_size: int | None,
        params: dict[str, str] | None = None,
        validate: str = "each_value",
        on_invalid: str = "stop",
        cases: Sequence[Sequence[str]] | None = None,
    ) -> None:
        if validate not in VALIDATE:
            raise ValueError(f"hydra.sweeper.validate: must be one of {VALIDATE} (got {validate!r})")
        if on_invalid not in ON_INVALID:
            raise ValueError(f"hydra.sweeper.on_invalid: must be one of {ON_INVALID} (got {on_invalid!r})")
        if max_batch_size is not None and max_batch_size != -1 and max_batch_size < 1:
            raise ValueError(f"hydra.sweeper.max_batch_size: must be >= 1, -1 or null (got {max_batch_size})")
        self.max_batch_size = None if max_batch_size == -1 else max_batch_size
        self.params = dict(params or {})
        self.validate = validate
        self.on_invalid = on_invalid
        self.cases = [list(case) for case in (cases or [])]
        self.config: Any = None
        self.hydra_context: Any = None
        self.launcher: Any = None

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        from hydra.core.plugins import Plugins

        self.config = config
        self.hydra_context = hydra_context
        self.launcher = Plugins.instance().instantiate_launcher(
            hydra_context=hydra_context, task_function=task_function, config=config
        )

    def sweep(self, arguments: list[str]) -> Any:
        from hydra.core.override_parser.overrides_parser import OverridesParser
        from omegaconf import OmegaConf

        loader = self.hydra_context.config_loader
        parser = OverridesParser.create(config_loader=loader)
        grid, jobs = expand(self.params, arguments, parser, self.cases)
        sweep_dir = Path(self.config.hydra.sweep.dir)
        prepare(loader, self.config, sweep_dir, grid, jobs, self.validate, self.on_invalid)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")  # as Hydra's basic sweeper does
        size = self.max_batch_size or max(len(jobs), 1)
        returns = []
        for start in range(0, len(jobs), size):
            results = self.launcher.launch(jobs[start : start + size], initial_job_idx=start)
            for result in results:
                _ = result.return_value  # re-raises what ended a job (a Ctrl-C)
            returns.append(results)
        return returns


def register() -> None:
    """Make Hydra know the sweeper (its scan of ``hydra_plugins`` misses editable installs)."""
    from hydra.core.plugins import Plugins

    plugins = Plugins.instance()
    if SwarmsceneSweeper not in plugins.class_name_to_class.values():
        plugins.register(SwarmsceneSweeper)
