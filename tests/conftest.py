"""Shared test setup: Hydra's search-path plugin registered in code (editable installs hide it), the
default scenario composed once, and an environment for Ray processes isolated from the user's."""

from __future__ import annotations

import copy
import os
import secrets
from pathlib import Path

import pytest

from swarmscene import api
from swarmscene.composition.searchpath import register_search_path

register_search_path()

END_TO_END = (
    "test_sweep_launchers.py", "test_sweeps.py", "test_sweep_safety.py", "test_faults.py", "test_mlflow.py",
    "test_tutorial.py", "test_third_party_plugin.py", "test_reproduction.py", "test_composition.py",
    "test_inputs_property.py", "test_cli.py", "test_api.py", "test_falsify.py", "test_export.py",
    "test_replay.py", "test_plots.py", "test_report.py", "test_compile.py", "test_packaging.py",
    "test_rl_train.py", "test_rl_supersuit.py", "test_live.py", "test_export_crazyswarm2.py", "test_export_cflib.py",
    "test_sweep_pool.py", "test_sweep_tasks.py", "test_lint.py", "test_ros_tutorial.py", "test_suite_third_party.py",
    "test_batch.py", "test_recorded_spelling.py",
)
"""Test modules that run whole commands, sweeps, clusters, installs, whole preset runs (test_batch.py:
every preset, batched and alone) or the linters and type checker (ruff and mypy over the whole
package: test_lint.py): left out by ``--quick``."""


def builtins_only_env() -> dict[str, str]:
    """``os.environ`` for a subprocess that must see the built-in plugins and config tree only:
    every installed third-party entry point (plugins and config folders, such as the tutorial's
    package a user installed in the same environment) named in ``SWARMSCENE_DISABLE_PLUGINS``."""
    from importlib.metadata import entry_points

    from swarmscene.core.registry import CONF_ENTRY_POINT_GROUP, DISABLE_ENV, ENTRY_POINT_GROUP

    names = sorted({f"{ep.dist.name if ep.dist is not None else 'unknown'}:{ep.name}"
                    for group in (ENTRY_POINT_GROUP, CONF_ENTRY_POINT_GROUP) for ep in entry_points(group=group)})
    env = {**os.environ}
    if names:
        env[DISABLE_ENV] = ",".join(filter(None, [env.get(DISABLE_ENV, ""), *names]))
    return env


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--quick", action="store_true",
        help="the quick tier: unit and contract tests, without the end-to-end modules (conftest.END_TO_END)",
    )


def pytest_collection_finish(session: pytest.Session) -> None:
    """absl (rliable's logging, imported by test_suite.py) makes a stream handler at import, bound
    to the stream sys.stderr is then: pytest's capture. Hydra's in-process logging set-up closes
    every handler, so a later in-process run closed pytest's own stderr and the session died
    ("lost sys.stderr"). The handler is pointed at the process's stderr, which absl never closes."""
    import sys

    absl_logging = sys.modules.get("absl.logging")
    if absl_logging is not None:
        absl_logging.get_absl_handler().python_handler.setStream(sys.__stderr__)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if not config.getoption("--quick"):
        return
    kept = [item for item in items if item.path.name not in END_TO_END]
    deselected = [item for item in items if item.path.name in END_TO_END]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = kept


@pytest.fixture(scope="session")
def default_data() -> dict:
    """The default scenario, composed once per session (tests copy it before editing)."""
    return api.compose([])


@pytest.fixture
def data(default_data: dict) -> dict:
    return copy.deepcopy(default_data)


@pytest.fixture
def ray_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """A complete environment for Ray processes that does not depend on this machine's past.

    ``HOME`` is a fresh folder holding what an earlier local Ray run leaves behind: since Ray 2.5x
    ``ray.init()`` without an address writes ``~/.ray/auth_token``, and a later ``ray start --head``
    finding it requires token authentication (tested with Ray 2.60.0). None of the caller's
    ``RAY_*`` variables (an address, an auth mode, a token) is passed on. Every Ray service stays on
    the loopback interface (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``; Linux defaults to the host's
    address) and no usage statistics are sent.
    """
    home = Path(tmp_path_factory.mktemp("home"))
    (home / ".ray").mkdir()
    (home / ".ray" / "auth_token").write_text(secrets.token_hex(32))  # as ray.init() writes it
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    env.update(HOME=str(home), RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER="0", RAY_USAGE_STATS_ENABLED="0")
    return env
