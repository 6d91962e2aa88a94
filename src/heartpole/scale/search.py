"""Hyperparameter searches: Optuna on Ray Tune over `default_space`,
each trial a few seeds of `heartpole.training.train_seeds`; resumable from
its output folder."""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import re
from collections.abc import Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ray import tune

from heartpole import files, training
from heartpole.registry import check_heartpole_id
from heartpole.scale.trials import (
    AllTrialsFailedError,
    SearchInterruptedError,
    TrialFailure,
    TrialsBar,
    failure,
    fit,
    ray_session,
    run_config,
)

OBJECTIVE = "objective"
SEARCH_NAME = "search"
SEARCH_SETTINGS_FILE = "search.json"
"""The search's settings in its folder (what a resumed search checks it continues)."""
SEARCH_FORMAT = "heartpole-search/1"
"""The ``format`` of the ``search.json`` this HeartPole writes and resumes (one written before the field existed,
with the same keys, resumes too)."""
MAX_TRIALS = 10_000
"""The most trials one search runs: ten times the largest budget Optuna recommends for its TPE sampler (100 to
1,000 trials), whose time to choose a trial grows as n log n with the n trials before it, and Ray Tune keeps
every trial in memory and in the state it saves. A bigger search is better run as several."""
TRIALS_FILE = "trials.csv"
PRESET_FILE = "best_preset.json"
PLOT_FILE = "search.png"
TUNE_SUMMARY_FILE = "tune_summary.json"
SEARCHABLE = ("ppo", "a2c")
TIMINGS = ("wall_seconds", "cpu_seconds")
"""A trial's timings, summed over its seeds: the wall time of its runs and their CPU time."""
"""Algorithms with a default search space (DQN has neither ``n_steps`` nor ``ent_coef``)."""


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
            "format": SEARCH_FORMAT,
            "base": self.base.to_dict(),
            "trials": self.trials,
            "seeds": list(self.seeds),
            "eval_episodes": self.eval_episodes,
            "eval_seed": self.eval_seed,
            "search_seed": self.search_seed,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SearchSettings:
        """The inverse of [`to_dict`][heartpole.scale.search.SearchSettings.to_dict].

        Raises:
            ValueError: another format than [`SEARCH_FORMAT`][heartpole.scale.search.SEARCH_FORMAT], a key
                missing or unknown, or a value of the wrong kind, named.
        """
        from heartpole.parameters import check_integer

        if not isinstance(data, Mapping):
            raise ValueError(f"expected a JSON object, got {type(data).__name__}")
        values = dict(data)
        found = values.pop("format", SEARCH_FORMAT)
        if found != SEARCH_FORMAT:
            raise ValueError(f"format {found!r}, and this HeartPole resumes {SEARCH_FORMAT!r} only")
        known = {"base", "trials", "seeds", "eval_episodes", "eval_seed", "search_seed"}
        if set(values) - known or not {"base", "trials", "seeds"} <= set(values):
            raise ValueError(f"keys {sorted(values)}, expected {sorted(known)}")
        try:
            values["base"] = training.TrainConfig.from_dict(values["base"])
        except (TypeError, ValueError, AttributeError) as error:
            raise ValueError(f"base: {' '.join(str(error).split())}") from None
        if not isinstance(values["seeds"], list) or not values["seeds"]:
            raise ValueError(f"seeds must be a list of seeds, got {values['seeds']!r}")
        values["seeds"] = tuple(check_integer("seeds[]", seed, 0) for seed in values["seeds"])
        values["trials"] = check_integer("trials", values["trials"], 1, MAX_TRIALS)
        for key in ("eval_episodes", "eval_seed", "search_seed"):
            if key in values:
                values[key] = check_integer(key, values[key], 1 if key == "eval_episodes" else 0)
        return cls(**values)


def can_resume(folder: str | os.PathLike[str]) -> bool:
    """Whether ``folder`` holds a search that [`tune_search`][heartpole.scale.search.tune_search] can resume."""
    folder = Path(folder).resolve()
    return (folder / SEARCH_SETTINGS_FILE).is_file() and tune.Tuner.can_restore(str(folder / SEARCH_NAME))


RESUME_PICKLE = "tuner.pkl"
"""The file of Ray Tune's saved search (in ``search/``) that resuming unpickles first; its experiment state and
searcher state are unpickled after it."""


class UntrustedSearchError(ValueError):
    """A search that only unpickling Ray Tune's saved state could resume (which can run code), without
    ``trust_pickles``: refused before Ray read anything."""


def prepare_search_folder(
    folder: str | os.PathLike[str], resume: bool = False, force: bool = False, *, trust_pickles: bool = False
) -> Path:
    """Check, before any trial runs, that a search may run in ``folder``; return it as an absolute ``Path``.

    With ``resume`` it must hold a search to continue, and ``trust_pickles`` must be given: Ray Tune resumes a
    search by unpickling its saved state (``search/tuner.pkl``, the experiment and searcher state), and
    unpickling can run any code the folder's author chose. Otherwise it must be missing or empty, or, with
    ``force``, hold an earlier search (its [`SEARCH_SETTINGS_FILE`][heartpole.scale.search.SEARCH_SETTINGS_FILE]), which
    [`tune_search`][heartpole.scale.search.tune_search] replaces
    once the new search is done: ``force`` never removes anything else.

    Raises:
        ValueError: ``resume`` with ``force``, nothing to resume, a file in the way, a non-empty folder
            without ``force``, or with ``force`` a folder that holds no search.
        UntrustedSearchError: ``resume`` without ``trust_pickles``; nothing from the folder was unpickled.
    """
    out = Path(folder).resolve()
    if resume:
        if force:
            raise ValueError("--resume continues the search in --out and --force replaces it: give one")
        if not can_resume(out):
            raise ValueError(f"--resume: no search to continue in {out}")
        read_settings(out)  # a damaged or other-version search.json: refused before Ray starts
        if not trust_pickles:
            raise UntrustedSearchError(
                f"--resume would unpickle {out / SEARCH_NAME / RESUME_PICKLE} (Ray Tune's saved search), which can "
                "run any code its author chose; nothing from it was run. Resume only a search you trust: pass "
                "--trust-pickles (trust_pickles=True in Python)"
            )
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
    """The settings of the search in ``folder``; its env id must be a HeartPole id (checked before anything makes
    it).

    Raises:
        ValueError: a ``search.json`` that is not JSON, or not one this HeartPole writes (see
            [`SearchSettings.from_dict`][heartpole.scale.search.SearchSettings.from_dict]), or whose env id is not
            a HeartPole id, naming the file.
        OSError: it cannot be read.
    """
    path = Path(folder) / SEARCH_SETTINGS_FILE
    try:
        data = json.loads(path.read_text())
    except ValueError as error:  # json.JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise ValueError(f"{path} is not the settings of a search this HeartPole can resume: "
                         f"{' '.join(str(error).split())}") from None  # fmt: skip
    base = data.get("base") if isinstance(data, dict) else None
    if isinstance(base, dict):  # before anything reads the settings further: nothing may make a foreign id
        check_heartpole_id(base.get("env_id", "HeartPole-v0"), str(path))
    try:
        return SearchSettings.from_dict(data)
    except ValueError as error:
        raise ValueError(f"{path} is not the settings of a search this HeartPole can resume: "
                         f"{' '.join(str(error).split())}") from None  # fmt: skip


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
    trust_pickles: bool = False,
) -> dict[str, Any]:
    """Search hyperparameters with Optuna on Ray Tune; write the results into ``folder``; return them.

    ``folder`` (made absolute) receives ``search.json`` (the settings), ``search/`` (Ray Tune's experiment
    state: what [`can_resume`][heartpole.scale.search.can_resume] and ``resume=True`` use), ``trials/<trial id>/`` (each
    trial's [`heartpole.training.train_seeds`][heartpole.training.runs.train_seeds] output), and at the end
    ``trials.csv`` (one row per trial), ``best_preset.json`` (the best configuration, for ``heartpole train --preset``),
    ``search.png`` (the objective per trial, when matplotlib is installed) and ``tune_summary.json``.

    ``space`` defaults to [`default_space`][heartpole.scale.search.default_space]; ``points_to_evaluate`` are tried
    first (Optuna enqueues them). With ``resume``, the settings saved in ``folder`` are used and ``settings`` is
    ignored; finished trials are kept, unfinished ones rerun, failed ones stay failed. ``folder`` is checked by
    [`prepare_search_folder`][heartpole.scale.search.prepare_search_folder]; ``force`` replaces an earlier search once
    the new one is done. One search at a time runs in ``folder``
    ([`heartpole.files.folder_lock`][heartpole.files.folder_lock]). Resuming unpickles Ray Tune's saved state, which
    can run code: it needs ``trust_pickles``.

    Raises:
        UntrustedSearchError: ``resume`` without ``trust_pickles`` (before Ray reads anything).
        AllTrialsFailedError: every trial failed (``tune_summary.json`` and ``trials.csv`` are still written).
        SearchInterruptedError: a signal stopped the search; it stays in ``folder`` to resume.
        KeyboardInterrupt: a signal stopped it before it could resume, or with ``force``: ``folder`` is as it was.
        heartpole.files.FolderInUseError: another search is running in ``folder`` (nothing was changed).
    """
    import optuna
    from ray.tune.search.optuna import OptunaSearch

    optuna.logging.set_verbosity(optuna.logging.WARNING)  # not "A new study created in memory"
    with files.folder_lock(Path(folder).resolve()):  # one search at a time writes the folder
        folder = prepare_search_folder(folder, resume, force, trust_pickles=trust_pickles)
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
        bar = TrialsBar(settings.trials, "trials", OBJECTIVE)
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
                    run_config=run_config(folder, SEARCH_NAME, bar),
                )
            grid = fit(tuner, bar)
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
            failed = failure(result, f"trial {row['trial']}")
            failures.append(failed)
            row["error"] = failed.error
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
