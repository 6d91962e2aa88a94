"""Beyond one machine: the seeds of ``heartpole train`` and hyperparameter searches as Ray Tune trials.

This module needs the optional ``ray`` extra (``pip install 'heartpole[ray]'``: Ray Tune, Optuna and the
``train`` extra); it is the only module that imports Ray, and ``import heartpole`` never imports it.

* :func:`train_seeds_ray` runs one Ray Tune trial per seed. Each trial calls
  :func:`heartpole.training.train_run`, exactly as ``heartpole train --seeds`` does one after another, and
  writes the same files to ``<folder>/seed_<s>/``; the summary is :func:`heartpole.training.seeds_summary`'s
  (interquartile mean across seeds with a bootstrap interval). Same seed, same settings, same results.
* :func:`tune_search` searches hyperparameters with Optuna (Ray Tune's ``OptunaSearch``) over
  :func:`default_space`; each trial trains ``seeds_per_trial`` seeds with
  :func:`heartpole.training.train_seeds` and evaluates them with the standard protocol; the objective is
  the interquartile mean over those seeds of the expected-risk return (the score is reported beside it).
  The search keeps Ray Tune's experiment state in its output folder, so an interrupted search resumes.

Ray runs locally when no address is given (``ray.init()`` on this machine's cores) and joins a cluster
with ``address`` (``"auto"`` or ``"ray://host:10001"``). Ray's start-up messages, dashboard, Tune's tables
and loggers are all switched off; progress is one bar (trials done / total and the best figure so far).
A trial that raises is reported as one :class:`TrialFailure` line and the others go on.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import logging
import math
import os
import re
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from heartpole import files, training
from heartpole.progress import Progress

RAY_EXTRA = "pip install 'heartpole[ray]'"
"""How to install what this module needs (Ray Tune, Optuna, Stable-Baselines3)."""

try:
    import ray
    from ray import tune
except ImportError as error:  # pragma: no cover - the CLI checks for the modules first
    raise ImportError(f"heartpole.scale needs Ray Tune: {RAY_EXTRA}") from error

if TYPE_CHECKING:
    from ray.tune.experiment import Trial

OBJECTIVE = "objective"
SEARCH_NAME = "search"
SEARCH_SETTINGS_FILE = "search.json"
TRIALS_FILE = "trials.csv"
PRESET_FILE = "best_preset.json"
PLOT_FILE = "search.png"
TUNE_SUMMARY_FILE = "tune_summary.json"
SEARCHABLE = ("ppo", "a2c")
TIMINGS = ("wall_seconds", "cpu_seconds")
"""A trial's timings, summed over its seeds: the wall time of its runs and their CPU time."""
"""Algorithms with a default search space (DQN has neither ``n_steps`` nor ``ent_coef``)."""


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
    """Every trial failed, so there is nothing to aggregate; :attr:`failures` says why."""

    def __init__(self, failures: Sequence[TrialFailure]) -> None:
        super().__init__("; ".join(f.line() for f in failures))
        self.failures = list(failures)


class SearchInterruptedError(KeyboardInterrupt):
    """The search stopped (Ctrl-C) before all its trials finished; its state is saved for ``resume``."""


# ------------------------------------------------------------------------------------------------------
# Ray, quietly


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
def _quiet_tune() -> Iterator[None]:
    """Tune's legacy reporter at verbosity 0 prints nothing; its controller logs a traceback per failed
    trial, which :class:`TrialFailure` replaces by one line; no TensorBoard/CSV/JSON logger files."""
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


class _Bar(tune.Callback):
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
            if self.bar.enabled:  # clear the bar's line for whatever on_result prints
                self.bar.stream.write("\r\x1b[K")
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


def _failure(result: tune.Result, label: str) -> TrialFailure:
    """The one-line failure of a Tune ``Result`` whose trial raised."""
    error = result.error
    cause = getattr(error, "cause", None) or error
    text = " ".join(f"{type(cause).__name__}: {cause}".split())
    return TrialFailure(label, text if len(text) <= 300 else text[:297] + "...")


def _fit(tuner: tune.Tuner, bar: _Bar) -> list[tune.Result]:
    """Run ``tuner``; its results in Tune's order (a ``ResultGrid`` is indexed, its stubs declare no iterator)."""
    with _quiet_tune(), files.signals_as_ctrl_c():  # SIGTERM, SIGHUP: Tune stops its trials as on Ctrl-C
        try:
            grid = tuner.fit()
        finally:
            bar.close()
    return [grid[index] for index in range(len(grid))]


def _run_config(storage: Path, name: str, bar: _Bar) -> tune.RunConfig:
    return tune.RunConfig(
        storage_path=str(storage),
        name=name,
        verbose=0,
        callbacks=[bar],
        failure_config=tune.FailureConfig(max_failures=0, fail_fast=False),
    )


# ------------------------------------------------------------------------------------------------------
# seeds


def _seed_trial(
    params: Mapping[str, Any],
    *,
    config: training.TrainConfig,
    folder: str,
    eval_episodes: int,
    eval_seed: int,
    final_folder: str | None,
    threads: int,
) -> None:
    """A Ray Tune trial: :func:`heartpole.training.train_run` for ``params["seed"]``, reported to Tune."""
    import torch

    torch.set_num_threads(threads)
    seed = int(params["seed"])
    run = training.train_run(
        replace(config, seed=seed),
        Path(folder) / f"seed_{seed}",
        eval_episodes=eval_episodes,
        eval_seed=eval_seed,
        final_folder=Path(final_folder) / f"seed_{seed}" if final_folder is not None else None,
    )
    # Tune flattens nested metrics (intervals, the solved bar): the whole summary travels as JSON beside the
    # plain numbers the progress bar reads.
    numbers = {key: value for key, value in run.items() if isinstance(value, (int, float, bool))}
    tune.report({**numbers, "run": json.dumps(run, allow_nan=False)})


def _run_of(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """A trial's reported metrics back as :func:`heartpole.training.run_summary`'s dict."""
    run: dict[str, Any] = json.loads(metrics["run"])
    return run


def train_seeds_ray(
    config: training.TrainConfig,
    seeds: Sequence[int],
    folder: str | os.PathLike[str],
    *,
    eval_episodes: int = 2000,
    eval_seed: int = 0,
    address: str | None = None,
    num_cpus: int | None = None,
    cpus_per_trial: int = 1,
    final_folder: str | os.PathLike[str] | None = None,
    on_run: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """:func:`heartpole.training.train_seeds` with each seed a Ray Tune trial; same files, same summary.

    ``folder`` is made absolute (trials run in Ray's own working directories, and on a cluster it must
    be a path every node shares). Each trial gets ``cpus_per_trial`` CPUs and as many PyTorch threads;
    with one (the default, and what ``heartpole train`` uses) a seed's results equal the sequential run's.
    ``summary.json`` lists failed seeds under ``"failed"``, and the aggregate is over the seeds that ran.

    Raises:
        AllTrialsFailedError: every seed failed (nothing is aggregated or written).
        KeyboardInterrupt: a signal (Ctrl-C, SIGTERM, SIGHUP) stopped the trials; Tune stops them first.
    """
    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"give distinct seeds, got {seeds}")
    if cpus_per_trial < 1:
        raise ValueError(f"cpus_per_trial must be >= 1, got {cpus_per_trial}")
    folder = Path(folder).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    trainable = tune.with_resources(
        tune.with_parameters(
            _seed_trial,
            config=config,
            folder=str(folder),
            eval_episodes=eval_episodes,
            eval_seed=eval_seed,
            final_folder=None if final_folder is None else str(final_folder),
            threads=cpus_per_trial,
        ),
        {"cpu": cpus_per_trial},
    )
    bar = _Bar(len(seeds), "seeds", "expected_return", None if on_run is None else lambda m: on_run(_run_of(m)))
    with tempfile.TemporaryDirectory(prefix="heartpole-tune-") as storage, ray_session(address, num_cpus):
        tuner = tune.Tuner(
            trainable,
            param_space={"seed": tune.grid_search(seeds)},
            run_config=_run_config(Path(storage), "seeds", bar),
        )
        grid = _fit(tuner, bar)
        runs, failures = {}, []
        for result in grid:
            if result.error is None and "expected_return" not in (result.metrics or {}):
                raise files.interruption()  # Tune stopped the trial before it finished: a signal
            seed = int((result.config or {})["seed"])
            if result.error is not None:
                failures.append(_failure(result, f"seed {seed}"))
            else:
                runs[seed] = _run_of(result.metrics or {})
    if not runs:
        raise AllTrialsFailedError(failures)
    summary = training.seeds_summary(
        config, seeds, [runs[s] for s in seeds if s in runs], eval_episodes=eval_episodes, eval_seed=eval_seed
    )
    if failures:
        summary["failed"] = [f.to_dict() for f in sorted(failures, key=lambda f: seeds.index(int(f.label[5:])))]
    files.write_json(folder / training.SUMMARY_FILE, summary)
    return summary


# ------------------------------------------------------------------------------------------------------
# hyperparameter search


def default_space(algo: str = "ppo") -> dict[str, Any]:
    """The default search space of ``algo`` (``ppo`` or ``a2c``), as Ray Tune distributions.

    ======================  =============================================  ==============================
    parameter               range                                          why
    ======================  =============================================  ==============================
    ``learning_rate``       log-uniform 1e-5 .. 3e-3                       the usual PPO/A2C range
    ``ent_coef``            log-uniform 1e-4 .. 0.1                        exploration while unlearning drinks
    ``gamma``               uniform 0.90 .. 0.999                          a day is ~17 decisions
    ``n_steps``             PPO 32, 64, 128, 256, 512; A2C 5, 8, 16, 32    rollout length per env
    ``net_width``           16, 32, 64, 128, 256                           hidden units per layer ...
    ``net_depth``           1, 2, 3                                        ... and layers (``net_arch``)
    ======================  =============================================  ==============================

    Everything else (reward, normalisation, batch size, epochs, ``n_envs``) is the default preset's.
    """
    if algo not in SEARCHABLE:
        raise ValueError(f"no default search space for {algo!r}; choose one of {', '.join(SEARCHABLE)}")
    return {
        "learning_rate": tune.loguniform(1e-5, 3e-3),
        "ent_coef": tune.loguniform(1e-4, 0.1),
        "gamma": tune.uniform(0.90, 0.999),
        "n_steps": tune.choice([32, 64, 128, 256, 512] if algo == "ppo" else [5, 8, 16, 32]),
        "net_width": tune.choice([16, 32, 64, 128, 256]),
        "net_depth": tune.choice([1, 2, 3]),
    }


def apply_params(base: training.TrainConfig, params: Mapping[str, Any]) -> training.TrainConfig:
    """``base`` with a trial's parameters: ``net_width``/``net_depth`` make ``net_arch``; the rest are
    the algorithm's hyperparameters (``n_steps`` as an integer)."""
    params = dict(params)
    width = int(params.pop("net_width", base.net_arch[0]))
    depth = int(params.pop("net_depth", len(base.net_arch)))
    hyperparameters = dict(base.hyperparameters)
    for key, value in params.items():
        hyperparameters[key] = int(value) if key == "n_steps" else float(value)
    return replace(base, net_arch=(width,) * depth, hyperparameters=hyperparameters)


def _search_trial(
    params: Mapping[str, Any],
    *,
    base: training.TrainConfig,
    seeds: Sequence[int],
    folder: str,
    eval_episodes: int,
    eval_seed: int,
    threads: int,
) -> None:
    """A Ray Tune trial of the search: train ``seeds`` with ``params``, report the objective."""
    import torch

    torch.set_num_threads(threads)
    config = apply_params(base, params)
    trial = tune.get_context().get_trial_id()
    summary = training.train_seeds(
        config, seeds, Path(folder) / "trials" / trial, eval_episodes=eval_episodes, eval_seed=eval_seed
    )
    aggregate = summary["aggregate"]
    tune.report(
        {
            OBJECTIVE: aggregate["expected_return"]["iqm"],
            "score": aggregate["score"]["iqm"],
            "heart_attacks_per_episode": aggregate["heart_attacks_per_episode"]["iqm"],
            "mean_return": aggregate["mean_return"]["iqm"],
            "solved_seeds": summary["solved_seeds"],
            "wall_seconds": sum(run["wall_seconds"] for run in summary["runs"]),
            **training.cpu_total(summary["runs"]),
        }
    )


@dataclass(frozen=True)
class SearchSettings:
    """What a search depends on, saved as ``search.json`` so that a resumed search runs the same trials."""

    base: training.TrainConfig
    trials: int
    seeds: tuple[int, ...]
    eval_episodes: int = 2000
    eval_seed: int = 0
    search_seed: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe."""
        return {
            "base": self.base.to_dict(),
            "trials": self.trials,
            "seeds": list(self.seeds),
            "eval_episodes": self.eval_episodes,
            "eval_seed": self.eval_seed,
            "search_seed": self.search_seed,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SearchSettings:
        """The inverse of :meth:`to_dict`."""
        values = dict(data)
        values["base"] = training.TrainConfig.from_dict(values["base"])
        values["seeds"] = tuple(int(s) for s in values["seeds"])
        return cls(**values)


def can_resume(folder: str | os.PathLike[str]) -> bool:
    """Whether ``folder`` holds a search that :func:`tune_search` can resume."""
    folder = Path(folder).resolve()
    return (folder / SEARCH_SETTINGS_FILE).is_file() and tune.Tuner.can_restore(str(folder / SEARCH_NAME))


def prepare_search_folder(folder: str | os.PathLike[str], resume: bool = False, force: bool = False) -> Path:
    """Check, before any trial runs, that a search may run in ``folder``; return it as an absolute ``Path``.

    With ``resume`` it must hold a search to continue. Otherwise it must be missing or empty, or, with
    ``force``, hold an earlier search (its :data:`SEARCH_SETTINGS_FILE`), which :func:`tune_search` replaces
    once the new search is done: ``force`` never removes anything else.

    Raises:
        ValueError: ``resume`` with ``force``, nothing to resume, a file in the way, a non-empty folder
            without ``force``, or with ``force`` a folder that holds no search.
    """
    out = Path(folder).resolve()
    if resume:
        if force:
            raise ValueError("--resume continues the search in --out and --force replaces it: give one")
        if not can_resume(out):
            raise ValueError(f"--resume: no search to continue in {out}")
        return out
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file, not a folder")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise ValueError(f"--out {out} is not empty; pass --resume to continue its search or --force to replace")
        if not (out / SEARCH_SETTINGS_FILE).is_file():
            raise ValueError(f"--out {out} holds no search ({SEARCH_SETTINGS_FILE}); refusing to replace it")
    return out


def read_settings(folder: str | os.PathLike[str]) -> SearchSettings:
    """The settings of the search in ``folder``."""
    return SearchSettings.from_dict(json.loads((Path(folder) / SEARCH_SETTINGS_FILE).read_text()))


def tune_search(
    settings: SearchSettings,
    folder: str | os.PathLike[str],
    *,
    resume: bool = False,
    force: bool = False,
    space: Mapping[str, Any] | None = None,
    points_to_evaluate: Sequence[Mapping[str, Any]] | None = None,
    address: str | None = None,
    num_cpus: int | None = None,
    cpus_per_trial: int = 1,
) -> dict[str, Any]:
    """Search hyperparameters with Optuna on Ray Tune; write the results into ``folder``; return them.

    ``folder`` (made absolute) receives ``search.json`` (the settings), ``search/`` (Ray Tune's experiment
    state: what :func:`can_resume` and ``resume=True`` use), ``trials/<trial id>/`` (each trial's
    :func:`heartpole.training.train_seeds` output), and at the end ``trials.csv`` (one row per trial),
    ``best_preset.json`` (the best configuration, for ``heartpole train --preset``), ``search.png`` (the
    objective per trial, when matplotlib is installed) and ``tune_summary.json``.

    ``space`` defaults to :func:`default_space`; ``points_to_evaluate`` are tried first (Optuna enqueues
    them). With ``resume``, the settings saved in ``folder`` are used and ``settings`` is ignored; finished
    trials are kept, unfinished ones rerun, failed ones stay failed. ``folder`` is checked by
    :func:`prepare_search_folder`; ``force`` replaces an earlier search once the new one is done.

    Raises:
        AllTrialsFailedError: every trial failed (``tune_summary.json`` and ``trials.csv`` are still written).
        SearchInterruptedError: a signal stopped the search; it stays in ``folder`` to resume.
        KeyboardInterrupt: a signal stopped it before it could resume, or with ``force``: ``folder`` is as it was.
    """
    import optuna
    from ray.tune.search.optuna import OptunaSearch

    optuna.logging.set_verbosity(optuna.logging.WARNING)  # not "A new study created in memory"
    folder = prepare_search_folder(folder, resume, force)
    earlier = not resume and folder.is_dir() and any(folder.iterdir())
    if resume:
        settings = read_settings(folder)
    base = settings.base
    trainable = tune.with_resources(
        tune.with_parameters(
            _search_trial,
            base=base,
            seeds=list(settings.seeds),
            folder=str(folder),
            eval_episodes=settings.eval_episodes,
            eval_seed=settings.eval_seed,
            threads=cpus_per_trial,
        ),
        {"cpu": cpus_per_trial},
    )
    bar = _Bar(settings.trials, "trials", OBJECTIVE)
    place = nullcontext(folder) if resume else files.folder_in_place(folder, keep=can_resume)
    with place, ray_session(address, num_cpus):
        if resume:
            tuner = tune.Tuner.restore(str(folder / SEARCH_NAME), trainable, resume_unfinished=True)
            # Tuner.restore takes no run configuration: give the restored one a bar that starts where
            # the interrupted search stopped.
            # (_local_tuner is None only under Ray Client, a "ray://" address.)
            tuner._local_tuner.get_run_config().callbacks = [bar]  # type: ignore[union-attr]
        else:
            files.write_json(folder / SEARCH_SETTINGS_FILE, settings.to_dict())
            searcher = OptunaSearch(
                metric=OBJECTIVE,
                mode="max",
                seed=settings.search_seed,
                points_to_evaluate=[dict(p) for p in points_to_evaluate] if points_to_evaluate else None,
            )
            tuner = tune.Tuner(
                trainable,
                param_space=dict(space if space is not None else default_space(base.algo)),
                tune_config=tune.TuneConfig(search_alg=searcher, num_samples=settings.trials),
                run_config=_run_config(folder, SEARCH_NAME, bar),
            )
        grid = _fit(tuner, bar)
        finished = [r for r in grid if r.error is not None or OBJECTIVE in (r.metrics or {})]
        if len(finished) < settings.trials:  # Tune stops on a signal after saving its state
            kept = resume or not earlier and can_resume(folder)  # as folder_in_place decides
            raise SearchInterruptedError(f"{len(finished)} trials finished") if kept else files.interruption()
        summary = _write_search_results(settings, grid, folder)
    if summary["best"] is None:
        raise AllTrialsFailedError([TrialFailure(f["trial"], f["error"]) for f in summary["failed"]])
    return summary


def _trial_tag(result: tune.Result) -> tuple[int, str]:
    """A search trial's number (1, 2, ... in the order Optuna proposed them) and Tune's id for it, both
    in the name of the trial's folder: ``_search_trial_<id>_<number>_<parameters>_<date>``."""
    name = Path(result.path).name
    trial_id = str((result.metrics or {}).get("trial_id") or name.removeprefix("_search_trial_").split("_")[0])
    match = re.search(rf"_{re.escape(trial_id)}_([0-9]+)(_|$)", name)
    if match is None:
        raise ValueError(f"cannot tell the trial number of {result.path}")
    return int(match.group(1)), trial_id


def _write_search_results(settings: SearchSettings, grid: Sequence[tune.Result], folder: Path) -> dict[str, Any]:
    """Write the search's result files (moved into place together); return the summary."""
    trials, failures = [], []
    for result in grid:
        number, trial_id = _trial_tag(result)
        row: dict[str, Any] = {"trial": number, "trial_id": trial_id, **dict(result.config or {})}
        if result.error is not None:
            failure = _failure(result, f"trial {row['trial']}")
            failures.append(failure)
            row["error"] = failure.error
        else:
            for key in (OBJECTIVE, "score", "heart_attacks_per_episode", "mean_return", "solved_seeds", *TIMINGS):
                row[key] = (result.metrics or {}).get(key)
        trials.append(row)
    trials.sort(key=lambda row: row["trial"])
    done = [row for row in trials if row.get(OBJECTIVE) is not None]
    best = max(done, key=lambda row: (row[OBJECTIVE], row["score"])) if done else None
    summary: dict[str, Any] = {
        "settings": settings.to_dict(),
        "objective": "interquartile mean over the trial's seeds of the expected-risk return (score secondary)",
        "trials": trials,
        "failed": [f.to_dict() for f in failures],
        "best": best,
    } | training.cpu_total(done)
    if best is not None:
        summary["preset"] = str(folder / PRESET_FILE)
        if importlib.util.find_spec("matplotlib") is not None:
            summary["plot"] = str(folder / PLOT_FILE)
    names = [TRIALS_FILE, TUNE_SUMMARY_FILE] + [Path(summary[key]).name for key in ("preset", "plot") if key in summary]
    with files.atomic_files(*(folder / name for name in names)) as temporaries:
        paths = dict(zip(names, temporaries))
        _write_trials_csv(paths[TRIALS_FILE], trials)
        if best is not None:
            params = {k: best[k] for k in dict(grid[0].config or {}) if k in best}
            config = replace(apply_params(settings.base, params), preset="tuned")
            training.save_preset(config, paths[PRESET_FILE], search=str(folder), trial=best["trial_id"],
                                 objective=best[OBJECTIVE], score=best["score"])  # fmt: skip
        if PLOT_FILE in paths:
            plot_search(trials, paths[PLOT_FILE])
        files.write_json(paths[TUNE_SUMMARY_FILE], summary)
    return summary


def _write_trials_csv(path: Path, trials: Sequence[Mapping[str, Any]]) -> None:
    columns: list[str] = []
    for row in trials:
        columns += [key for key in row if key not in columns]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows(trials)


def plot_search(trials: Sequence[Mapping[str, Any]], path: str | os.PathLike[str]) -> Path:
    """A PNG of the search: each trial's objective in trial order, the best so far as a line."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from heartpole.plots import CURVE_COLOR, save_figure

    done = [row for row in trials if row.get(OBJECTIVE) is not None]
    figure = Figure(figsize=(7.0, 4.0), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    x = [row["trial"] for row in done]
    y = [row[OBJECTIVE] for row in done]
    best = [max(y[: i + 1]) for i in range(len(y))]
    axes.scatter(x, y, color=CURVE_COLOR, s=18, label="trial")
    axes.step(x, best, where="post", color="#e03131", label="best so far")
    failed = [row["trial"] for row in trials if row.get(OBJECTIVE) is None]
    if failed and y:
        axes.scatter(failed, [min(y)] * len(failed), marker="x", color="#7f8c8d", label="failed")
    from matplotlib.ticker import MaxNLocator

    axes.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes.set_xlabel("trial")
    axes.set_ylabel("expected-risk return (IQM over seeds)")
    axes.set_title(f"hyperparameter search: {len(done)} trials" + (f", {len(failed)} failed" if failed else ""))
    axes.legend(loc="lower right")
    return files.atomic_write(path, lambda temporary: save_figure(figure, temporary))
