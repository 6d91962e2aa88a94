"""A tampered dataset's actions: out of range, -1 (which indexing would read as the last action) or not whole
are refused in one line naming the dataset, the episode, the step and the accepted range (issue 43, item 9)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

pytest.importorskip("minari")
h5py = pytest.importorskip("h5py")

from heartpole.cli import main  # noqa: E402
from heartpole.offline import datasets  # noqa: E402

DATASET = "heartpole/v0/tampered-v0"


@pytest.fixture
def recorded(tmp_path: Path, monkeypatch) -> Path:
    """A small dataset in a private Minari folder; returns its HDF5 file."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    datasets.record_dataset("reference", 0.2, 3, dataset_id=DATASET, env_kwargs={"max_steps": 20})
    return tmp_path / DATASET / "data" / "main_data.hdf5"


@pytest.mark.parametrize("action", [-1, 4, 255])
def test_ope_refuses_an_action_out_of_range(recorded: Path, capsys, action: int) -> None:
    with h5py.File(recorded, "r+") as data:
        data["episode_1"]["actions"][7] = action
    assert main(["ope", "--dataset", DATASET, "--policy", "expert", "--truth-episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert f"dataset '{DATASET}': episode 1, step 7: action {action} is not one of the env's actions" in err
    assert "whole numbers 0 to 3" in err


def test_actions_that_are_not_whole_numbers_are_refused(recorded: Path) -> None:
    with h5py.File(recorded, "r+") as data:
        actions = data["episode_0"]["actions"][()].astype("float64")
        actions[3] = 1.5
        del data["episode_0"]["actions"]
        data["episode_0"]["actions"] = actions
    with pytest.raises(ValueError, match=r"episode 0, step 3: action 1\.5 is not one of the env's actions"):
        datasets.load_trajectories(DATASET)


def test_an_untouched_dataset_reads_back(recorded: Path) -> None:
    trajectories = datasets.load_trajectories(DATASET)
    assert trajectories.actions.shape == (3, 20) and trajectories.actions.min() >= 0


@pytest.mark.parametrize(
    ("field", "value"),
    [("observations", float("nan")), ("rewards", float("inf")), ("infos/action_probabilities", float("nan"))],
)
def test_a_number_that_is_not_finite_is_refused(recorded: Path, capsys, field: str, value: float) -> None:
    with h5py.File(recorded, "r+") as data:
        data["episode_0"][field][2] = value  # FQE and DR printed nan (a NaN propensity went unseen) with exit 0
    assert main(["ope", "--dataset", DATASET, "--policy", "expert", "--truth-episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert f"dataset '{DATASET}': episode 0, step 2: {field.split('/')[-1]} holds" in err
    assert "every recorded number must be finite" in err


def test_a_damaged_dataset_is_one_line(recorded: Path, capsys) -> None:
    with h5py.File(recorded, "r+") as data:
        del data["episode_0"]  # was a KeyError traceback
    assert main(["ope", "--dataset", DATASET, "--policy", "expert", "--truth-episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert f"dataset '{DATASET}' cannot be read (damaged" in err


def test_a_dataset_file_that_is_not_a_regular_file_is_refused_without_waiting(recorded: Path, capsys) -> None:
    recorded.unlink()
    os.mkfifo(recorded)  # the HDF5 reader blocked on it forever
    assert main(["ope", "--dataset", DATASET, "--policy", "expert", "--truth-episodes", "2"]) == 2
    assert f"{recorded} is not a regular file" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("content", "said"),
    [(b"", "is not an HDF5 file (it is empty)"), (b"not an HDF5 file at all\n", "is not an HDF5 file;")],
    ids=["empty", "not-hdf5"],
)
def test_a_dataset_file_that_is_not_hdf5_is_named(recorded: Path, capsys, content: bytes, said: str) -> None:
    recorded.write_bytes(content)  # h5py's "file signature not found" named no file
    assert main(["ope", "--dataset", DATASET, "--policy", "expert", "--truth-episodes", "2"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert f"dataset '{DATASET}': {recorded} {said}" in err
