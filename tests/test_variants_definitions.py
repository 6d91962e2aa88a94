"""Users' variants defined badly: each definition fails when it is made, with a message naming what is
wrong and what is accepted."""

from __future__ import annotations

import math

import gymnasium as gym
import pytest

import heartpole
from heartpole import Action, Variable
from heartpole.actions import (
    DRINK_TEA,
    MAX_REST_HALF_HOURS,
    as_action,
)

BAD_IDS = [
    ("MyPole", "Name-vN"),
    ("MyPole-v", "Name-vN"),
    ("MyPole-v01", "Name-vN"),
    ("My Pole-v0", "Name-vN"),
    ("-v0", "Name-vN"),
    ("1Pole-v0", "Name-vN"),
    (7, "Name-vN"),
    ("HeartPole-v0", "built into"),
    ("HeartPole-v1", "built into"),
    ("CartPole-v1", "already registered"),
]

TEA = {"name": "drink_tea", "effects": {"alertness": (0.0, 0.5)}}
STRESS = Variable("stress", 0.0, decay=0.8)

BAD_DEFINITIONS = [
    # actions: the wrong shape or missing fields
    ({"actions": DRINK_TEA}, "actions must be a list"),
    ({"actions": TEA}, "actions must be a list"),
    ({"actions": "drink_tea"}, "actions must be a list"),
    ({"actions": [("drink_tea", {"alertness": (0, 1)})]}, r"action #0 must be a heartpole.Action or a mapping"),
    ({"actions": [{"effects": {"alertness": (0, 1)}}]}, "action #0 is missing its 'name'"),
    ({"actions": [{"name": "tea", "effect": {}}]}, r"unknown field\(s\) \['effect'\]; accepted fields are"),
    ({"actions": [{"name": "tea", "effects": {"alertness": (0.5,)}}]}, r"must be a \(low, high\) pair"),
    ({"actions": [{"name": "tea", "effects": {"alertness": (0, 1, 2)}}]}, r"must be a \(low, high\) pair"),
    ({"actions": [{"name": "tea", "effects": {"alertness": (1.0, 0.5)}}]}, "low <= high"),
    ({"actions": [{"name": "tea", "effects": {"alertness": (0.0, math.nan)}}]}, "must be a finite number, got nan"),
    ({"actions": [{"name": "tea", "effects": {"alertness": (0.0, math.inf)}}]}, "must be a finite number, got inf"),
    ({"actions": [{"name": "tea", "effects": [("alertness", 0, 1)]}]}, "effects must be a mapping"),
    ({"actions": [{"name": "drink tea"}]}, "identifier"),
    ({"actions": [{"name": "nap", "rest_half_hours": -1}]}, "rest_half_hours must be an integer >= 0"),
    ({"actions": [{"name": "nap", "rest_half_hours": 1.5}]}, "rest_half_hours must be an integer >= 0"),
    ({"actions": [{"name": "nap", "rest_half_hours": MAX_REST_HALF_HOURS + 1}]}, "at most 48"),
    ({"actions": [{"name": "nap", "sleeps": "yes"}]}, "sleeps must be True or False"),
    ({"actions": []}, "at least one action"),
    ({"actions": [TEA, TEA]}, "action names must be unique"),
    ({"actions": [{"name": "x", "effects": {"stress": (0, 1)}}]}, r"changes 'stress', which is not a state variable"),
    ({"actions": [{"name": "x", "effects": {"work_done": (0, 1)}}]}, "may not change 'work_done'"),
    ({"actions": [{"name": "x", "effects": {"time_elapsed": (-1, 0)}}]}, "may not change 'time_elapsed'"),
    ({"actions": heartpole.V1_ACTIONS}, r"changes 'thc', which is not a state variable.*Variable\('thc'"),
    # variables
    ({"variables": [STRESS]}, "first six variables must be v0's exactly"),
    ({"variables": [STRESS, *heartpole.V0_VARIABLES]}, "first six variables must be v0's exactly"),
    ({"variables": [Variable("alertness", 0.0), *heartpole.V0_VARIABLES[1:]]}, "v0's exactly"),
    ({"variables": (*heartpole.V0_VARIABLES, STRESS, STRESS)}, r"unique; \['stress'\] appear"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "low": 1.0})}, "low <= 0 <= high"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "low": -2.0, "high": -1.0})}, "low <= 0 <= high"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "low": math.nan})}, "low must be a number"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "decay": 0.0})}, r"decay must be None.*\(0, 1\]"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "decay": 1.5})}, "decay must be None"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "decay": "fast"})}, "decay must be None"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "anxiety_relief": math.inf})}, "anxiety_relief"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "my stress"})}, "identifier"),
    ({"variables": (*heartpole.V0_VARIABLES, {"name": "stress", "fade": 0.9})}, r"unknown field\(s\) \['fade'\]"),
    ({"variables": (*heartpole.V0_VARIABLES, {"low": 0.0})}, "variable #6 is missing its 'name'"),
    ({"variables": (*heartpole.V0_VARIABLES, "stress")}, "variable #6 must be a heartpole.Variable"),
    ({"variables": STRESS}, "variables must be a list"),
    (
        {
            "actions": [{"name": "x", "effects": {"stress": (0, 1)}}],
            "variables": (*heartpole.V0_VARIABLES, Variable("stress", 0.0, 1.0)),
        },
        "does not cap them",
    ),
    # parameters
    ({"heart_attack_proclivity": 1.5}, r"heart_attack_proclivity must be a finite number in \[0.0, 1.0\]"),
    ({"heart_attack_proclivity": -0.1}, "heart_attack_proclivity"),
    ({"max_steps": 0}, r"max_steps must be an integer in \[1, 9,007,199,254,740,992\]"),
    ({"max_steps": 10**20}, r"max_steps must be an integer in \[1, 9,007,199,254,740,992\], got 100000000000000000000"),
    ({"max_steps": 10.5}, r"max_steps must be an integer in \[1, 9,007,199,254,740,992\]"),
    ({"decay_rate": 0.0}, r"decay_rate must be a finite number in \(0.0, 1.0\]"),
    ({"decay_rate": 1.2}, "decay_rate"),
    ({"sleep_half_hours": -1}, "sleep_half_hours must be an integer >= 0"),
    ({"heart_attack_penalty": -5}, "heart_attack_penalty"),
    ({"wake_alertness": (1.3, 0.7)}, "wake_alertness must be"),
    ({"wake_alertness": 1.0}, "wake_alertness must be"),
    ({"replace": "yes"}, "replace must be True or False"),
]


@pytest.mark.parametrize("env_id, message", BAD_IDS, ids=[str(i) for i, _ in BAD_IDS])
def test_bad_ids_are_refused(env_id, message: str) -> None:
    before = dict(gym.registry)
    with pytest.raises(ValueError, match=message):
        heartpole.register_variant(env_id)
    assert dict(gym.registry) == before


@pytest.mark.parametrize(
    "definition, message", BAD_DEFINITIONS, ids=[f"{i}-{m[:24]}" for i, (_, m) in enumerate(BAD_DEFINITIONS)]
)
def test_bad_definitions_fail_when_defined(definition: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message) as raised:
        heartpole.register_variant("BadPole-v0", **definition)
    assert str(raised.value).startswith("HeartPole variant 'BadPole-v0': ") or "replace" in definition
    assert "BadPole-v0" not in gym.registry


@pytest.mark.parametrize(
    "definition",
    [
        {"actions": [{"name": "x", "effects": {"work_done": (0, 1)}}]},
        {"actions": [TEA, TEA]},
        {"variables": (*heartpole.V0_VARIABLES, STRESS, STRESS)},
        {"variables": [STRESS, *heartpole.V0_VARIABLES]},
        {"actions": heartpole.V1_ACTIONS},
    ],
)
def test_an_env_and_a_variant_refuse_a_definition_by_one_rule(definition: dict) -> None:
    """A variant's rules live in one place (heartpole.dynamics), so the env's constructor and register_variant
    refuse a bad definition with the same message."""
    objects = {
        "actions": [as_action(a) for a in definition.get("actions", heartpole.V0_ACTIONS)],
        "variables": definition.get("variables", heartpole.V0_VARIABLES),
    }
    with pytest.raises(ValueError) as by_env:
        heartpole.HeartPole(**objects)
    with pytest.raises(ValueError) as by_variant:
        heartpole.register_variant("BadPole-v0", **definition)
    assert str(by_variant.value) == f"HeartPole variant 'BadPole-v0': {by_env.value}"


def test_an_action_checks_its_own_rest() -> None:
    with pytest.raises(ValueError, match="Action 'nap' rests 49 half-hours; at most 48"):
        Action("nap", rest_half_hours=MAX_REST_HALF_HOURS + 1)


@pytest.mark.parametrize(
    "keywords, message",
    [
        ({"sleepiness": 3}, r"^register_variant\(\) got an unexpected keyword argument 'sleepiness'; it accepts \["),
        ({"render_mode": "ansi"}, r"argument 'render_mode': it is chosen when making the env.*gymnasium.make"),
        ({"num_envs": 4}, r"argument 'num_envs'.*gymnasium.make_vec"),
        ({"max_episode_steps": 9}, r"argument 'max_episode_steps'.*pass max_steps=9"),
    ],
)
def test_unexpected_keywords_are_type_errors(keywords: dict, message: str) -> None:
    before = dict(gym.registry)
    with pytest.raises(TypeError, match=message):
        heartpole.register_variant("BadPole-v0", **keywords)
    assert dict(gym.registry) == before


def test_gymnasiums_own_id_rules_become_a_value_error_too() -> None:
    gym.register("OddPole", entry_point="heartpole.env:HeartPole")
    try:
        with pytest.raises(ValueError, match="HeartPole variant 'OddPole-v0': .*unversioned environment"):
            heartpole.register_variant("OddPole-v0")
        assert "OddPole-v0" not in gym.registry
    finally:
        gym.registry.pop("OddPole")


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"low": 5.0}, "low <= 0 <= high"),
        ({"decay": "fast"}, "decay must be None"),
        ({"anxiety_relief": math.nan}, "anxiety_relief"),
        ({"description": 3}, "description must be a string"),
    ],
)
def test_a_variable_checks_its_own_fields_when_it_is_made(fields, message) -> None:
    """Before, Variable("stress", low=5.0) was accepted and the env returned observations outside its own
    observation_space; decay="fast" failed with a TypeError inside a step."""
    with pytest.raises(ValueError, match=message):
        Variable("stress", **fields)
