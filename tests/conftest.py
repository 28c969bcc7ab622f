"""Shared test setup: Hydra's search-path plugin registered in code (editable installs hide it)."""

from __future__ import annotations

import copy

import pytest

from swarmscene import api
from swarmscene.searchpath import register_search_path

register_search_path()


@pytest.fixture(scope="session")
def default_data() -> dict:
    """The default scenario, composed once per session (tests copy it before editing)."""
    return api.compose([])


@pytest.fixture
def data(default_data: dict) -> dict:
    return copy.deepcopy(default_data)
