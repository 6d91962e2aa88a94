"""Shared test setup: solutions of heartpole.optimum are cached in a temporary folder, not the user's cache."""

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _optimum_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Point ``HEARTPOLE_CACHE_DIR`` at a session temporary folder unless the caller chose one."""
    if "HEARTPOLE_CACHE_DIR" not in os.environ:
        os.environ["HEARTPOLE_CACHE_DIR"] = str(tmp_path_factory.mktemp("heartpole-cache"))
