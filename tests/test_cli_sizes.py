"""Sizes of work a user asks for (a recorded episode's length, a dataset's episodes, a search's trials), refused in
one line before the work starts (issue 43: "every size a user can ask for is checked against what the machine has
before the work starts")."""

from __future__ import annotations

from pathlib import Path

import pytest

from heartpole import paths
from tests.test_cli_one_line import one_line

HUGE = str(10**11)


def _no_episode(*args: object, **kwargs: object) -> None:
    raise AssertionError("the episode started before its length was checked")


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["record", "--steps", HUGE, "--out", "v.mp4"], "--steps"),
        (["record", "--env-kwargs", f'{{"max_steps": {HUGE}}}', "--out", "v.mp4"], "max_steps"),
        (["plot", "episode", "--steps", HUGE, "--out", "e.png"], "--steps"),
    ],
    ids=["record", "record-env-kwargs", "plot-episode"],
)
def test_an_episode_too_long_to_draw_is_refused_first(
    capsys, monkeypatch, tmp_path: Path, argv: list[str], option: str
) -> None:
    pytest.importorskip("matplotlib")
    pytest.importorskip("imageio_ffmpeg")
    from heartpole import plots

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(plots, "episode_frames", _no_episode)
    monkeypatch.setattr(plots, "trace_episode", _no_episode)
    err = one_line(capsys, [*argv, "--policy", "nothing"])
    assert f"{option} 100,000,000,000: an episode drawn or recorded has at most 100,000 decisions" in err
    assert list(tmp_path.iterdir()) == []


def test_a_gif_larger_than_the_memory_is_refused_first(capsys, monkeypatch, tmp_path: Path) -> None:
    pytest.importorskip("PIL")
    from heartpole import plots

    monkeypatch.setattr(plots, "episode_frames", _no_episode)
    monkeypatch.setattr(paths, "physical_memory", lambda: 2 * 1001 * plots.GIF_FRAME_BYTES - 1)
    err = one_line(capsys, ["record", "--policy", "nothing", "--steps", "1000", "--out", str(tmp_path / "v.gif")])
    assert "--steps 1,000 as a GIF (1,001 frames Pillow holds until it writes) needs about" in err
    assert "record an MP4" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("standard", [False, True], ids=["one", "standard"])
def test_a_dataset_larger_than_the_disk_is_refused_before_anything_runs(
    capsys, monkeypatch, tmp_path: Path, standard: bool
) -> None:
    pytest.importorskip("minari")
    from heartpole.offline import datasets

    def no_work(*args: object, **kwargs: object) -> None:
        raise AssertionError("the dataset's work started before its size was checked")

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    for name in ("chunk_seed", "reference_scores", "behaviour_policy"):
        monkeypatch.setattr(datasets, name, no_work)
    argv = ["dataset", "--standard", "--force"] if standard else ["dataset", "--policy", "expert"]
    err = one_line(capsys, [*argv, "--episodes", str(10**9)])
    assert "--episodes 1,000,000,000" + (" for each of the 6 standard datasets" if standard else "") in err
    assert " TiB and " in err and " free; free some space or point MINARI_DATASETS_PATH elsewhere" in err
    assert not (tmp_path / "minari").exists()


def test_the_library_checks_a_datasets_room_before_it_runs(monkeypatch, tmp_path: Path) -> None:
    pytest.importorskip("minari")
    from heartpole.offline import datasets

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    monkeypatch.setattr(datasets, "chunk_seed", _no_episode)
    with pytest.raises(OSError, match=r"dataset 'heartpole/v0/expert-v0' \(1,000,000,000 episodes\) needs about"):
        datasets.record_dataset("expert", 0.0, 10**9)


def _no_search(*args: object, **kwargs: object) -> None:
    raise AssertionError("the search started before its trials were checked")


def test_more_trials_than_a_search_runs_are_refused(capsys, monkeypatch, tmp_path: Path) -> None:
    pytest.importorskip("ray")
    pytest.importorskip("optuna")
    pytest.importorskip("stable_baselines3")
    from heartpole import scale
    from heartpole.scale import MAX_TRIALS, SearchSettings
    from heartpole.training import preset_config

    monkeypatch.setattr(scale, "tune_search", _no_search)
    out = tmp_path / "o"
    err = one_line(capsys, ["tune", "--trials", HUGE, "--timesteps", "64", "--out", str(out)])
    assert f"--trials 100,000,000,000: a search runs at most {MAX_TRIALS:,} trials" in err
    assert not out.exists()  # refused before prepare_search_folder
    data = SearchSettings(base=preset_config(), trials=1, seeds=(0,)).to_dict()
    with pytest.raises(ValueError, match=r"trials must be an integer in \[1, 10,000\], got 100000000000"):
        SearchSettings.from_dict({**data, "trials": 10**11})
