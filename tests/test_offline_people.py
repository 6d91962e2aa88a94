"""Datasets and off-policy evaluation over people: each episode's person round-trips, the population is in the
metadata, and OPE's truth is the dataset's population's.

Statistical tolerance. The truth under the default people differs from v0's: with 1,000 episodes each, the two
expected-risk discounted values (gamma 1, HeartPole's return: about -136 and -123, each interval about +-1.5)
differ by more than 4 standard errors of their difference.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

pytest.importorskip("minari")

import heartpole.people  # noqa: E402
from heartpole.evaluation import chunk_seed  # noqa: E402
from heartpole.offline.datasets import load_local, load_trajectories, record_dataset  # noqa: E402
from heartpole.offline.ope import evaluate_off_policy  # noqa: E402
from heartpole.offline.population import dataset_env_kwargs, people_from_dict, people_suffix  # noqa: E402
from heartpole.offline.truth import true_value  # noqa: E402
from heartpole.people import People, Uniform  # noqa: E402
from heartpole.rollout import vector_env  # noqa: E402
from tests.people_cohorts import TRIO  # noqa: E402

pytestmark = pytest.mark.slow  # datasets over people compile the people's loop and solve a cohort: minutes

EPISODES = 12
STEPS = 1000


@pytest.fixture(autouse=True)
def minari_folder(tmp_path, monkeypatch):  # type: ignore[no-untyped-def]
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    return tmp_path


def reset_people(seed: int, episodes: int, **env_kwargs: object) -> tuple[np.ndarray, np.ndarray]:
    """The people the env itself draws at the reset the recording's first chunk makes."""
    with vector_env("HeartPole-v0", env_kwargs, episodes) as env:
        _, info = env.reset(seed=chunk_seed(seed, 0))
    return np.asarray(info["person"]), np.asarray(info["traits"])


def test_each_episodes_person_round_trips() -> None:
    dataset = record_dataset("expert", 0.1, EPISODES, seed=3, people="default")
    assert dataset.spec.dataset_id == "heartpole/v0/expert-eps10-people-default-v0"
    data = load_trajectories(dataset.spec.dataset_id)
    person, traits = reset_people(3, EPISODES, people="default")
    assert data.person is not None and data.traits is not None
    np.testing.assert_array_equal(data.person, person)
    np.testing.assert_array_equal(data.traits, traits)
    assert len(set(data.person.tolist())) > 1  # people differ between episodes
    default = People.default()
    table = np.array([[p.values()["heart_attack_proclivity"]] for p in default.cohort])
    proclivity = list(default.traits).index("heart_attack_proclivity")
    np.testing.assert_allclose(data.traits[:, proclivity], table[data.person, 0], rtol=1e-6)
    assert data.observations.shape == (EPISODES, STEPS + 1, 6)  # the traits are hidden
    meta = load_local(dataset.spec.dataset_id).storage.metadata
    assert meta["people"] == default.to_dict() and meta["observe_traits"] is False
    assert json.loads(json.dumps(meta["people"])) == default.to_dict()
    assert data.subset(slice(2, 5)).person.tolist() == person[2:5].tolist()  # type: ignore[union-attr]


def test_observed_traits_are_the_episodes_persons() -> None:
    dataset = record_dataset("reference", 0.0, 6, seed=4, people=TRIO, observe_traits=True, num_envs=3)
    assert dataset.spec.dataset_id == "heartpole/v0/reference-people-traits-v0"
    data = load_trajectories(dataset.spec.dataset_id)
    assert data.traits is not None and data.traits.shape == (6, len(TRIO.traits))
    np.testing.assert_array_equal(data.observations[:, 0, 6:], data.traits)  # two chunks, persons in order
    np.testing.assert_array_equal(data.observations[:, -1, 6:], data.traits)
    meta = load_local(dataset.spec.dataset_id).storage.metadata
    assert dataset_env_kwargs(meta)["observe_traits"] is True


def test_a_dataset_without_people_has_none() -> None:
    dataset = record_dataset("reference", 0.2, 2, seed=1, env_id="HeartPole-v0")
    data = load_trajectories(dataset.spec.dataset_id)
    assert data.person is None and data.traits is None
    assert "people" not in load_local(dataset.spec.dataset_id).storage.metadata
    assert dataset_env_kwargs(load_local(dataset.spec.dataset_id).storage.metadata) == {}


@pytest.mark.parametrize(
    "people",
    [
        People.default(),
        TRIO,
        People(
            heart_attack_proclivity=Uniform(0.3, 0.7), wake_alertness=Uniform((0.6, 1.2), (0.8, 1.4)), decay_rate=0.95
        ),
    ],
    ids=["default", "trio", "distribution"],
)
def test_the_population_comes_back_from_its_description(people: People) -> None:
    again = people_from_dict(json.loads(json.dumps(people.to_dict())))
    assert again.to_dict() == people.to_dict() and again.traits == people.traits


def test_bad_people_are_refused_before_anything_is_written(minari_folder) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError, match="observe_traits=True needs people"):
        record_dataset("expert", 0.1, 2, observe_traits=True)
    with pytest.raises(ValueError, match="unknown population 'nobody'"):
        record_dataset("expert", 0.1, 2, people="nobody")
    with pytest.raises(ValueError, match="'cohort' or 'fields'"):
        people_from_dict({"people": []})
    assert list(minari_folder.iterdir()) == []
    assert people_suffix(None, False) == "" and people_suffix("default", True) == "-people-default-traits"


def test_the_truth_under_people_differs_from_v0s() -> None:
    under = true_value("expert", 1.0, 1000, seed=0, env_kwargs={"people": "default"})
    v0 = true_value("expert", 1.0, 1000, seed=0)
    se = math.hypot(*((t.value_ci95[1] - t.value_ci95[0]) / (2 * 1.96) for t in (under, v0)))
    assert abs(under.value - v0.value) > 4 * se


def test_ope_reports_the_truth_over_the_datasets_people(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The truth is the env with the dataset's people (same seed and episodes: exactly true_value's), and a
    finite cohort adds the target's oracle regret."""
    record_dataset("reference", 0.2, 4, seed=2, people=TRIO, dataset_id="heartpole/v0/trio-v0")
    report = evaluate_off_policy("heartpole/v0/trio-v0", "expert", truth_episodes=40, seed=5)
    assert report.truth == true_value("expert", 0.95, 40, seed=5, env_kwargs={"people": TRIO})
    assert report.truth != true_value("expert", 0.95, 40, seed=5)
    assert report.people == TRIO.to_dict()
    low, high = report.oracle["oracle_regret_ci95"]
    assert low <= report.oracle["oracle_regret"] <= high and math.isfinite(low)
    out = report.to_dict()
    assert out["people"] == TRIO.to_dict() and out["oracle_regret"] == report.oracle["oracle_regret"]
    assert out["no_oracle_regret_reason"] is None
    json.dumps(out, allow_nan=False)
    with pytest.raises(ValueError, match="'oracle' needs each episode's person"):
        evaluate_off_policy("heartpole/v0/trio-v0", "oracle", truth_episodes=10)


def test_ope_under_a_distribution_says_why_there_is_no_oracle_regret() -> None:
    people = People(heart_attack_proclivity=Uniform(0.3, 0.7))
    record_dataset("reference", 0.2, 3, seed=2, people=people, dataset_id="heartpole/v0/range-v0")
    out = evaluate_off_policy("heartpole/v0/range-v0", "expert", truth_episodes=10).to_dict()
    assert out["oracle_regret"] is None and "distribution" in out["no_oracle_regret_reason"]
    assert out["people"] == people.to_dict()


def test_ope_without_people_reports_none() -> None:
    record_dataset("reference", 0.2, 2, seed=2)
    out = evaluate_off_policy("heartpole/v0/reference-eps20-v0", "expert", truth_episodes=10).to_dict()
    assert out["people"] is None and out["oracle_regret"] is None
    assert out["no_oracle_regret_reason"] == "the dataset was recorded without people"


def test_cli_dataset_and_ope_with_people(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from heartpole.cli import main

    monkeypatch.setitem(heartpole.people.POPULATIONS, "trio", lambda: TRIO)  # type: ignore[index]
    argv = ["dataset", "--policy", "reference", "--epsilon", "0.2", "--episodes", "4", "--people", "trio"]
    assert main([*argv, "--observe-traits"]) == 0
    out = capsys.readouterr().out
    assert (
        "heartpole/v0/reference-eps20-people-trio-traits-v0" in out and "people: 3 in a cohort, traits observed" in out
    )
    ope = ["ope", "--dataset", "heartpole/v0/reference-eps20-people-trio-traits-v0", "--policy", "expert"]
    assert main([*ope, "--truth-episodes", "20"]) == 0
    out = capsys.readouterr().out
    assert "with the dataset's people" in out and "oracle regret" in out
    assert main([*ope, "--truth-episodes", "20", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["people"] == TRIO.to_dict()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["dataset", "--policy", "expert", "--observe-traits"], "--observe-traits needs --people"),
        (["dataset", "--standard", "--people", "default"], "--people records one dataset"),
        (["dataset", "--policy", "expert", "--people", "nobody"], "unknown population 'nobody'"),
    ],
)
def test_cli_bad_people(capsys, minari_folder, argv, message) -> None:  # type: ignore[no-untyped-def]
    from heartpole.cli import main

    try:
        code = main(argv)
    except SystemExit as exit:
        code = exit.code
    err = capsys.readouterr().err
    assert code == 2 and message in err
    assert list(minari_folder.iterdir()) == []
