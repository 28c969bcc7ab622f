"""docs/tutorial.md ("Your own scenario") as written: its files are the example files, and its
commands, run in order in a fresh folder, print what the page shows (issue #14, section 4).

The page's commands are read from its ```bash blocks and its files from the blocks introduced by
a line ending in `path`:, so the page cannot drift from what runs. ``pip install <dir>`` installs
into a private folder on PYTHONPATH (as tests/test_third_party_plugin.py does), never into the
test's environment.
"""

from __future__ import annotations

import csv
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "tutorial.md"
EXAMPLES = ROOT / "docs" / "examples"
FOLDER = "my_scenarios"
PACKAGE = "swarmscene-my-scenarios"

_BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
_FILE_INTRO = re.compile(r"`([\w./-]+\.\w+)`:\s*$")  # a file path, then a colon


@dataclass
class Command:
    line: str
    expected: list[str] = field(default_factory=list)  # lines the output shows, in order


def page_blocks() -> list[tuple[str, str, str]]:
    """(language, body, the last non-empty line before the block) of every fenced block."""
    text = TUTORIAL.read_text()
    blocks = []
    for match in _BLOCK.finditer(text):
        before = [line for line in text[: match.start()].splitlines() if line.strip()]
        blocks.append((match.group(1), match.group(2), before[-1] if before else ""))
    return blocks


def page_files() -> dict[str, str]:
    """Files the page shows in full: path (relative to the working folder) -> text."""
    files = {}
    for _, body, intro in page_blocks():
        named = _FILE_INTRO.search(intro)
        if named:
            files[named.group(1)] = body
    return files


def page_commands() -> list[Command]:
    """Commands of the ```bash blocks in order; a ```text block right after one shows the output
    of that block's last command."""
    commands: list[Command] = []
    previous = None
    for language, body, _ in page_blocks():
        if language == "bash":
            commands += [Command(line) for line in body.splitlines() if line.strip() and not line.startswith("#")]
        elif language == "text" and previous == "bash":
            commands[-1].expected = body.splitlines()
        previous = language
    return commands


def shows(output: str, expected: list[str]) -> bool:
    """Whether ``output`` has the ``expected`` lines in order; a line ``...`` skips any lines and a
    line ending in ``...`` matches any line starting with what precedes it."""
    lines = iter(output.splitlines())
    for want in expected:
        if want == "...":
            continue
        prefix = want[:-3] if want.endswith("...") else None
        if not any(line.startswith(prefix) if prefix is not None else line == want for line in lines):
            return False
    return True


def test_every_file_shown_is_the_example_file_and_every_example_file_is_shown():
    shown = page_files()
    on_disk = {
        p.relative_to(EXAMPLES).as_posix()
        for p in (EXAMPLES / FOLDER).rglob("*") if p.is_file()
    } | {f"{PACKAGE}/pyproject.toml"}
    assert set(shown) == on_disk
    for path, text in shown.items():
        assert (EXAMPLES / path).read_text() == text, f"docs/tutorial.md shows another {path}"


def test_page_runs_the_commands_it_teaches():
    lines = [c.line for c in page_commands()]
    assert lines[0] == f"swarmscene --config-dir {FOLDER} scenario=my_preset"
    assert any("--multirun" in line for line in lines)
    assert f"pip install ./{PACKAGE}" in lines
    assert lines[-1] == "swarmscene scenario=my_preset"  # installed: no --config-dir


@pytest.fixture(scope="module")
def walkthrough(tmp_path_factory) -> dict[str, subprocess.CompletedProcess]:
    """Every command of the page run in order in a fresh working folder holding what the page
    has the reader write by hand (the scenario folder, the package's pyproject.toml)."""
    work = tmp_path_factory.mktemp("lab")
    for path, text in page_files().items():
        (work / path).parent.mkdir(parents=True, exist_ok=True)
        (work / path).write_text(text)
    site = work.parent / f"{work.name}-site"
    env = {**os.environ, "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]])}
    env["PYTHONPATH"] = os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])
    for name in ("HYDRA_FULL_ERROR", "SWARMSCENE_DEBUG"):
        env.pop(name, None)
    results = {}
    for command in page_commands():
        argv = shlex.split(command.line)
        if argv[:2] == ["pip", "install"]:  # into a private folder, as test_third_party_plugin.py
            argv = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                    "--target", str(site), *argv[2:]]
            proc = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True, timeout=300)
        else:
            proc = subprocess.run(command.line, shell=True, cwd=work, env=env, capture_output=True,
                                  text=True, timeout=300)
        results[command.line] = proc
    results["work"] = work  # type: ignore[assignment]
    return results


REFUSED = {f"swarmscene --config-dir {FOLDER} scenario=my_preset formation=hex_lattice"}
"""The page's command that shows a refusal: exit status 2 and only the line the page shows."""


@pytest.mark.parametrize("command", page_commands(), ids=lambda c: c.line)
def test_command_prints_what_the_page_shows(walkthrough, command):
    proc = walkthrough[command.line]
    if command.line in REFUSED:
        assert proc.returncode == 2 and proc.stdout == ""
        assert proc.stderr.splitlines() == command.expected  # one line naming the key, no traceback
    else:
        assert proc.returncode == 0, proc.stderr
        assert shows(proc.stdout + proc.stderr, command.expected), proc.stdout + proc.stderr


def test_page_shows_its_refusal():
    assert REFUSED <= {c.line for c in page_commands()}


def test_packaging_commands_make_the_example_package(walkthrough):
    """The page's mkdir/cp/find give exactly docs/examples/swarmscene-my-scenarios (the reader's
    folder copied into a package, an __init__.py in every folder)."""
    made, example = walkthrough["work"] / PACKAGE, EXAMPLES / PACKAGE

    def tree(root: Path) -> dict[str, str]:
        files = {p.relative_to(root).as_posix(): p for p in root.rglob("*") if p.is_file()}
        return {
            name: path.read_text() for name, path in files.items()
            if not any(part == "build" or part == "__pycache__" or part.endswith(".egg-info")
                       for part in Path(name).parts)
        }

    assert tree(made) == tree(example)


def test_sweep_compares_the_methods_as_the_page_says(walkthrough):
    """CEM flies the aisle with no collision; none and potential do not (docs/tutorial.md, 5)."""
    with open(walkthrough["work"] / "multirun" / "my_preset" / "summary.csv", newline="") as fh:
        rows = {row["avoidance"]: row for row in csv.DictReader(fh)}
    assert set(rows) == {"none", "potential", "cem"}
    assert rows["cem"]["success"] == "True" and rows["cem"]["collisions"] == "0"
    for method in ("none", "potential"):
        assert rows[method]["success"] == "False" and int(rows[method]["collisions"]) >= 1
    for row in rows.values():
        assert row["healthy_at_end"] == "4"  # both failures applied


def test_installed_package_runs_the_preset_with_its_tuning(walkthrough):
    """After pip install the preset, its map, its events and its tuning come from the package."""
    import yaml

    runs = sorted((walkthrough["work"] / "outputs" / "my_preset").glob("*/config.yaml"))
    configs = [yaml.safe_load(p.read_text()) for p in runs]  # in the order they ran
    assert [c["avoidance"]["name"] for c in configs] == ["cem", "potential", "cem"]
    from_folder, _, installed = configs
    assert installed == from_folder
    cem = installed["avoidance"]
    assert (cem["name"], cem["direction"], cem["a_f"]) == ("cem", 0.0, 0.8)  # the preset's tuning
    assert installed["environment"]["name"] == "warehouse" and len(installed["events"]) == 2
    assert configs[1]["avoidance"].get("a_f") is None  # potential has no a_f: CEM's tuning stayed with CEM
