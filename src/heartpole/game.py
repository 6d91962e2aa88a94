"""A person's game of HeartPole: the keys, what the player sees, the tally, and the standing.

``heartpole play`` is this module in a terminal: [`new_game`][heartpole.game.new_game] makes a
[`Game`][heartpole.game.Game] on a HeartPole env, [`play_turns`][heartpole.game.play_turns] asks for one key per
half-hour (read by a [`KeyReader`][heartpole.game.KeyReader]) and steps the env, and
[`standings`][heartpole.game.standings] ranks the player's [`Standing`][heartpole.game.Standing] beside the built-in
policies' by the expected-risk return, the return without the luck of the heart-attack coin.

A game can be driven without a terminal too:

>>> import io
>>> game = new_game("HeartPole-v0", steps=3, seed=0)
>>> sorted(key for key in game.keys if key.isalpha())
['b', 'c', 'n', 's']
>>> finished = play_turns(game, KeyReader(io.StringIO("c\\nn\\ns\\n")), 3, io.StringIO())
>>> finished, game.steps, game.actions
(True, 3, ['drink_coffee', 'do_nothing', 'sleep'])
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TextIO, cast

import numpy as np

from heartpole.rewards import expected_risk

if TYPE_CHECKING:
    import gymnasium as gym

    from heartpole.env import HeartPole

QUIT_KEYS = ("q", "Q", "\x04")
"""Keys that end a game early: q, or Ctrl-D (which arrives as a byte when the terminal is in cbreak mode)."""
BAR_WIDTH = 16
"""Characters of the bars drawn beside alertness, blood pressure and intoxication."""
PROMPT_WIDTH = 76
"""The prompt wraps before this column (80 with the ``" > "`` and a key)."""


@dataclass
class Game:
    """A game in progress: the env, the keys, the player's tally.

    Attributes:
        env: the HeartPole env, as `gymnasium.make` returned it.
        keys: which key takes which action (from [`action_keys`][heartpole.game.action_keys]).
        observation: the last observation.
        steps: decisions taken so far.
        total_return: the realized return so far.
        heart_attacks: heart attacks so far.
        risk_taken: the summed heart-attack probabilities of the steps taken.
        score: the score after the last step (work done / time elapsed).
        actions: the names of the actions taken, in order.
    """

    env: gym.Env[np.ndarray, int]
    keys: dict[str, int]
    observation: np.ndarray | None = None
    steps: int = 0
    total_return: float = 0.0
    heart_attacks: int = 0
    risk_taken: float = 0.0
    score: float = 0.0
    actions: list[str] = field(default_factory=list)

    @property
    def heartpole(self) -> HeartPole:
        """The unwrapped HeartPole env."""
        return cast("HeartPole", self.env.unwrapped)

    @property
    def penalty(self) -> float:
        """What a heart attack costs in this env's reward."""
        return float(self.heartpole.dynamics.params.heart_attack_penalty)

    @property
    def expected_return(self) -> float:
        """The player's score minus the penalty times the heart-attack risk taken: the return without the luck."""
        return float(expected_risk(self.score, self.risk_taken, self.penalty))

    def choices(self) -> dict[str, int]:
        """How often each action was taken, in the order first taken."""
        return {name: self.actions.count(name) for name in dict.fromkeys(self.actions)}

    def take(self, action: int) -> dict[str, Any]:
        """Step the env with ``action``, add the step to the tally and return the step's ``info``."""
        self.observation, reward, _, _, info = self.env.step(action)
        self.steps += 1
        self.total_return += float(reward)
        self.heart_attacks += bool(info["heart_attack"])
        self.risk_taken += float(info["heart_attack_risk"])
        self.score = float(info["score"])
        self.actions.append(self.heartpole.action_names[info["action_taken"]])
        return info

    def status(self, max_steps: int) -> list[str]:
        """[`status_lines`][heartpole.game.status_lines] of the current state."""
        return status_lines(self.heartpole.state, self.steps, max_steps, self.heart_attacks)

    def summary_line(self) -> str:
        """The tally in one line."""
        return (
            f"You: {self.steps} decisions, return {self.total_return:.3f}, score {self.score:.3f}, "
            f"heart attacks {self.heart_attacks}"
        )


def new_game(env_id: str, steps: int, seed: int) -> Game:
    """A game of ``steps`` decisions on ``env_id``, reset with ``seed``.

    Raises:
        ValueError: ``env_id`` is not registered, or not a HeartPole env.
    """
    import gymnasium as gym

    try:
        env = gym.make(env_id, max_steps=steps)
    except gym.error.Error as error:
        raise ValueError(f"cannot play {env_id!r}: {error}") from None
    except TypeError:  # it does not take HeartPole's arguments
        raise ValueError(f"env {env_id!r} is not a HeartPole env") from None
    if not hasattr(env.unwrapped, "dynamics"):
        raise ValueError(f"env {env_id!r} is not a HeartPole env")
    game = Game(env=env, keys=action_keys([a.name for a in cast("HeartPole", env.unwrapped).actions]))
    game.observation, _ = env.reset(seed=seed)
    return game


def action_keys(names: Sequence[str]) -> dict[str, int]:
    """One letter per action (the first free letter of its last word, then of its other words) and its digit.

    >>> action_keys(["do_nothing", "drink_coffee", "drink_beer", "sleep"])
    {'n': 0, 'c': 1, 'b': 2, 's': 3, '0': 0, '1': 1, '2': 2, '3': 3}
    """
    keys: dict[str, int] = {}
    for index, name in enumerate(names):
        words = name.lower().split("_")
        candidates = "".join(words[-1:] + words[:-1])
        letter = next((c for c in candidates if c.isalpha() and c not in keys and c not in QUIT_KEYS), None)
        if letter is not None:
            keys[letter] = index
    keys.update({str(index): index for index in range(min(len(names), 10))})
    return keys


def prompt(game: Game) -> str:
    """The question of every half-hour, wrapped to 80 columns: one ``key=action`` per action, then quit."""
    names = [a.name for a in game.heartpole.actions]
    letters = {index: key for key, index in game.keys.items() if key.isalpha()}
    options = [f"{letters.get(i, str(i))}={name.replace('_', ' ')}" for i, name in enumerate(names)] + ["q=quit"]
    lines = ["Your move?"]
    for option in options:
        if len(lines[-1]) + 2 + len(option) > PROMPT_WIDTH:
            lines.append(" ")
        lines[-1] += "  " + option
    return "\n".join(lines) + " > "


def bar(value: float, full: float) -> str:
    """``value`` as a bar of [`BAR_WIDTH`][heartpole.game.BAR_WIDTH] characters, full at ``full`` (clipped to [0,
    full]).

    >>> bar(2.5, 5.0)
    '[########........]'
    """
    filled = int(round(max(min(value / full, 1.0), 0.0) * BAR_WIDTH))
    return "[" + "#" * filled + "." * (BAR_WIDTH - filled) + "]"


def status_lines(state: dict[str, float], step: int, max_steps: int, heart_attacks: int) -> list[str]:
    """What the player sees every half-hour: the clock, the body, the work (lines of at most 80 characters)."""
    from heartpole import model
    from heartpole.render import ALERTNESS_RANGE, HYPERTENSION_RANGE, INTOXICATION_RANGE, clock, landmarks

    marks = landmarks()
    day, hour, minute = clock(state["time_elapsed"])
    risk = float(model.heart_attack_risk(state["hypertension"]))
    score = float(model.score(state["work_done"], state["time_elapsed"]))
    header = f"--- Day {day} {hour:02d}:{minute:02d}  (step {step}/{max_steps}) "
    lines = [
        header + "-" * max(60 - len(header), 3),
        f"  alertness      {state['alertness']:7.2f} {bar(state['alertness'], ALERTNESS_RANGE)}"
        f" best {marks.best_alertness:.1f}, anxious > {marks.anxious:g}",
        f"  blood pressure {state['hypertension']:7.2f} {bar(state['hypertension'], HYPERTENSION_RANGE)}"
        f" heart-attack risk {100 * risk:.2f}%",
        f"  intoxication   {state['intoxication']:7.3f} {bar(state['intoxication'], INTOXICATION_RANGE)}"
        f" Ballmer peak {marks.ballmer_peak:.3f}",
        f"  awake for      {state['time_since_slept'] / 2:7.1f} h"
        f"  (alertness fades fast after {marks.fading_hours:g} h)",
    ]
    v0 = {"alertness", "hypertension", "intoxication", "time_since_slept", "time_elapsed", "work_done"}
    lines += [f"  {name.replace('_', ' '):<14} {value:7.3f}" for name, value in state.items() if name not in v0]
    lines.append(
        f"  work done {state['work_done']:.2f}   score {score:.3f} per half-hour   heart attacks {heart_attacks}"
    )
    return lines


# --------------------------------------------------------------------------------------------------------
class KeyReader:
    """Single keys from a stream: unbuffered and unechoed when it is a terminal, else character by character."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        try:
            self.fd: int | None = stream.fileno()
        except (AttributeError, OSError, ValueError):  # no file behind it (a test's StringIO, say)
            self.fd = None
        self.is_terminal = self.fd is not None and os.isatty(self.fd)

    @contextmanager
    def keys(self) -> Iterator[KeyReader]:
        """Put a terminal in cbreak mode (keys without Enter, no echo) and restore it afterwards, always."""
        if not self.is_terminal:
            yield self
            return
        import termios
        import tty

        assert self.fd is not None  # is_terminal
        saved = termios.tcgetattr(self.fd)
        try:
            tty.setcbreak(self.fd)
            yield self
        finally:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, saved)

    def read(self) -> str:
        """The next key that is not a newline or carriage return; ``""`` at the end of input."""
        while True:
            if self.is_terminal:
                assert self.fd is not None
                key = os.read(self.fd, 1).decode("latin-1")
            else:
                key = self.stream.read(1)
            if key not in ("\n", "\r"):
                return key


def play_turns(game: Game, reader: KeyReader, steps: int, out: TextIO) -> bool:
    """Ask for a key every half-hour and take its action until ``steps`` decisions are taken (True) or the
    player quits with a key of [`QUIT_KEYS`][heartpole.game.QUIT_KEYS] or at the end of input (False). Writes to
    ``out``."""
    while game.steps < steps:
        out.write(prompt(game))
        out.flush()
        key = reader.read()
        if key == "" or key in QUIT_KEYS:
            out.write("quit\n")
            return False
        if key not in game.keys:
            letters = ", ".join(k for k in game.keys if k.isalpha())
            out.write(f"{key!r}?\n  Not a key of this game: press {letters} (or a digit), q to quit.\n")
            continue
        out.write(key + "\n")
        info = game.take(game.keys[key])
        action = game.actions[-1].replace("_", " ")
        out.write(f"You chose {action}; this half-hour earned {info['productivity']:.2f}.\n")
        if info["heart_attack"]:
            alarm = f"*** HEART ATTACK! *** -{game.penalty:g}. Your blood pressure is back to 0."
            out.write(red(alarm, out) + "\n")
        out.write("\n".join(game.status(steps)) + "\n")
    return True


def red(text: str, out: TextIO) -> str:
    """``text`` in red when ``out`` is a colour terminal (not when NO_COLOR is set)."""
    colour = getattr(out, "isatty", lambda: False)() and "NO_COLOR" not in os.environ
    return f"\x1b[1;31m{text}\x1b[0m" if colour else text


# --------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Standing:
    """One row of the final table: a built-in policy's evaluation, or the player's one episode.

    Attributes:
        name: the policy's name, or ``"you"``.
        expected_return: the expected-risk return, by which rows are ranked.
        mean_return: the realized return (the player's: of the one episode).
        ci95: its 95% interval (``None`` for the player's one episode; NaN where the evaluation has none).
        heart_attacks: heart attacks per episode (the player's: in the episode).
        score: the final score.
    """

    name: str
    expected_return: float
    mean_return: float
    ci95: tuple[float, float] | None
    heart_attacks: float
    score: float

    @classmethod
    def of_player(cls, game: Game) -> Standing:
        """The player's row."""
        return cls("you", game.expected_return, game.total_return, None, game.heart_attacks, game.score)


def baseline_standings(env_id: str, steps: int, episodes: int, seed: int) -> list[Standing]:
    """Every built-in policy that runs on ``env_id``, evaluated over ``episodes`` episodes of ``steps``
    decisions with ``seed`` (the seed of the player's episode)."""
    from heartpole.evaluation import evaluate
    from heartpole.policies import available_builtins, load_policy

    env_kwargs = {"max_steps": steps}
    rows = []
    for name in available_builtins(env_id, env_kwargs):
        policy = load_policy(name, env_id, env_kwargs=env_kwargs, rng=seed)
        result = evaluate(policy, env_id, episodes, seed, env_kwargs=env_kwargs)
        rows.append(
            Standing(
                name,
                result.expected_return,
                result.mean_return,
                result.ci95,
                result.heart_attacks_per_episode,
                result.score,
            )
        )
    return rows


def standings(you: Standing, baselines: Sequence[Standing]) -> list[Standing]:
    """The player's row beside ``baselines``, best expected-risk return first (the player last among equals).

    Examples:
        >>> you = Standing("you", -1.0, 0.3, None, 0, 0.3)
        >>> baselines = [Standing("a", 0.5, 0.5, None, 0, 0.5), Standing("b", -2.0, 0.2, None, 0, 0.2)]
        >>> [row.name for row in standings(you, baselines)]
        ['a', 'you', 'b']
    """
    return sorted([*baselines, you], key=lambda row: -row.expected_return)


def place(ranked: Sequence[Standing]) -> int:
    """The player's place in ``ranked`` (1 is first)."""
    return [row.name for row in ranked].index("you") + 1


def verdict(ranked: Sequence[Standing]) -> str:
    """One sentence on the player's place in ``ranked``.

    >>> rows = [Standing(n, 1.0 - i, 0.0, None, 0, 0.0) for i, n in enumerate(["expert", "you", "random"])]
    >>> verdict(rows)
    'You beat: random.'
    """
    where = place(ranked)
    if where == 1:
        return "Better than every built-in policy."
    beaten = [row.name for row in ranked[where:]]
    if not beaten:
        return "Every built-in policy did better."
    return "You beat: " + ", ".join(beaten) + "."
