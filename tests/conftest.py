"""Shared test setup: solutions of heartpole.optimum and JAX's compiled code are cached in temporary folders,
not the user's caches (another process writing the same cache at the same time, such as a second test run or
a training run, must not hand a test half-written entries); the optimum's folder is one for all of a run's xdist
workers, and the default cohort is solved into it by one worker at a time (`COHORT_TESTS`); ``terminal_signals``
for the tests that raise signals in the test process (tests/signal_dispositions.py says why)."""

import fcntl
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest


@pytest.fixture(autouse=True, scope="session")
def _private_caches(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Point ``HEARTPOLE_CACHE_DIR`` and ``HEARTPOLE_JAX_CACHE`` at session temporary folders unless the
    caller chose them, and ``SB3_LOGDIR`` at this worker's own: a test that calls SB3's ``learn`` gets SB3's
    default logger, which makes an empty ``SB3-<timestamp>/`` folder in the system's temporary folder otherwise
    (``stable_baselines3.common.logger.configure``)."""
    if "HEARTPOLE_CACHE_DIR" not in os.environ:
        # One folder for the run's xdist workers (their temporary folders share a parent): what one solved, the
        # others load. The optimum's cache writes atomically, so workers may share it, as CI's stages do.
        shared = tmp_path_factory.getbasetemp()
        if "PYTEST_XDIST_WORKER" in os.environ:
            shared = shared.parent
        os.environ["HEARTPOLE_CACHE_DIR"] = str(shared / "heartpole-cache")
        (shared / "heartpole-cache").mkdir(exist_ok=True)
    # The optimum's solve lock is taken where its folder exists: with it made now, two workers wanting one
    # solution (v0's, at the start) solve it once
    (Path(os.environ["HEARTPOLE_CACHE_DIR"]) / "optimum").mkdir(parents=True, exist_ok=True)
    if "HEARTPOLE_JAX_CACHE" not in os.environ:
        os.environ["HEARTPOLE_JAX_CACHE"] = str(tmp_path_factory.mktemp("heartpole-jax-cache"))
    if "SB3_LOGDIR" not in os.environ:
        os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3-logs"))


RAY_FILES = frozenset({"test_scale.py", "test_signals.py"})
"""Test files that start Ray: with pytest-xdist (``-n 2 --dist loadgroup``) they share one worker, so that
two local Ray clusters never start at once on a 2-core machine."""


COHORT_TESTS = (
    "test_docs_examples.py::test_the_examples_run[jax.md]",
    "test_docs_examples.py::test_the_examples_run[people.md]",
    "test_optimum_people.py::test_the_solver_covers_every_default_person",
    "test_train_people.py::test_a_tiny_training_run_under_people_writes_the_oracle_keys",
    "test_truth.py::test_the_default_population_oracle_and_expert",
)
"""Slow tests that need the optima of the default cohort of people on v0 (24 solves, about a minute on two
cores): they start once `default_cohort` has them in the run's optimum cache, so that two workers never solve the
same cohort side by side (each at half speed)."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Group the tests of `RAY_FILES` on one xdist worker."""
    for item in items:
        if item.path.name in RAY_FILES:
            item.add_marker(pytest.mark.xdist_group("ray"))


@pytest.fixture(autouse=True)
def _cohort_first(request: pytest.FixtureRequest) -> None:
    """`default_cohort` for the tests of `COHORT_TESTS`."""
    if request.node.nodeid.removeprefix("tests/").startswith(COHORT_TESTS):
        request.getfixturevalue("default_cohort")


@pytest.fixture(scope="session")
def default_cohort(_private_caches: None) -> None:
    """The default cohort's optima in the run's optimum cache: solved by the first worker to ask, under a lock in
    that cache folder; the others wait for it and then load them."""
    from heartpole.optimum import solve_people

    cache = Path(os.environ["HEARTPOLE_CACHE_DIR"])
    cache.mkdir(parents=True, exist_ok=True)
    with open(cache / ".default-cohort.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        solve_people("default")


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
