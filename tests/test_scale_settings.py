"""``search.json`` carries a format: ``heartpole tune --resume`` refuses a damaged or other-version one in one
line, before Ray starts (issue 43, item 9)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")
pytest.importorskip("ray")
pytest.importorskip("optuna")

from heartpole import scale, training  # noqa: E402
from heartpole.cli import main  # noqa: E402


def _search_folder(tmp_path: Path, text: str) -> Path:
    """A folder that looks like an interrupted search, with ``text`` as its search.json (Ray's state is an
    empty file: it is never read when the settings are refused)."""
    out = tmp_path / "tune"
    (out / scale.SEARCH_NAME).mkdir(parents=True)
    (out / scale.SEARCH_NAME / "tuner.pkl").write_bytes(b"")
    (out / scale.SEARCH_SETTINGS_FILE).write_text(text)
    return out


def _settings() -> dict[str, object]:
    settings = scale.SearchSettings(training.preset_config(timesteps=2048), trials=3, seeds=(0, 1), eval_episodes=5)
    return settings.to_dict()


def test_search_json_records_its_format_and_reads_back() -> None:
    data = _settings()
    assert data["format"] == scale.SEARCH_FORMAT == "heartpole-search/1"
    assert scale.SearchSettings.from_dict(data).to_dict() == data
    legacy = {k: v for k, v in data.items() if k != "format"}  # written before the field existed
    assert scale.SearchSettings.from_dict(legacy).to_dict() == data


DAMAGED = {
    "not JSON": ('{"trials": 3,', "Expecting"),
    "not an object": ("[1, 2]", "expected a JSON object"),
    "another version": (json.dumps({**_settings(), "format": "heartpole-search/2"}), "resumes 'heartpole-search/1'"),
    "a key missing": (json.dumps({k: v for k, v in _settings().items() if k != "seeds"}), "keys"),
    "an unknown key": (json.dumps({**_settings(), "grid": 1}), "keys"),
    "bad trials": (json.dumps({**_settings(), "trials": "3"}), "trials must be an integer in [1, 10,000]"),
    "bad seeds": (json.dumps({**_settings(), "seeds": 7}), "seeds must be a list"),
    "bad base": (json.dumps({**_settings(), "base": {"algo": "sac"}}), "base: unknown algorithm"),
    "binary": ("\udcff", ""),
}


@pytest.mark.parametrize("case", DAMAGED, ids=list(DAMAGED))
def test_resume_refuses_a_damaged_or_other_version_search_json(tmp_path: Path, capsys, case: str) -> None:
    text, fragment = DAMAGED[case]
    out = _search_folder(tmp_path, "")
    (out / scale.SEARCH_SETTINGS_FILE).write_bytes(text.encode("utf-8", "surrogateescape"))
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    assert main(["tune", "--resume", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "is not the settings of a search this HeartPole can resume" in err and fragment in err
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before  # nothing written or removed
