"""Ray Tune, quietly: the Ray session, one progress bar for a whole run of trials, and failed trials as one
line each. The seeds (`heartpole.scale.seeds`) and the search
(`heartpole.scale.search`) run their trials through these."""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from heartpole import files
from heartpole.progress import Progress

RAY_EXTRA = "pip install 'heartpole[ray]'"
"""How to install what this package needs (Ray Tune, Optuna, Stable-Baselines3)."""

try:
    import ray
    from ray import tune
except ImportError as error:  # pragma: no cover - the CLI checks for the modules first
    raise ImportError(f"heartpole.scale needs Ray Tune: {RAY_EXTRA}") from error

if TYPE_CHECKING:
    from ray.tune.experiment import Trial


@dataclass(frozen=True)
class TrialFailure:
    """A trial that raised: what it was (``"seed 3"``, ``"trial 7"``) and the exception's last line."""

    label: str
    error: str

    def line(self) -> str:
        """One line for the summary."""
        return f"{self.label} failed: {self.error}"

    def to_dict(self) -> dict[str, str]:
        """JSON-safe."""
        return {"trial": self.label, "error": self.error}


class AllTrialsFailedError(RuntimeError):
    """Every trial failed, so there is nothing to aggregate; ``failures`` says why."""

    def __init__(self, failures: Sequence[TrialFailure]) -> None:
        super().__init__("; ".join(f.line() for f in failures))
        self.failures = list(failures)


class SearchInterruptedError(KeyboardInterrupt):
    """The search stopped (Ctrl-C) before all its trials finished; its state is saved for ``resume``."""


@contextmanager
def ray_session(address: str | None = None, num_cpus: int | None = None) -> Iterator[None]:
    """Start local Ray (``address=None``, on ``num_cpus`` CPUs or all) or join a cluster, without noise.

    No dashboard, Ray's loggers at ERROR, and the workers' output not forwarded (a trial's error reaches
    the summary through Tune instead). Shuts Ray down at the end only if this call started it, so an
    already running session (a notebook's, a test's) is reused as it is.
    """
    if ray.is_initialized():
        yield
        return
    with files.signal_handlers_kept():  # not Ray's SIGTERM handler (exit status 1, no cleanup of ours)
        ray.init(address=address, num_cpus=num_cpus if address is None else None, include_dashboard=False,
                 logging_level=logging.ERROR, log_to_driver=False)  # fmt: skip
    try:
        yield
    finally:
        with files.signals_deferred():  # the workers end before anything cleans up after them
            ray.shutdown()


@contextmanager
def quiet_tune() -> Iterator[None]:
    """Tune, quiet: its legacy reporter at verbosity 0 prints nothing; its controller logs a traceback per
    failed trial, which `TrialFailure` replaces by one line; no
    TensorBoard/CSV/JSON logger files."""
    saved = {k: os.environ.get(k) for k in ("RAY_AIR_NEW_OUTPUT", "TUNE_DISABLE_AUTO_CALLBACK_LOGGERS")}
    os.environ.update(RAY_AIR_NEW_OUTPUT="0", TUNE_DISABLE_AUTO_CALLBACK_LOGGERS="1")
    logger = logging.getLogger("ray")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


class TrialsBar(tune.Callback):
    """One progress bar for a whole Tune run: trials done / total and the best figure so far.

    ``on_result`` is called in the driver with each finished trial's reported metrics.
    """

    def __init__(
        self, total: int, label: str, metric: str, on_result: Callable[[dict[str, Any]], None] | None = None
    ) -> None:
        self.total, self.label, self.metric, self.on_result = total, label, metric, on_result
        self.done, self.failed, self.best = 0, 0, -math.inf
        self.bar = Progress(total, self._describe())

    def __getstate__(self) -> dict[str, Any]:
        # Tune pickles its run configuration (callbacks included) into the experiment state; the bar's
        # stream cannot be pickled and means nothing to a restored run, which gets a new bar.
        return {"total": self.total, "label": self.label, "metric": self.metric}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["total"], state["label"], state["metric"])  # type: ignore[misc]

    def _describe(self) -> str:
        best = f"{self.best:.3f}" if math.isfinite(self.best) else "-"
        failed = f", {self.failed} failed" if self.failed else ""
        return f"{self.label} {self.done}/{self.total}{failed}, best expected-risk return {best}"

    def on_trial_complete(self, iteration: int, trials: list[Trial], trial: Trial, **info: Any) -> None:
        """A trial finished: pass its result on, redraw."""
        result = dict(trial.last_result or {})
        if self.on_result is not None and result:
            self.bar.clear()  # for whatever on_result prints
            self.on_result(result)
        self._redraw(trials, trial, failed=False)

    def on_trial_error(self, iteration: int, trials: list[Trial], trial: Trial, **info: Any) -> None:
        """A trial raised: redraw with it counted as failed."""
        self._redraw(trials, trial, failed=True)

    def _redraw(self, trials: list[Trial], current: Trial, failed: bool) -> None:
        # Count from all trials, so that a restored search starts from the trials it had finished.
        others = [t for t in trials if t is not current]
        self.failed = int(failed) + sum(t.status == "ERROR" for t in others)
        self.done = 1 + sum(t.status in ("TERMINATED", "ERROR") for t in others)
        figures = [t.last_result[self.metric] for t in trials if t.last_result and self.metric in t.last_result]
        self.best = max(figures, default=-math.inf)
        self.bar.description = self._describe()
        self.bar.done = self.done - 1
        self.bar.update(1)

    def close(self) -> None:
        """End the bar's line."""
        self.bar.close()


def failure(result: tune.Result, label: str) -> TrialFailure:
    """The one-line failure of a Tune ``Result`` whose trial raised."""
    error = result.error
    cause = getattr(error, "cause", None) or error
    text = " ".join(f"{type(cause).__name__}: {cause}".split())
    return TrialFailure(label, text if len(text) <= 300 else text[:297] + "...")


def fit(tuner: tune.Tuner, bar: TrialsBar) -> list[tune.Result]:
    """Run ``tuner``; its results in Tune's order (a ``ResultGrid`` is indexed, its stubs declare no iterator)."""
    with quiet_tune(), files.signals_as_ctrl_c():  # SIGTERM, SIGHUP: Tune stops its trials as on Ctrl-C
        try:
            grid = tuner.fit()
        finally:
            bar.close()
    return [grid[index] for index in range(len(grid))]


def run_config(storage: Path, name: str, bar: TrialsBar) -> tune.RunConfig:
    """Tune's run configuration: state under ``storage/name``, silent, ``bar`` as the only callback, and no
    retries (a failed trial is reported, the others go on)."""
    return tune.RunConfig(
        storage_path=str(storage),
        name=name,
        verbose=0,
        callbacks=[bar],
        failure_config=tune.FailureConfig(max_failures=0, fail_fast=False),
    )
