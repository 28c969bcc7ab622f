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


def test_every_benchmark_command_on_the_page_is_run_by_benchmarks_all():
    """docs/benchmarks.md's figures regenerate from one command (benchmarks/all.py): each
    benchmark script invocation on the page (in backticks or a code block) is one of its entries."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_all", ROOT / "benchmarks" / "all.py")
    bench_all = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_all)
    listed = {command for _, command, _ in bench_all.ENTRIES} | set(bench_all.EXAMPLES)
    page = (ROOT / "docs" / "benchmarks.md").read_text()
    pattern = r"((?:[A-Z_]+=\S+ |taskset -c \d )*python benchmarks/[\w/]+\.py(?: --?[\w-]+| [\w.]+)*)"
    shown = {m.strip() for m in re.findall(r"`" + pattern + r"`", page)}
    shown |= {m.strip() for block in re.findall(r"```\w*\n(.*?)```", page, re.S)
              for line in block.splitlines() for m in re.findall(r"^" + pattern, line.split("#")[0].strip())}
    assert shown and shown <= listed, sorted(shown - listed)
