"""Limits on the YAML files a user hands the engine, checked before Hydra parses them.

A scenario file (a preset, a map, an experiment file under ``--config-dir``/``--config-path``, a
third-party package's options) is read by Hydra's config sources with ``OmegaConf.load``, which
has no limit: a YAML alias bomb (nine aliases of nine aliases ...) or a 50 MB scalar hangs it,
deep nesting overflows the parser's recursion, and non-UTF-8 bytes raise an error that does not
name the file. :func:`install` puts :func:`check_scenario_file` in front of both of Hydra's file
readers (``FileConfigSource`` and ``ImportlibResourcesConfigSource``, wrapped by
:mod:`swarmscene.composition.hydra_internals`), so every such file is checked first, and any problem is one
line naming the file (and the line, where there is one):

- size: at most :data:`MAX_FILE_BYTES` (checked before reading);
- text: UTF-8;
- structure: at most :data:`MAX_DEPTH` nested mappings/sequences and :data:`MAX_NODES` nodes
  once every alias is expanded (counted from the parser's events, without expanding anything);
- ``${oc.env:...}`` is refused: the resolved configuration is written to the run directory's
  ``config.yaml`` (and hashed), so an environment variable's value (a token, a password) would
  be persisted there. Give such a value on the command line if it is meant to be recorded.

The check costs one pass of PyYAML's event parser over the file (a few ms for a preset).
"""

from __future__ import annotations

import os
import re
from typing import Any

from ..core.errors import ConfigError

MAX_FILE_BYTES = 4 * 1024 * 1024
"""Largest scenario file read (bytes): the largest shipped one is a few KiB."""
MAX_NODES = 200_000
"""Most YAML nodes in a file once its aliases are expanded."""
MAX_DEPTH = 64
"""Deepest nesting of mappings and sequences."""
MAX_EXPANDED_BYTES = 4 * MAX_FILE_BYTES
"""Most bytes of scalar values in a file once its aliases are expanded (a long value aliased many
times stays under the node limit and the file's size, yet fills memory when the run's config.yaml
is written)."""
_REFUSED_RESOLVER = re.compile(r"\$\{\s*oc\.env\s*:")
"""``${oc.env:...}``, as OmegaConf's grammar reads it (spaces allowed after ``${`` and before ``:``)."""


def check_scenario_file(raw: bytes, where: str) -> None:
    """Raise ConfigError (one line starting with ``where``) when the file breaks a limit."""
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError([f"{where}: too large ({len(raw)} bytes; a scenario file holds at most {MAX_FILE_BYTES})"])
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError([f"{where}: not UTF-8 text (byte {exc.start}: {raw[exc.start:exc.start + 1]!r})"]) from None
    _check_structure(text, where)


def _check_structure(text: str, where: str) -> None:
    """Depth, expanded size (nodes and scalar bytes) and refused resolvers, from the parser's event
    stream (no recursion, no expansion: an alias adds the size its anchor was counted with)."""
    import yaml

    sizes: list[list[int]] = []  # [nodes, scalar bytes] in each open collection, its own included
    anchors_open: list[str | None] = []
    anchored: dict[str, tuple[int, int]] = {}  # anchor -> (nodes, scalar bytes) it stands for, expanded
    nodes = bytes_ = 0  # of the whole file, every alias expanded
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                if len(sizes) >= MAX_DEPTH:
                    _refuse(where, event, f"nested deeper than {MAX_DEPTH} levels")
                sizes.append([1, 0])
                anchors_open.append(event.anchor)
                nodes += 1
                continue
            if isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                (size, length), anchor = sizes.pop(), anchors_open.pop()
                if anchor is not None:
                    anchored[anchor] = (size, length)
                if sizes:  # counted in the file's totals already, node by node
                    sizes[-1][0] += size
                    sizes[-1][1] += length
                continue
            if isinstance(event, yaml.ScalarEvent):
                if _REFUSED_RESOLVER.search(event.value):
                    _refuse(where, event, "${oc.env:...} is refused in scenario files (its value would be "
                                          "written into the run's config.yaml); give the value on the command line")
                size, length = 1, len(event.value)
                if event.anchor is not None:
                    anchored[event.anchor] = (size, length)
            elif isinstance(event, yaml.AliasEvent):
                size, length = anchored.get(event.anchor, (1, 0))
            else:
                continue
            if sizes:
                sizes[-1][0] += size
                sizes[-1][1] += length
            nodes += size
            bytes_ += length
            if nodes > MAX_NODES:
                _refuse(where, event, f"expands to more than {MAX_NODES} nodes (YAML aliases of aliases?)")
            if bytes_ > MAX_EXPANDED_BYTES:
                _refuse(where, event,
                        f"expands to more than {MAX_EXPANDED_BYTES} bytes of values (YAML aliases of a long value?)")
    except yaml.YAMLError:
        return  # Hydra's own reading reports a syntax error with its file and line (hydra_errors)


def _refuse(where: str, event: Any, problem: str) -> None:
    mark = getattr(event, "start_mark", None)
    line = f":{mark.line + 1}" if mark is not None else ""
    raise ConfigError([f"{where}{line}: {problem}"])


def _read_limited(open_binary: Any) -> bytes:
    with open_binary() as fh:
        return fh.read(MAX_FILE_BYTES + 1)


def install() -> None:
    """Check every file Hydra's two file readers load (idempotent; the wrapping of Hydra's readers
    is :func:`swarmscene.composition.hydra_internals.check_before_config_files_are_read`)."""
    from .hydra_internals import check_before_config_files_are_read

    check_before_config_files_are_read(_check_file, _check_resource)


def _check_file(full: str) -> None:
    """The check of a file Hydra reads from a folder (``full``: its real path; absent: Hydra says so)."""
    if os.path.isfile(full):
        size = os.path.getsize(full)
        if size > MAX_FILE_BYTES:  # refused before a byte is read
            raise ConfigError([f"{full}: too large ({size} bytes; a scenario file holds at most {MAX_FILE_BYTES})"])
        check_scenario_file(_read_limited(lambda: open(full, "rb")), full)


def _check_resource(res: Any) -> None:
    """The check of a file Hydra reads from a package (``res``: its ``importlib.resources`` resource)."""
    if res.is_file():
        check_scenario_file(_read_limited(lambda: res.open("rb")), str(res))
