"""The docs say what the registry does (issue #27): the error lines they quote are the engine's,
word for word, and they name the modules where things now live."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _line(overrides, registry=None):
    with pytest.raises(ConfigError) as err:
        api.load(overrides, registry)
    (line,) = err.value.lines
    return line


@pytest.mark.parametrize("doc, overrides", [
    ("rl.md", ["avoidance=policy", "avoidance.policy=nope"]),
    ("rl.md", ["avoidance=policy", "avoidance.policy=seek_reference", "avoidance.policy_options.speed=1"]),
])
def test_a_quoted_error_line_is_the_engines(doc, overrides):
    text = " ".join((DOCS / doc).read_text().split())  # quoted lines may wrap
    assert f"`{_line(overrides)}`" in text


def test_the_plugin_guide_quotes_the_line_for_a_parameter_of_another_generator():
    template = importlib.import_module("swarmscene.plugins.generator._template")
    _, registry = api.plugins()
    registry.register("generator", template.MyGenerator)
    line = _line(["environment=open", "environment.generator=my_generator", "environment.width=1.0"], registry)
    assert f"`{line}`" in " ".join((DOCS / "plugins.md").read_text().split())


def test_rl_docs_register_a_policy_through_the_hook_and_mark_the_old_group_deprecated():
    text = (DOCS / "rl.md").read_text()
    assert "def swarmscene_register_policies(register):" in text
    assert re.search(r"\*\*Deprecated: the entry-point group `swarmscene\.policies`\.\*\*", text)
    assert "avoidance: unknown policy" not in text  # the old message


def test_the_docs_name_where_validation_and_the_memory_check_live():
    guide = (DOCS / "guide.md").read_text()
    assert "`core/validation.py`" in guide and "`core/resources.py`" in guide
    for path in DOCS.glob("*.md"):
        for stale in ("DISTURBANCE_MODELS", "GENERATORS[", "GeneratorName"):
            assert stale not in path.read_text(), f"{path.name} names {stale}"
