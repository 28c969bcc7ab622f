"""The README's group table (python -m swarmscene.tools.docgen --groups) and ``swarmscene --help``'s
group list come from the config tree, so no choice goes unlisted."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from swarmscene.composition import groups

ROOT = Path(__file__).resolve().parents[1]


def test_readme_group_table_is_current():
    readme = (ROOT / "README.md").read_text()
    assert groups.readme_groups() in readme, "run: python -m swarmscene.tools.docgen --groups"


def test_every_group_of_the_defaults_list_is_documented():
    from omegaconf import OmegaConf

    primary = OmegaConf.load(ROOT / "scenarios" / "config.yaml")
    chosen = set()
    for entry in primary.defaults:
        if isinstance(entry, str):
            continue
        (key,) = entry.keys()
        if not key.startswith(("optional ", "override ")):
            chosen.add(key)
    assert chosen | {"sweep"} == {group for group, _ in groups.GROUPS}


def test_group_options_are_the_yaml_files_of_the_folder():
    assert groups.group_options("dynamics") == ["double_integrator", "quadrotor", "single_integrator"]
    assert "falsify_failure" in groups.group_options("sweep")


def test_help_is_short_and_lists_no_internal_groups():
    from conftest import builtins_only_env

    out = subprocess.run([sys.executable, "-c", "from swarmscene.cli import main; main()", "--help"], capture_output=True, text=True,
                         timeout=120, cwd=ROOT, env=builtins_only_env())  # whatever else is installed here
    assert out.returncode == 0, out.stderr
    assert "tuning/" not in out.stdout
    assert groups.help_groups(groups.group_options) in out.stdout  # built-ins, no third party here
    assert len(out.stdout.splitlines()) < 40


def test_the_help_group_list_is_resolved_once_per_search_path(tmp_path, monkeypatch):
    """OmegaConf resolves the help template at every composition that merges over it: the list is
    made once per search path (a config folder added by a third party gives a new one)."""
    from hydra import initialize_config_dir, initialize_config_module

    made: list[int] = []
    monkeypatch.setattr(groups, "help_groups", lambda options: made.append(1) or f"list {len(made)}")
    monkeypatch.setattr(groups, "_HELP_GROUPS", {})
    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"):
        first, again = groups.installed_help_groups(), groups.installed_help_groups()
    (tmp_path / "swarm").mkdir()
    (tmp_path / "swarm" / "mine.yaml").write_text("n: 3\n")
    with initialize_config_dir(config_dir=str(tmp_path), version_base="1.3"):
        other = groups.installed_help_groups()
    assert (first, again, other) == ("list 1", "list 1", "list 2")


def test_the_help_groups_are_listed_once_per_search_path(monkeypatch):
    """The help template's ``${swarmscene_groups:}`` is resolved by every composition (a merge looks
    through it); its list is made once for a search path, not once per composition (each has a new
    search path object: keyed by that object, the list was made again and kept, every time)."""
    from swarmscene import api

    monkeypatch.setattr(groups, "_HELP_GROUPS", {})
    made = []
    real = groups.help_groups
    monkeypatch.setattr(groups, "help_groups", lambda options: made.append(1) or real(options))
    for _ in range(3):
        api.compose(["scenario=swap"])
    assert len(made) == 1 and len(groups._HELP_GROUPS) == 1
    assert "scenario: " in next(iter(groups._HELP_GROUPS.values()))
