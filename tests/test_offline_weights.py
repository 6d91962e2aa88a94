"""OPE reports each importance-sampling estimate's effective sample size and warns when it is too small to mean
anything, including when no episode keeps a weight past some step (issue 43, item 6)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from heartpole.offline.weights import weight_diagnostics


def test_equal_weights_count_every_episode() -> None:
    diagnostics = weight_diagnostics(np.ones((50, 8)), 0.9)
    assert diagnostics.effective_sample_size == pytest.approx(50.0)
    assert (diagnostics.weight_horizon, diagnostics.lost_share, diagnostics.warning) == (8, 0.0, None)


def test_a_small_dataset_with_equal_weights_is_not_warned_about() -> None:
    assert weight_diagnostics(np.ones((4, 10)), 0.95).warning is None  # 4 of 4: small, but not the weights' doing
    weights = np.ones((4, 10))
    weights[1:] = 1e-4
    assert "effective sample size 1.0 of 4 episodes" in str(weight_diagnostics(weights, 0.95).warning)


def test_one_heavy_episode_counts_as_about_one() -> None:
    weights = np.full((1000, 4), 1e-6)
    weights[0] = 1.0
    diagnostics = weight_diagnostics(weights, 1.0)
    assert diagnostics.effective_sample_size == pytest.approx(1.0, abs=0.01)
    assert "effective sample size 1.0 of 1,000 episodes" in str(diagnostics.warning)


def test_below_one_percent_of_the_episodes_is_too_few() -> None:
    weights = np.zeros((10_000, 3))
    weights[:50] = 1.0  # 50 effective episodes: more than 10, less than 1% of 10,000
    assert "effective sample size 50.0 of 10,000 episodes" in str(weight_diagnostics(weights, 1.0).warning)
    assert weight_diagnostics(weights[:1000], 1.0).warning is None  # 50 of 1,000 is 5%


def test_no_weight_past_a_step_is_said_with_the_step() -> None:
    weights = np.ones((100, 200))
    weights[:, 20:] = 0.0  # every episode took an action the target never takes by step 21
    diagnostics = weight_diagnostics(weights, 0.95)
    assert diagnostics.weight_horizon == 20
    assert diagnostics.lost_share == pytest.approx(0.95**20, rel=1e-3)
    assert str(diagnostics.warning).startswith("no episode keeps weight past step 20: the 180 steps after it (36%")
    every_weight_zero = weight_diagnostics(np.zeros((100, 200)), 0.95)
    assert every_weight_zero.effective_sample_size == 0.0
    assert str(every_weight_zero.warning).startswith("no episode keeps any weight")
    assert weight_diagnostics(weights, 0.5).warning is None  # 0.5**20 of the weight lost: negligible


def test_ope_prints_the_warning_in_one_line_and_puts_it_in_the_json(tmp_path: Path, monkeypatch, capsys) -> None:
    pytest.importorskip("minari")
    from heartpole.cli import main
    from heartpole.offline import datasets

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    datasets.record_dataset("reference", 0.2, 40, dataset_id="heartpole/v0/ess-v0")
    argv = ["ope", "--dataset", "heartpole/v0/ess-v0", "--policy", "expert", "--truth-episodes", "4"]
    assert main([*argv, "--json"]) == 0
    captured = capsys.readouterr()
    warnings = [line for line in captured.err.splitlines() if line.startswith("warning: ")]
    assert len(warnings) == 1 and "no episode keeps weight past step" in warnings[0]
    estimates = {e["estimator"]: e for e in json.loads(captured.out)["estimates"]}
    for name in ("PDIS", "WPDIS", "DR"):
        assert estimates[name]["effective_sample_size"] < 10 and estimates[name]["weight_horizon"] < 1000
        assert estimates[name]["warning"] == warnings[0].removeprefix("warning: ")
    assert estimates["FQE"]["effective_sample_size"] is None and estimates["FQE"]["warning"] is None
    assert main(argv) == 0
    assert "ESS" in capsys.readouterr().out
