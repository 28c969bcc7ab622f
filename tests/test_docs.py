"""The docs cover every hook and every option, and the README's test command is what CI runs."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

from swarmscene.core import hookspecs
from swarmscene.tools.docgen import render

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
    assert (ROOT / "docs" / "options.md").read_text() == render(), "run: python -m swarmscene.tools.docgen docs/options.md"


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


# Text files that name benchmark paths (benchmarks/ is split into speed/ and reproduction/, issue
# #27); the engine's own docstrings and the scenario comments are left to the folders' owners.
BENCHMARK_PATH_SOURCES = ("README.md", "docs/*.md", "benchmarks/**/*.md", "benchmarks/**/*.py",
                          "benchmarks/**/*.yaml", "tests/**/*.py", "core/**/*.py", "methods/**/*.py",
                          "plugins/**/*.py", "swarmscene/**/*.py", "scenarios/**/*.yaml")


def _git_ignored(path: str) -> bool:
    """Whether ``path`` (or a folder above it) matches one of .gitignore's patterns: a generated
    output the scripts write (a peer's venv, results/), named but never committed."""
    from fnmatch import fnmatch

    patterns = [p.strip().rstrip("/") for p in (ROOT / ".gitignore").read_text().splitlines()
                if p.strip() and not p.startswith("#")]
    parts = path.rstrip("/").split("/")
    return any(fnmatch("/".join(parts[:k]), p) for k in range(1, len(parts) + 1) for p in patterns)


def test_every_benchmark_path_named_exists():
    """A path such as benchmarks/speed/bench_tick.py in the docs, a script's usage or a test names
    a file that is there (or a git-ignored output), so a moved script leaves no stale command."""
    named: dict[str, set[str]] = {}
    for pattern in BENCHMARK_PATH_SOURCES:
        for source in ROOT.glob(pattern):
            if _git_ignored(str(source.relative_to(ROOT))):  # a venv (the peers' .venv-mesa), an output
                continue
            for path in re.findall(r"benchmarks/[\w./-]*", source.read_text()):
                named.setdefault(path.rstrip("."), set()).add(str(source.relative_to(ROOT)))
    assert len(named) > 30
    missing = {p: sorted(s) for p, s in named.items() if not (ROOT / p).exists() and not _git_ignored(p)}
    assert not missing, missing


def test_git_ignored_check_reads_the_patterns():
    assert _git_ignored("benchmarks/speed/peers/.venv-mesa") and _git_ignored("benchmarks/results/all/x.log")
    old_place = "/".join(("benchmarks", "bench_tick.py"))  # joined, so the scan above does not read it
    assert not _git_ignored(old_place) and not _git_ignored("benchmarks/speed/bench_tick.py")


def test_each_benchmark_folder_readme_names_every_script():
    """benchmarks/speed/ and benchmarks/reproduction/ say in their README what each script is for."""
    for folder in ("speed", "reproduction"):
        readme = (ROOT / "benchmarks" / folder / "README.md").read_text()
        scripts = {p.name for p in (ROOT / "benchmarks" / folder).glob("*.py")}
        assert len(scripts) >= 8
        assert {s for s in scripts if f"`{s}`" not in readme} == set(), folder


def test_the_keys_docs_outputs_lists_as_always_present_are_in_every_runs_metrics():
    """docs/outputs.md's "Engine keys (always present)" table against a run's metrics.json: it
    listed `violations.*`, which a run writes only for a condition it violated."""
    import re

    from swarmscene import api

    text = (ROOT / "docs" / "outputs.md").read_text()
    table = text.split("Engine keys (always present):", 1)[1].split("\n\n", 2)[1]
    keys = re.findall(r"^\| `([^`]+)` \|", table, flags=re.M)
    assert "success" in keys and "wall_time" in keys
    metrics = api.run(["clock.duration=0.5", "output.summary=false"]).metrics
    assert sorted(k for k in keys if k not in metrics) == []
