"""The tasks of a suite version and the hash each version is frozen under.

A task is a file of the ``task`` config group (``scenarios/task/<id>.yaml``): a scenario (presets,
groups, values) plus its ``task`` section (:class:`swarmscene.core.task.TaskConfig`). Its
*definition* is its composition, method-free: what ``swarmscene task=<id>`` composes, resolved,
without the ``avoidance`` node (the method under test) and the ``seed`` (the task lists its own).
A version's hash is the SHA-256 of the canonical JSON (sorted keys) of ``{id: definition}`` over
its tasks. ``<version>.json`` beside this module freezes a version: its hash, and each task's
definition with its own hash. Runs are scored against the frozen definitions, and
``tests/test_suite.py`` fails when the composition of a frozen version no longer gives them, so v1
cannot change silently: a changed task is a new version
(``python -m swarmscene.suite.definition v2`` writes the record of a new one).

Canonical form (:func:`canonical`): a definition is hashed, frozen and compared with a run's
``config.yaml`` with each event's and each disturbance model's plugin name keyed ``kind``, and the
start layout ``swarm.start.kind``, as v1 was frozen, whichever key the task file or the run record
spells it with (``name``, ``kind`` until 0.6.0; ``layout``, ``kind`` until 0.7.0:
:mod:`swarmscene.core.spelling`). The spelling is not part of what a task means: the new
one leaves v1's hashes as they were, and a run recorded either way holds the same definition.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from functools import cache
from importlib.resources import files
from typing import Any, cast

from ..core.spelling import canonical_names

SUITE = "swarmscene-bench"
"""The suite's name, as every task's ``task.suite`` says and a citation names it."""
CURRENT = "v1"
"""The newest frozen version."""
METHOD_FREE = ("avoidance", "seed")
"""Left out of a task's definition: the method under test and the run's seed."""
TASK_GROUP = "task"
"""The config group of the tasks (``scenarios/task/``)."""

VERSIONS = ("v1",)
"""The frozen versions (each a ``<version>.json`` beside this module)."""


def task_files() -> list[str]:
    """The ids of every file of the ``task`` group shipped with the engine, sorted."""
    folder = files("swarmscene.scenarios").joinpath(TASK_GROUP)
    return sorted(p.name[: -len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml"))


@cache
def _composed(task_id: str) -> str:
    """``task=<id>`` composed (JSON, so the cache hands out fresh copies)."""
    from ..composition.compose import compose

    return json.dumps(compose([f"{TASK_GROUP}={task_id}"]), sort_keys=True)


def composed(task_id: str) -> dict[str, Any]:
    """``swarmscene task=<id>`` composed and resolved, as plain data."""
    return json.loads(_composed(task_id))


def canonical(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a composition, a definition or a run's config) in the canonical form every
    definition is hashed and compared in: each event's and disturbance model's plugin name, and the
    start layout, keyed ``kind`` (the module docstring; :func:`~swarmscene.core.spelling.canonical_names`)."""
    return cast("dict[str, Any]", canonical_names(data))


def definition(task_id: str) -> dict[str, Any]:
    """A task's definition: its composition without :data:`METHOD_FREE`, in :func:`canonical` form."""
    data = canonical(composed(task_id))
    return {k: v for k, v in data.items() if k not in METHOD_FREE}


def tasks(version: str = CURRENT) -> list[str]:
    """The ids of a version's tasks (the task files whose ``task.version`` is it), sorted."""
    return [t for t in task_files() if (composed(t).get("task") or {}).get("version") == version]


def digest(data: Any) -> str:
    """SHA-256 of the canonical JSON of ``data`` (sorted keys, no whitespace)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()


def version_hashes(task_ids: Iterable[str]) -> dict[str, Any]:
    """``{"sha256": <hash of every definition>, "tasks": {id: <hash of its definition>}}``."""
    defs = {t: definition(t) for t in task_ids}
    return {"sha256": digest(defs), "tasks": {t: digest(d) for t, d in defs.items()}}


def record(version: str) -> dict[str, Any]:
    """The record that freezes ``version`` as its tasks compose now: the suite, the version, its
    hash, and each task's definition and hash."""
    ids = tasks(version)
    defs = {t: definition(t) for t in ids}
    return {"suite": SUITE, "version": version, "sha256": digest(defs),
            "tasks": {t: {"sha256": digest(d), "definition": d} for t, d in defs.items()}}


@cache
def _frozen_text(version: str) -> str:
    if version not in VERSIONS:
        raise ValueError(f"suite version {version!r} is not frozen (valid: {', '.join(VERSIONS)})")
    return files(__package__).joinpath(f"{version}.json").read_text()


def frozen(version: str = CURRENT) -> dict[str, Any]:
    """The frozen record of ``version`` (:func:`record`'s shape), as shipped."""
    return cast("dict[str, Any]", json.loads(_frozen_text(version)))


def changed_tasks(version: str) -> list[str]:
    """The tasks of a frozen version whose definition no longer has its frozen hash (added,
    removed or edited), sorted; empty when the version composes as it was frozen."""
    was = {t: v["sha256"] for t, v in frozen(version)["tasks"].items()}
    now = version_hashes(tasks(version))["tasks"]
    return sorted(t for t in set(was) | set(now) if was.get(t) != now.get(t))


def main(argv: list[str] | None = None) -> None:
    """Write ``<version>.json`` beside this module from the tasks as they compose now; refused for
    a version already frozen (a changed task is a new version)."""
    import sys
    from pathlib import Path

    version = (argv if argv is not None else sys.argv[1:] or [""])[0]
    if not version or version in VERSIONS:
        raise SystemExit(f"usage: python -m swarmscene.suite.definition NEW_VERSION (frozen: {', '.join(VERSIONS)})")
    path = Path(__file__).with_name(f"{version}.json")
    path.write_text(json.dumps(record(version), indent=1, sort_keys=True) + "\n")
    print(f"wrote {path}; add {version!r} to VERSIONS")


if __name__ == "__main__":
    main()
