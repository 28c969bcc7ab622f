"""The docs cover every hook and every option, and the README's test command is what CI runs."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

from swarmscene.core import hookspecs
from swarmscene.docgen import render

ROOT = Path(__file__).resolve().parents[1]


def test_every_hook_is_documented():
    hooks = {name for name, obj in inspect.getmembers(hookspecs, inspect.isfunction) if name.startswith("swarmscene_")}
    documented = set(re.findall(r"^### `(swarmscene_\w+)\(", (ROOT / "docs" / "hooks.md").read_text(), re.M))
    assert hooks == documented


def test_every_hook_has_a_docstring_saying_when():
    for name, obj in inspect.getmembers(hookspecs, inspect.isfunction):
        if name.startswith("swarmscene_"):
            assert "When:" in (obj.__doc__ or ""), name


def test_options_doc_is_current():
    assert (ROOT / "docs" / "options.md").read_text() == render(), "run: python -m swarmscene.docgen docs/options.md"


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    command = re.search(r'^TEST_COMMAND="(.+)"$', ci, re.M).group(1)
    assert command in readme


def test_every_benchmark_script_on_the_page_is_run_by_benchmarks_all():
    """docs/benchmarks.md's figures regenerate from one command (benchmarks/all.py): every
    benchmark script the page runs (in backticks or a code block) is run by one of its entries."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_all", ROOT / "benchmarks" / "all.py")
    bench_all = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_all)
    script = r"python (benchmarks/[\w/]+\.py)"
    run = {m for _, command, _ in bench_all.ENTRIES for m in re.findall(script, command)}
    page = (ROOT / "docs" / "benchmarks.md").read_text()
    code = re.findall(r"`([^`]+)`", page) + re.findall(r"```\w*\n(.*?)```", page, re.S)
    shown = {m for text in code for m in re.findall(script, text)}
    assert len(shown) > 10 and shown - {"benchmarks/all.py"} <= run, sorted(shown - run)
