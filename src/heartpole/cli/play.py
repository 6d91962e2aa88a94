"""``heartpole play``: a person plays HeartPole in the terminal, one key per half-hour.

The state is printed every half-hour; one key chooses the next action (no Enter needed when stdin is a
terminal; piped keys work too). ``q`` (or Ctrl-D) ends the game early with the summary; Ctrl-C ends it
at once. The summary sets the player's return, score and heart attacks beside the built-in policies'
over episodes of the same length and seed.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TextIO, cast

from heartpole.cli.common import CommandError, Subparsers, format_table, positive_int, seed_int

if TYPE_CHECKING:
    from heartpole.env import HeartPole

ORDER = 40

DEFAULT_ENV = "HeartPole-v0"
DEFAULT_STEPS = 100
QUIT_KEYS = ("q", "Q", "\x04")  # q, or Ctrl-D (which arrives as a byte when the terminal is in cbreak mode)
BAR_WIDTH = 16


def register(subparsers: Subparsers) -> None:
    """Add ``play`` to the ``heartpole`` command."""
    parser = subparsers.add_parser(
        "play",
        help="play HeartPole yourself in the terminal",
        description="Play HeartPole: every half-hour press one key to choose what to do, watch your alertness, "
        "blood pressure and score, and see how you did against the built-in policies. "
        "q quits with a summary, Ctrl-C quits at once.",
    )
    parser.add_argument(
        "--steps",
        type=positive_int,
        default=DEFAULT_STEPS,
        help=f"decisions in your episode ({DEFAULT_STEPS}; the env's standard episode is 1000)",
    )
    parser.add_argument(
        "--seed",
        type=seed_int,
        default=None,
        help="seed of your episode and of the baselines' (default: a new random one)",
    )
    parser.add_argument(
        "--baseline-episodes",
        type=positive_int,
        default=200,
        metavar="N",
        help="episodes per built-in policy for the comparison (200)",
    )
    parser.add_argument("--env", default=DEFAULT_ENV, metavar="ID", help=f"HeartPole env id ({DEFAULT_ENV})")
    parser.set_defaults(handler=play)


# --------------------------------------------------------------------------------------------------------
@dataclass
class Game:
    """A game in progress: the env, the keys, the player's tally."""

    env: Any
    keys: dict[str, int]
    observation: Any = None
    steps: int = 0
    total_return: float = 0.0
    heart_attacks: int = 0
    risk_taken: float = 0.0
    score: float = 0.0
    actions: list[str] = field(default_factory=list)


def action_keys(names: Sequence[str]) -> dict[str, int]:
    """One letter per action (the first free letter of its last word, then of its other words) and its digit.

    v0 gets ``n`` do_nothing, ``c`` drink_coffee, ``b`` drink_beer, ``s`` sleep; ``0``-``9`` work too.
    """
    keys: dict[str, int] = {}
    for index, name in enumerate(names):
        words = name.lower().split("_")
        candidates = "".join(words[-1:] + words[:-1])
        letter = next((c for c in candidates if c.isalpha() and c not in keys and c != "q"), None)
        if letter is not None:
            keys[letter] = index
    keys.update({str(index): index for index in range(min(len(names), 10))})
    return keys


def _prompt(game: Game) -> str:
    """The question of every half-hour, wrapped to 80 columns: one ``key=action`` per action, then quit."""
    names = [a.name for a in game.env.unwrapped.actions]
    letters = {index: key for key, index in game.keys.items() if key.isalpha()}
    options = [f"{letters.get(i, str(i))}={name.replace('_', ' ')}" for i, name in enumerate(names)] + ["q=quit"]
    lines = ["Your move?"]
    for option in options:
        if len(lines[-1]) + 2 + len(option) > 76:
            lines.append(" ")
        lines[-1] += "  " + option
    return "\n".join(lines) + " > "


def _bar(value: float, full: float) -> str:
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
        f"  alertness      {state['alertness']:7.2f} {_bar(state['alertness'], ALERTNESS_RANGE)}"
        f" best {marks.best_alertness:.1f}, anxious > {marks.anxious:g}",
        f"  blood pressure {state['hypertension']:7.2f} {_bar(state['hypertension'], HYPERTENSION_RANGE)}"
        f" heart-attack risk {100 * risk:.2f}%",
        f"  intoxication   {state['intoxication']:7.3f} {_bar(state['intoxication'], INTOXICATION_RANGE)}"
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
    """Single keys from stdin: unbuffered and unechoed when stdin is a terminal, else character by character."""

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
                data = os.read(self.fd, 1)
                key = data.decode("latin-1")
            else:
                key = self.stream.read(1)
            if key not in ("\n", "\r"):
                return key


# --------------------------------------------------------------------------------------------------------
def play(args: argparse.Namespace) -> int:
    """``heartpole play``: run the game, then print the summary."""
    import numpy as np

    seed = args.seed if args.seed is not None else int(np.random.default_rng().integers(0, 2**31))
    game = _new_game(args.env, args.steps, seed)
    out = sys.stdout
    _intro(game, args.steps, seed, out)
    reader = KeyReader(sys.stdin)
    try:
        with reader.keys():
            finished = _loop(game, reader, args.steps, out)
    except KeyboardInterrupt:
        out.write("\nInterrupted.\n")
        _summary_line(game, out)
        out.flush()
        return 130
    if not finished:
        out.write(f"\nYou stopped after {game.steps} of {args.steps} half-hour decisions.\n")
    _summary(game, args, seed, out)
    return 0


def _new_game(env_id: str, steps: int, seed: int) -> Game:
    import gymnasium as gym

    try:
        env = gym.make(env_id, max_steps=steps)
    except gym.error.Error as error:
        raise CommandError(f"cannot play {env_id!r}: {error}") from None
    except TypeError:  # it does not take HeartPole's arguments
        raise CommandError(f"env {env_id!r} is not a HeartPole env") from None
    if not hasattr(env.unwrapped, "dynamics"):
        raise CommandError(f"env {env_id!r} is not a HeartPole env")
    game = Game(env=env, keys=action_keys([a.name for a in cast("HeartPole", env.unwrapped).actions]))
    game.observation, _ = env.reset(seed=seed)
    return game


def _intro(game: Game, steps: int, seed: int, out: TextIO) -> None:
    out.write(
        "HeartPole: you are at work. Every half-hour you choose what to do, then you\n"
        "work for a half-hour. Coffee wakes you up, beer may put you at the Ballmer\n"
        "peak, sleep takes 8 hours and restores you. Every drink raises your blood\n"
        "pressure, and high blood pressure risks a heart attack (-100 reward).\n"
        "Your score is work done per half-hour, sleep included.\n"
        f"{steps} decisions, seed {seed}. One key per move, no Enter needed.\n\n"
    )
    out.write("\n".join(status_lines(game.env.unwrapped.state, 0, steps, 0)) + "\n")


def _loop(game: Game, reader: KeyReader, steps: int, out: TextIO) -> bool:
    """Play until the episode ends (True) or the player quits (False)."""
    while game.steps < steps:
        out.write(_prompt(game))
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
        _take(game, game.keys[key], steps, out)
    return True


def _take(game: Game, action: int, steps: int, out: TextIO) -> None:
    game.observation, reward, _, _, info = game.env.step(action)
    game.steps += 1
    game.total_return += float(reward)
    game.heart_attacks += bool(info["heart_attack"])
    game.risk_taken += float(info["heart_attack_risk"])
    game.score = float(info["score"])
    game.actions.append(info["action"])
    out.write(f"You chose {info['action'].replace('_', ' ')}; this half-hour earned {info['productivity']:.2f}.\n")
    if info["heart_attack"]:
        penalty = game.env.unwrapped.dynamics.params.heart_attack_penalty
        out.write(_red(f"*** HEART ATTACK! *** -{penalty:g}. Your blood pressure is back to 0.", out) + "\n")
    out.write("\n".join(status_lines(game.env.unwrapped.state, game.steps, steps, game.heart_attacks)) + "\n")


def _red(text: str, out: TextIO) -> str:
    """``text`` in red on a colour terminal (not when NO_COLOR is set)."""
    colour = getattr(out, "isatty", lambda: False)() and "NO_COLOR" not in os.environ
    return f"\x1b[1;31m{text}\x1b[0m" if colour else text


def _summary_line(game: Game, out: TextIO) -> None:
    out.write(
        f"You: {game.steps} decisions, return {game.total_return:.3f}, score {game.score:.3f}, "
        f"heart attacks {game.heart_attacks}\n"
    )


def expected_return(game: Game) -> float:
    """The player's score minus the penalty times the heart-attack risk taken: the return without the luck."""
    penalty = game.env.unwrapped.dynamics.params.heart_attack_penalty
    return game.score - penalty * game.risk_taken


def _summary(game: Game, args: argparse.Namespace, seed: int, out: TextIO) -> None:
    """The player's result beside the built-in policies' over episodes as long as the player's."""
    out.write("\n=== Summary ===\n")
    _summary_line(game, out)
    if game.steps == 0:
        return
    counts = {name: game.actions.count(name) for name in dict.fromkeys(game.actions)}
    out.write("Your choices: " + ", ".join(f"{n.replace('_', ' ')} {c}" for n, c in counts.items()) + "\n")
    penalty = game.env.unwrapped.dynamics.params.heart_attack_penalty
    out.write(
        f"Your expected return {expected_return(game):.3f} = score - {penalty:g} x the heart-attack risk you ran:\n"
        "what your choices earn without the luck of the coin. Policies are ranked by it.\n"
        f"\nThe built-in policies over {args.baseline_episodes} episodes of {game.steps} decisions (seed {seed}):\n"
    )
    out.flush()
    ranked = _baseline_rows(args.env, game.steps, args.baseline_episodes, seed)
    you = ["you", f"{expected_return(game):.3f}", f"{game.total_return:.3f} (one episode)", str(game.heart_attacks)]
    ranked.append((expected_return(game), [*you, f"{game.score:.3f}"]))
    ranked.sort(key=lambda pair: -pair[0])  # by the expected return itself, not its formatted text
    rows = [row for _, row in ranked]
    headers = ["policy", "expected return", "return (95% CI)", "heart attacks", "score"]
    out.write(format_table(headers, rows) + "\n")
    place = [row[0] for row in rows].index("you") + 1
    out.write(f"\nYou placed {place} of {len(rows)}. {_verdict(rows, place)}\n")


def _baseline_rows(env_id: str, steps: int, episodes: int, seed: int) -> list[tuple[float, list[str]]]:
    """One ``(expected return, row)`` per built-in policy; the row holds the expected return, the realized
    return with its interval, heart attacks and score, formatted."""
    from heartpole.evaluation import evaluate
    from heartpole.policies import available_builtins, load_policy

    rows = []
    for name in available_builtins(env_id, {"max_steps": steps}):
        policy = load_policy(name, env_id, env_kwargs={"max_steps": steps}, rng=seed)
        result = evaluate(policy, env_id, episodes, seed, env_kwargs={"max_steps": steps})
        low, high = result.ci95
        interval = f" [{low:.2f}, {high:.2f}]" if math.isfinite(low) else ""
        realized = f"{result.mean_return:.3f}{interval}"
        attacks = f"{result.heart_attacks_per_episode:.3f}"
        rows.append(
            (result.expected_return, [name, f"{result.expected_return:.3f}", realized, attacks, f"{result.score:.3f}"])
        )
    return rows


def _verdict(rows: list[list[str]], place: int) -> str:
    if place == 1:
        return "Better than every built-in policy."
    beaten = [row[0] for row in rows[place:]]
    if not beaten:
        return "Every built-in policy did better."
    return "You beat: " + ", ".join(beaten) + "."
