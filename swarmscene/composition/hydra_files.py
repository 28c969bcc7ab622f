"""What Hydra writes, and where: kept inside the run directory, never through a planted link.

Two things Hydra does on its own before the engine's task runs:

- it makes the run (or job) directory from ``hydra.run.dir`` / ``hydra.sweep.dir``, patterns that
  hold the scenario's ``name`` (``outputs/${swarmscene.dir_name:${name}}/...``). The resolver
  ``swarmscene.dir_name`` (:func:`dir_name`) refuses a name that is not one plain directory name
  (``name=../../x``, ``name=a/b``, ``name=.x``) with one line, before any directory is made: a
  name is refused, never rewritten, so a directory's name is the scenario's name.
- it writes ``.hydra/config.yaml``, ``hydra.yaml`` and ``overrides.yaml`` with a plain ``open(path,
  "w")``, which follows a symbolic link planted at that name. :func:`protect_hydra_writes`
  makes Hydra write them with :func:`save_config` instead (the replacement of Hydra's private
  writer is :func:`swarmscene.composition.hydra_internals.replace_save_config`), which writes through a
  private temporary file and ``os.replace`` (a link at the name is replaced, not written through)
  and refuses a run directory or ``.hydra`` that is itself a link.

:func:`install` does both; it is idempotent and cheap, and runs on importing
:mod:`swarmscene.cli` (so a launcher's worker process, which imports the task to run it, has it
too) and in :func:`swarmscene.composition.searchpath.register_search_path`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

RESOLVER = "swarmscene.dir_name"


def dir_name(name: Any) -> str:
    """The scenario ``name`` as a directory name, or a ConfigError naming ``name`` (one line)."""
    from ..core.config import name_problem
    from ..core.errors import ConfigError

    problem = name_problem(name)
    if problem is not None:
        raise ConfigError([f"name: {problem} (got {name!r})"])
    return str(name)


def save_config(cfg: Any, filename: str, output_dir: Path) -> None:
    """Hydra's ``_save_config``, written atomically and never through a symbolic link."""
    from omegaconf import OmegaConf

    from ..runs.outputs import atomic_write_bytes
    from ..runs.rundir import RunFileError

    output_dir = Path(output_dir)
    for directory in (output_dir.parent, output_dir):
        if directory.is_symlink():
            raise RunFileError(
                directory, "is a symbolic link (refused: Hydra's records are written inside the run directory)")
    output_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(output_dir / filename, OmegaConf.to_yaml(cfg).encode("utf-8"))


def protect_hydra_writes() -> None:
    """Replace Hydra's ``.hydra/`` writer with :func:`save_config` (idempotent)."""
    from .hydra_internals import replace_save_config

    replace_save_config(save_config)


def register_dir_name_resolver() -> None:
    """Make the ``dir_name`` resolver known to OmegaConf (once: registering twice is an error)."""
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver(RESOLVER):
        OmegaConf.register_new_resolver(RESOLVER, dir_name)


def install() -> None:
    """Both protections (module docstring)."""
    protect_hydra_writes()
    register_dir_name_resolver()
