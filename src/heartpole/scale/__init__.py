"""Beyond one machine: the seeds of ``heartpole train`` and hyperparameter searches as Ray Tune trials.

This package needs the optional ``ray`` extra (``pip install 'heartpole[ray]'``: Ray Tune, Optuna and the
``train`` extra); it is the only package that imports Ray, and ``import heartpole`` never imports it.

* `train_seeds_ray` (module ``seeds``) runs one Ray Tune trial per seed. Each trial
  calls `train_run`, exactly as ``heartpole train --seeds`` does one after another,
  and writes the same files to ``<folder>/seed_<s>/``; the summary is
  [`seeds_summary`][heartpole.records.seeds_summary]'s (interquartile mean across seeds with a bootstrap interval).
  Same seed, same settings, same results.
* `tune_search` (module ``search``) searches hyperparameters with Optuna (Ray Tune's
  ``OptunaSearch``) over `default_space`; each trial trains ``seeds_per_trial`` seeds
  with `train_seeds` and evaluates them with the standard protocol; the objective is
  the interquartile mean over those seeds of the expected-risk return (the score is reported beside it). The search
  keeps Ray Tune's experiment state in its output folder, so an interrupted search resumes.

Ray runs locally when no address is given (``ray.init()`` on this machine's cores) and joins a cluster with
``address`` (``"auto"`` or ``"ray://host:10001"``). Ray's start-up messages, dashboard, Tune's tables and loggers are
all switched off; progress is one bar (trials done / total and the best figure so far). A trial that raises is
reported as one `TrialFailure` (module ``trials``, with the Ray session) line and the
others go on.
"""

# trials first: it says what to install when Ray is missing
from heartpole.scale.trials import (
    RAY_EXTRA,
    AllTrialsFailedError,
    SearchInterruptedError,
    TrialFailure,
    TrialsBar,
    fit,
    quiet_tune,
    ray_session,
    run_config,
)

# isort: split
from heartpole.scale.search import (
    MAX_TRIALS,
    OBJECTIVE,
    PLOT_FILE,
    PRESET_FILE,
    RESUME_PICKLE,
    SEARCH_FORMAT,
    SEARCH_NAME,
    SEARCH_SETTINGS_FILE,
    SEARCHABLE,
    TIMINGS,
    TRIALS_FILE,
    TUNE_SUMMARY_FILE,
    SearchSettings,
    UntrustedSearchError,
    apply_params,
    can_resume,
    default_space,
    plot_search,
    prepare_search_folder,
    read_settings,
    tune_search,
)
from heartpole.scale.seeds import train_seeds_ray

__all__ = [
    "RAY_EXTRA",
    "AllTrialsFailedError",
    "SearchInterruptedError",
    "TrialFailure",
    "TrialsBar",
    "fit",
    "quiet_tune",
    "ray_session",
    "run_config",
    "train_seeds_ray",
    "MAX_TRIALS",
    "OBJECTIVE",
    "PLOT_FILE",
    "PRESET_FILE",
    "RESUME_PICKLE",
    "SEARCH_NAME",
    "SEARCH_FORMAT",
    "SEARCH_SETTINGS_FILE",
    "SEARCHABLE",
    "TIMINGS",
    "TRIALS_FILE",
    "TUNE_SUMMARY_FILE",
    "SearchSettings",
    "UntrustedSearchError",
    "apply_params",
    "can_resume",
    "default_space",
    "plot_search",
    "prepare_search_folder",
    "read_settings",
    "tune_search",
]
