"""heartpole.game: the game ``heartpole play`` runs in a terminal, driven here through streams."""

from __future__ import annotations

import io

import pytest

from heartpole.game import (
    KeyReader,
    Standing,
    baseline_standings,
    new_game,
    place,
    play_turns,
    standings,
    verdict,
)


def test_a_game_keeps_the_tally_of_its_steps() -> None:
    game = new_game("HeartPole-v0", steps=10, seed=1)
    risks, infos = [], []
    for action in (1, 2, 0, 3):
        info = game.take(action)
        risks.append(info["heart_attack_risk"])
        infos.append(info)
    assert game.steps == 4 and game.actions == ["drink_coffee", "drink_beer", "do_nothing", "sleep"]
    assert game.risk_taken == pytest.approx(sum(risks))
    assert game.score == infos[-1]["score"]
    assert game.expected_return == pytest.approx(game.score - 100.0 * game.risk_taken)
    assert game.choices() == {"drink_coffee": 1, "drink_beer": 1, "do_nothing": 1, "sleep": 1}
    assert game.summary_line().startswith("You: 4 decisions, return ")


def test_a_new_game_refuses_what_is_not_heartpole() -> None:
    with pytest.raises(ValueError, match="cannot play 'Nope-v0'"):
        new_game("Nope-v0", 5, 0)
    with pytest.raises(ValueError, match="'CartPole-v1' is not a HeartPole env"):
        new_game("CartPole-v1", 5, 0)


def test_the_key_reader_skips_newlines_and_ends_with_the_input() -> None:
    reader = KeyReader(io.StringIO("c\n\rb"))
    assert not reader.is_terminal
    with reader.keys():
        assert [reader.read(), reader.read(), reader.read()] == ["c", "b", ""]


@pytest.mark.parametrize(("keys", "finished", "steps"), [("cbs", True, 3), ("czq", False, 1), ("c", False, 1)])
def test_turns_end_after_the_steps_on_q_or_at_the_end_of_input(keys: str, finished: bool, steps: int) -> None:
    game = new_game("HeartPole-v0", steps=3, seed=0)
    out = io.StringIO()
    assert play_turns(game, KeyReader(io.StringIO(keys)), 3, out) is finished
    assert game.steps == steps
    text = out.getvalue()
    assert text.count("You chose") == steps
    assert ("Not a key of this game" in text) == ("z" in keys)
    assert text.count("(step ") == steps  # one status after each step


def test_standings_rank_by_the_expected_return_and_say_where_the_player_stands() -> None:
    def row(name: str, expected: float) -> Standing:
        return Standing(name, expected, 0.0, (0.0, 0.0), 0.0, 0.0)

    you = Standing("you", 0.1, 5.0, None, 0, 0.3)  # a lucky realized return does not count
    ranked = standings(you, [row("random", -1.0), row("expert", 0.2), row("nothing", 0.1)])
    assert [r.name for r in ranked] == ["expert", "nothing", "you", "random"]  # ties: the player last
    assert place(ranked) == 3 and verdict(ranked) == "You beat: random."
    first = standings(Standing("you", 9.0, 0.0, None, 0, 0.0), [row("expert", 0.2)])
    assert place(first) == 1 and verdict(first) == "Better than every built-in policy."
    last = standings(Standing("you", -9.0, 0.0, None, 0, 0.0), [row("expert", 0.2)])
    assert verdict(last) == "Every built-in policy did better."


def test_the_baselines_are_the_built_in_policies_evaluated_on_the_players_episode_length() -> None:
    from heartpole.evaluation import evaluate

    rows = baseline_standings("HeartPole-v0", 5, 20, 3)
    names = [row.name for row in rows]
    assert {"random", "nothing", "coffee", "reference", "expert"} <= set(names)
    nothing = rows[names.index("nothing")]
    again = evaluate("nothing", "HeartPole-v0", 20, 3, env_kwargs={"max_steps": 5})
    assert nothing.expected_return == again.expected_return and nothing.ci95 == again.ci95


def test_a_game_longer_than_the_registered_limit_is_not_cut_short() -> None:
    """gymnasium.make kept a TimeLimit at the spec's 1,000 decisions: ``play --steps 1500`` ended at 1,000."""
    import gymnasium as gym

    game = new_game("HeartPole-v0", steps=1500, seed=0)
    limits = [e._max_episode_steps for e in _wrappers(game.env) if isinstance(e, gym.wrappers.TimeLimit)]
    assert limits == [] and game.env.unwrapped.max_steps == game.env.spec.max_episode_steps == 1500


def _wrappers(env: object) -> list[object]:
    found = []
    while env is not None:
        found.append(env)
        env = getattr(env, "env", None)
    return found
