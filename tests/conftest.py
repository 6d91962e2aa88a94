"""Shared test setup: solutions of heartpole.optimum and JAX's compiled code are cached in temporary folders,
not the user's caches (another process writing the same cache at the same time, such as a second test run or
a training run, must not hand a test half-written entries)."""

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _private_caches(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Point ``HEARTPOLE_CACHE_DIR`` and ``HEARTPOLE_JAX_CACHE`` at session temporary folders unless the
    caller chose them."""
    if "HEARTPOLE_CACHE_DIR" not in os.environ:
        os.environ["HEARTPOLE_CACHE_DIR"] = str(tmp_path_factory.mktemp("heartpole-cache"))
    if "HEARTPOLE_JAX_CACHE" not in os.environ:
        os.environ["HEARTPOLE_JAX_CACHE"] = str(tmp_path_factory.mktemp("heartpole-jax-cache"))
