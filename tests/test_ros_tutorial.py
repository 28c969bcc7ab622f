"""docs/tutorial.md, section 7 ("In ROS tools, and a flown show back in") as written: its ```sh
commands, run in order in a fresh folder, succeed and print what the page shows (the ```text block
after each, with the tutorial's ``...`` rules), and leave the files it names."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from .test_tutorial import shows  # the tutorial test's rule: lines in order, ``...`` skips

ROOT = Path(__file__).resolve().parents[1]
SECTION = "## 7. In ROS tools, and a flown show back in"
_BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def section_commands() -> list[tuple[str, list[str]]]:
    """(command, the lines the page shows after the block that ends with it) in page order."""
    text = (ROOT / "docs" / "tutorial.md").read_text()
    text = text[text.index(SECTION):].split("\n## ", 1)[0]
    commands: list[tuple[str, list[str]]] = []
    previous = None
    for match in _BLOCK.finditer(text):
        language, body = match.group(1), match.group(2)
        if language == "sh":
            commands += [(line, []) for line in body.splitlines() if line.strip()]
        elif language == "text" and previous == "sh":
            commands[-1] = (commands[-1][0], body.splitlines())
        previous = language
    return commands


@pytest.fixture(scope="module")
def walkthrough(tmp_path_factory):
    work = tmp_path_factory.mktemp("ros_lab")
    env = {**os.environ, "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]])}
    for name in ("HYDRA_FULL_ERROR", "SWARMSCENE_DEBUG"):
        env.pop(name, None)
    results = {}
    for line, _ in section_commands():
        results[line] = subprocess.run(line, shell=True, cwd=work, env=env, capture_output=True, text=True,
                                       timeout=600)
    return work, results


def test_the_section_runs_a_bag_out_and_a_recording_back_in():
    lines = [line for line, _ in section_commands()]
    assert any("output.mcap=true" in line for line in lines)
    assert any("--mcap" in line for line in lines)
    assert any("formation=recorded formation.bag=runs/six/bag" in line for line in lines)
    assert lines[-1].startswith("swarmscene scenario=recorded_flight")


@pytest.mark.parametrize("command", section_commands(), ids=lambda c: c[0])
def test_command_prints_what_the_page_shows(walkthrough, command):
    line, expected = command
    proc = walkthrough[1][line]
    assert proc.returncode == 0, proc.stderr
    assert shows(proc.stdout + proc.stderr, expected), proc.stdout + proc.stderr


def test_the_replayed_show_flew_the_recording(walkthrough):
    work = walkthrough[0]
    import numpy as np

    recorded = np.load(work / "runs" / "six" / "trajectory.npz")
    replayed = np.load(work / "runs" / "six_orca" / "trajectory.npz")
    assert replayed["pos"].shape[1] == recorded["pos"].shape[1] == 6
    # agent 0 hovered in the recording from its failure at 2 s: replayed, it holds near there
    at = np.searchsorted(recorded["t"], 10.0)
    assert np.linalg.norm(replayed["pos"][np.searchsorted(replayed["t"], 10.0), 0] - recorded["pos"][at, 0]) < 0.5
