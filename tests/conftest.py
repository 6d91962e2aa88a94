"""Shared test setup: solutions of heartpole.optimum and JAX's compiled code are cached in temporary folders,
not the user's caches (another process writing the same cache at the same time, such as a second test run or
a training run, must not hand a test half-written entries); ``terminal_signals`` for the tests that raise signals
in the test process (tests/signal_dispositions.py says why)."""

import os
import signal
from collections.abc import Iterator

import pytest


@pytest.fixture(autouse=True, scope="session")
def _private_caches(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Point ``HEARTPOLE_CACHE_DIR`` and ``HEARTPOLE_JAX_CACHE`` at session temporary folders unless the
    caller chose them."""
    if "HEARTPOLE_CACHE_DIR" not in os.environ:
        os.environ["HEARTPOLE_CACHE_DIR"] = str(tmp_path_factory.mktemp("heartpole-cache"))
    if "HEARTPOLE_JAX_CACHE" not in os.environ:
        os.environ["HEARTPOLE_JAX_CACHE"] = str(tmp_path_factory.mktemp("heartpole-jax-cache"))


RAY_FILES = frozenset({"test_scale.py", "test_signals.py"})
"""Test files that start Ray: with pytest-xdist (``-n 2 --dist loadgroup``) they share one worker, so that
two local Ray clusters never start at once on a 2-core machine."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Group the tests of `RAY_FILES` on one xdist worker."""
    for item in items:
        if item.path.name in RAY_FILES:
            item.add_marker(pytest.mark.xdist_group("ray"))


@pytest.fixture
def terminal_signals() -> Iterator[None]:
    """SIGINT raising ``KeyboardInterrupt``, SIGTERM and SIGHUP at their defaults, as in a terminal, for a test that
    raises them in its own process, whatever the run inherited (``nohup``, a background job); put back afterwards."""
    from tests.signal_dispositions import SIGNALS

    before = {signum: signal.getsignal(signum) for signum in SIGNALS}
    for signum in SIGNALS:
        signal.signal(signum, signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL)
    yield
    for signum, handler in before.items():
        signal.signal(signum, handler)
