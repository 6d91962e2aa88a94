"""A model folder carries its env: ``heartpole train`` records the env id and keyword arguments, and the
commands that play a model use them by default, say so, and take ``--env`` and ``--env-kwargs`` over them."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import heartpole
from heartpole.cli import main
from heartpole.cli.envs import parse_env_kwargs
from heartpole.policies.trained_env import trained_env

pytest.importorskip("stable_baselines3")

TRAINED_ON = {"heart_attack_proclivity": 0.8, "max_steps": 20}


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny model trained by ``heartpole train`` on a preset's env keyword arguments."""
    from heartpole import launch
    from heartpole.training import preset_config

    out = tmp_path_factory.mktemp("trained") / "run"
    config = preset_config("default", timesteps=256, n_envs=2, env_kwargs=TRAINED_ON)
    launch.train(config, out, eval_episodes=4, progress=False)
    return out


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_train_records_the_env_id_and_kwargs(run: Path) -> None:
    record = json.loads((run / "heartpole.json").read_text())
    assert (record["env_id"], record["env_kwargs"]) == ("HeartPole-v0", TRAINED_ON)
    found = trained_env(str(run / "model.zip"))
    assert found is not None and (found.env_id, found.env_kwargs) == ("HeartPole-v0", TRAINED_ON)
    assert trained_env(str(run)) == found  # the folder names its model


@pytest.mark.parametrize("given", ["folder", "zip"])
def test_evaluate_plays_the_recorded_env_and_says_so(run: Path, capsys, given: str) -> None:
    spec = str(run if given == "folder" else run / "model.zip")
    code, out, err = _run(capsys, "evaluate", "--policy", spec, "--episodes", "4", "--json")
    assert code == 0, err
    assert json.loads(out)["max_steps"] == 20  # not v0's 1,000
    line = f"playing HeartPole-v0 with {TRAINED_ON} as recorded in {run / 'heartpole.json'}"
    assert line in err.splitlines()
    # the training's own evaluation (seed 0, 4 episodes) is met exactly: the same env, the same episodes
    own = json.loads((run / "evaluation.json").read_text())
    assert json.loads(out)["expected_return"] == own["expected_return"]


def test_env_kwargs_override_the_record_and_env_wins_over_it(run: Path, capsys) -> None:
    model = str(run / "model.zip")
    code, out, err = _run(
        capsys, "evaluate", "--policy", model, "--episodes", "2", "--json", "--env-kwargs", "max_steps=7"
    )
    assert code == 0 and json.loads(out)["max_steps"] == 7
    assert "'heart_attack_proclivity': 0.8, 'max_steps': 7}" in err and "--env-kwargs replacing ['max_steps']" in err
    code, out, err = _run(capsys, "evaluate", "--policy", model, "--episodes", "2", "--json", "--env", "HeartPole-v0")
    assert code == 0 and json.loads(out)["max_steps"] == 1000
    assert "playing --env HeartPole-v0 as given" in err


def test_compare_and_record_play_the_recorded_env(run: Path, capsys, tmp_path: Path) -> None:
    code, out, err = _run(capsys, "compare", "--policy", str(run), "--policy", "expert", "--episodes", "2", "--json")
    assert code == 0 and json.loads(out)["a"]["max_steps"] == 20, err
    pytest.importorskip("PIL")
    code, out, err = _run(capsys, "record", "--policy", str(run), "--out", str(tmp_path / "v.gif"))
    assert code == 0 and "(21 frames" in out and "as recorded in" in err


def test_models_recording_different_envs_need_env(run: Path, tmp_path: Path, capsys) -> None:
    other = tmp_path / "other"
    other.mkdir()
    for name in ("model.zip", "vecnormalize.json"):
        (other / name).write_bytes((run / name).read_bytes())
    record = json.loads((run / "heartpole.json").read_text()) | {"env_kwargs": {"max_steps": 30}}
    (other / "heartpole.json").write_text(json.dumps(record))
    code, _, err = _run(capsys, "compare", "--policy", str(run), "--policy", str(other), "--episodes", "2")
    assert code == 2 and "give --env" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("env_id", ["evilmod:HeartPole-v0", "CartPole-v1", 7, "Nope-v0"])
def test_a_recorded_env_id_must_be_a_registered_heartpole_id(run: Path, tmp_path: Path, env_id: object) -> None:
    for name in ("model.zip", "vecnormalize.json"):
        (tmp_path / name).write_bytes((run / name).read_bytes())
    record = json.loads((run / "heartpole.json").read_text()) | {"env_id": env_id}
    (tmp_path / "heartpole.json").write_text(json.dumps(record))
    (tmp_path / "evilmod.py").write_text("open('imported', 'w').write('yes')\n")
    package = str(Path(heartpole.__file__).parents[1])  # this checkout's, from a folder of its own
    result = subprocess.run(
        [sys.executable, "-m", "heartpole", "evaluate", "--policy", "model.zip", "--episodes", "2"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONPATH": package},
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert "is not a registered HeartPole env id" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "imported").exists()


def test_env_kwargs_parse_json_or_name_value_pairs() -> None:
    assert parse_env_kwargs('{"max_steps": 200}') == {"max_steps": 200}
    assert parse_env_kwargs("max_steps=200, heart_attack_proclivity=0.8,people=default") == {
        "max_steps": 200,
        "heart_attack_proclivity": 0.8,
        "people": "default",
    }
    for bad in ("[1]", "{bad", "max_steps", "=3"):
        with pytest.raises(ValueError, match="--env-kwargs"):
            parse_env_kwargs(bad)


def test_bad_env_kwargs_are_one_line(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["evaluate", "--policy", "expert", "--env-kwargs", "{bad"])
    assert exit_.value.code == 2 and "not a JSON object" in capsys.readouterr().err
    code, _, err = _run(capsys, "evaluate", "--policy", "expert", "--env-kwargs", "nope=1")
    assert code == 2 and "unexpected keyword argument 'nope'" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "command",
    [["evaluate", "--policy", "expert"], ["dataset", "--policy", "expert", "--id", "heartpole/v0/never-v0"]],
)
def test_people_given_by_env_kwargs_and_people_is_one_line_before_any_work(capsys, command: list[str]) -> None:
    """As Python refuses a keyword argument given twice: --people used to replace --env-kwargs' people silently."""
    code, out, err = _run(capsys, *command, "--env-kwargs", "people=default", "--people", "default")
    assert code == 2 and not out and len(err.strip().splitlines()) == 1, err
    assert "--env-kwargs gives people and so does --people; give each once (drop people= from" in err


def _copy_with_format(run: Path, where: Path, fmt: str | None) -> Path:
    """``run``'s folder copied to ``where``, its record's ``format`` set to ``fmt`` (removed: None)."""
    import shutil

    shutil.copytree(run, where)
    record = json.loads((run / "heartpole.json").read_text())
    record.pop("format")
    (where / "heartpole.json").write_text(json.dumps(record if fmt is None else {**record, "format": fmt}))
    return where / "model.zip"


def test_a_model_folder_records_its_format_and_another_version_is_refused(run: Path, tmp_path: Path, capsys) -> None:
    from heartpole.policies import MODEL_FORMAT, load_policy

    assert json.loads((run / "heartpole.json").read_text())["format"] == MODEL_FORMAT == "heartpole-model/1"
    later = _copy_with_format(run, tmp_path / "later", "heartpole-model/99")
    code, _, err = _run(capsys, "evaluate", "--policy", str(later), "--episodes", "2")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{later.parent / 'heartpole.json'}: format 'heartpole-model/99', and this HeartPole reads " in err
    assert "'heartpole-model/1' only" in err
    with pytest.raises(ValueError, match="format 'heartpole-model/99'"):
        load_policy(str(later), "HeartPole-v0", env_kwargs=TRAINED_ON)
    older = _copy_with_format(run, tmp_path / "older", None)  # written before the field existed: version 1
    assert trained_env(str(older)) is not None
    load_policy(str(older), "HeartPole-v0", env_kwargs=TRAINED_ON)
