"""A Python file outside any package (a docs example, a benchmark script, an example plugin) loaded
as a module, for the tests that exercise it (``tests/`` is on pytest's ``pythonpath``)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType


def load(name: str, path: Path) -> ModuleType:
    """The file at ``path`` executed as module ``name``, registered in ``sys.modules`` first:
    dataclasses and pickle look a class's module up there while the file runs."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None, path
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
