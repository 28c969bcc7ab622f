"""swarmscene.composition.scenario_files: the limits on the YAML files a user hands the engine (size, UTF-8,
nesting, alias expansion, no ${oc.env:...}), each refusal one line naming the file, checked in
front of Hydra's own readers (a --config-dir file, a packaged preset) before anything is parsed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from swarmscene.composition import scenario_files
from swarmscene.composition.scenario_files import MAX_DEPTH, MAX_FILE_BYTES, MAX_NODES, check_scenario_file
from swarmscene.core.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]
HEADER = "# @package _global_\n"


def alias_bomb(levels: int = 9, width: int = 9) -> str:
    """The billion laughs in YAML: level k holds `width` aliases of level k - 1."""
    lines = [f"a0: &a0 [{', '.join(['lol'] * width)}]"]
    lines += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * width)}]" for k in range(1, levels)]
    return HEADER + "\n".join(lines) + "\n"


def refusal(text: str | bytes) -> str:
    raw = text.encode() if isinstance(text, str) else text
    with pytest.raises(ConfigError) as info:
        check_scenario_file(raw, "my.yaml")
    assert len(info.value.lines) == 1
    return info.value.lines[0]


def test_an_alias_bomb_is_refused_from_the_events_without_expanding():
    # 9 ** 9 = 387 million strings once expanded; counted, never built: refused at level 6 (9 ** 6 > MAX_NODES)
    assert refusal(alias_bomb()) == f"my.yaml:7: expands to more than {MAX_NODES} nodes (YAML aliases of aliases?)"


def test_a_few_aliases_are_fine_and_count_what_they_stand_for():
    check_scenario_file((HEADER + "base: &b {x: 1, y: 2}\none: *b\ntwo: *b\n").encode(), "my.yaml")
    width = 500  # 500 aliases of 500 scalars: 250,500 nodes expanded
    text = HEADER + f"a: &a [{', '.join(['1'] * width)}]\nb: [{', '.join(['*a'] * width)}]\n"
    assert refusal(text).startswith(f"my.yaml:3: expands to more than {MAX_NODES} nodes")


def test_size_utf8_depth_and_oc_env_each_name_the_file():
    assert refusal(b"x" * (MAX_FILE_BYTES + 1)) == \
        f"my.yaml: too large ({MAX_FILE_BYTES + 1} bytes; a scenario file holds at most {MAX_FILE_BYTES})"
    assert refusal(HEADER.encode() + b"description: caf\xe9\n") == "my.yaml: not UTF-8 text (byte 36: b'\\xe9')"
    assert refusal(HEADER + "x: " + "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1) + "\n") == \
        f"my.yaml:2: nested deeper than {MAX_DEPTH} levels"
    inner = MAX_DEPTH - 1  # the file's own mapping is the first level
    check_scenario_file((HEADER + "x: " + "[" * inner + "]" * inner + "\n").encode(), "my.yaml")
    assert refusal(HEADER + "name: ok\ndescription: token ${oc.env:SECRET}\n") == (
        "my.yaml:3: ${oc.env:...} is refused in scenario files (its value would be written into the run's "
        "config.yaml); give the value on the command line")


def test_a_syntax_error_is_left_to_hydras_own_line():
    check_scenario_file((HEADER + "swarm: {n: [1, 2\n").encode(), "my.yaml")  # no exception here


def test_every_shipped_config_file_is_within_the_limits():
    files = sorted((ROOT / "scenarios").rglob("*.yaml"))
    assert len(files) > 50
    for path in files:
        check_scenario_file(path.read_bytes(), str(path))


@pytest.mark.parametrize("name, content, line", [
    ("bomb", alias_bomb(), "bomb.yaml:7: expands to more than 200000 nodes (YAML aliases of aliases?)"),
    ("huge", None, "huge.yaml: too large (52428834 bytes; a scenario file holds at most 4194304)"),
    ("secret", HEADER + "description: ${oc.env:SWARMSCENE_TEST_SECRET}\n",
     "secret.yaml:2: ${oc.env:...} is refused in scenario files"),
    ("latin1", (HEADER + "description: caf\xe9\n").encode("latin-1"), "latin1.yaml: not UTF-8 text (byte 36"),
])
def test_the_command_line_refuses_a_hostile_config_dir_file_in_one_line(tmp_path, name, content, line):
    """A --config-dir scenario: one line naming the file, exit 2, no run directory, no secret."""
    scenario = tmp_path / "conf" / "scenario"
    scenario.mkdir(parents=True)
    path = scenario / f"{name}.yaml"
    if content is None:  # a 50 MB scalar, written without holding 50 MB of text twice
        with open(path, "w") as fh:
            fh.write(HEADER + "description: ")
            for _ in range(50):
                fh.write("x" * 1024 * 1024)
            fh.write("\n")
    else:
        path.write_bytes(content.encode() if isinstance(content, str) else content)
    env = {**os.environ, "SWARMSCENE_TEST_SECRET": "hunter2"}
    env.pop("HYDRA_FULL_ERROR", None)
    proc = subprocess.run([*EXE, "--config-dir", str(tmp_path / "conf"), f"scenario={name}", "clock.duration=0.1",
                           f"hydra.run.dir={tmp_path}/run"], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 2
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"swarmscene: {path.parent}/{line}"), err
    assert not (tmp_path / "run").exists() and "hunter2" not in proc.stdout + proc.stderr


def test_install_checks_hydras_readers_once():
    from hydra._internal.core_plugins.file_config_source import FileConfigSource

    from swarmscene.composition.searchpath import register_search_path

    register_search_path()
    first = FileConfigSource.load_config
    scenario_files.install()
    assert FileConfigSource.load_config is first and first._swarmscene_checked


@pytest.mark.parametrize("spelling", ["${ oc.env:SECRET}", "${oc.env :SECRET}", '${oc.decode:"${ oc.env:SECRET}"}'])
def test_oc_env_is_refused_however_the_grammar_lets_it_be_spelt(spelling):
    assert refusal(HEADER + f"description: {spelling}\n").startswith("my.yaml:2: ${oc.env:...} is refused")


def test_a_resolver_that_only_starts_like_oc_env_is_left_alone():
    check_scenario_file((HEADER + "description: ${oc.envelope:x}\n").encode(), "my.yaml")


def test_a_long_value_aliased_many_times_is_refused_by_its_expanded_bytes():
    from swarmscene.composition.scenario_files import MAX_EXPANDED_BYTES

    value = "x" * (1024 * 1024)  # 1 MiB, anchored once: the file stays under its size limit
    aliases = "\n".join("  - *v" for _ in range(MAX_EXPANDED_BYTES // len(value) + 1))
    text = HEADER + f"description: &v {value}\nlist:\n{aliases}\n"
    line, _, problem = refusal(text).removeprefix("my.yaml:").partition(": ")
    assert problem == f"expands to more than {MAX_EXPANDED_BYTES} bytes of values (YAML aliases of a long value?)"
    assert 4 <= int(line) <= text.count("\n")  # on one of the aliases, the one that crossed the limit
