"""``heartpole play``: a person plays HeartPole in the terminal, one key per half-hour.

The state is printed every half-hour; one key chooses the next action (no Enter needed when stdin is a
terminal; piped keys work too). ``q`` (or Ctrl-D) ends the game early with the summary; Ctrl-C ends it
at once. The summary sets the player's return, score and heart attacks beside the built-in policies'
over episodes of the same length and seed. The game itself is [`heartpole.game`][heartpole.game]; this module parses,
calls it and prints.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import TextIO

from heartpole import files
from heartpole.cli.common import CommandError, Subparsers, format_table, heartpole_env, positive_int, seed_int
from heartpole.game import (
    Game,
    KeyReader,
    Standing,
    baseline_standings,
    new_game,
    place,
    play_turns,
    standings,
    verdict,
)

ORDER = 40

DEFAULT_ENV = "HeartPole-v0"
DEFAULT_STEPS = 100


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
def play(args: argparse.Namespace) -> int:
    """``heartpole play``: run the game, then print the summary."""
    import numpy as np

    seed = args.seed if args.seed is not None else int(np.random.default_rng().integers(0, 2**31))
    try:
        game = new_game(heartpole_env(args.env), args.steps, seed)
    except ValueError as error:
        raise CommandError(str(error)) from None
    out = sys.stdout
    _intro(game, args.steps, seed, out)
    reader = KeyReader(sys.stdin)
    try:
        with reader.keys():
            finished = play_turns(game, reader, args.steps, out)
    except KeyboardInterrupt:  # Ctrl-C, or SIGTERM or SIGHUP (heartpole.files.signal_policy)
        try:
            out.write("\nInterrupted.\n" + game.summary_line() + "\n")
            out.flush()
        except OSError:
            pass  # SIGHUP: the terminal is gone
        return files.exit_code()
    if not finished:
        out.write(f"\nYou stopped after {game.steps} of {args.steps} half-hour decisions.\n")
    _summary(game, args, seed, out)
    return 0


def _intro(game: Game, steps: int, seed: int, out: TextIO) -> None:
    out.write(
        "HeartPole: you are at work. Every half-hour you choose what to do, then you\n"
        "work for a half-hour. Coffee wakes you up, beer may put you at the Ballmer\n"
        "peak, sleep takes 8 hours and restores you. Every drink raises your blood\n"
        "pressure, and high blood pressure risks a heart attack (-100 reward).\n"
        "Your score is work done per half-hour, sleep included.\n"
        f"{steps} decisions, seed {seed}. One key per move, no Enter needed.\n\n"
    )
    out.write("\n".join(game.status(steps)) + "\n")


def _summary(game: Game, args: argparse.Namespace, seed: int, out: TextIO) -> None:
    """The player's result beside the built-in policies' over episodes as long as the player's."""
    out.write("\n=== Summary ===\n" + game.summary_line() + "\n")
    if game.steps == 0:
        return
    out.write("Your choices: " + ", ".join(f"{n.replace('_', ' ')} {c}" for n, c in game.choices().items()) + "\n")
    out.write(
        f"Your expected return {game.expected_return:.3f} = score - {game.penalty:g} x the heart-attack risk you "
        "ran:\nwhat your choices earn without the luck of the coin. Policies are ranked by it.\n"
        f"\nThe built-in policies over {args.baseline_episodes} episodes of {game.steps} decisions (seed {seed}):\n"
    )
    out.flush()
    ranked = standings(Standing.of_player(game), baseline_standings(args.env, game.steps, args.baseline_episodes, seed))
    headers = ["policy", "expected return", "return (95% CI)", "heart attacks", "score"]
    out.write(format_table(headers, [_row(standing) for standing in ranked]) + "\n")
    out.write(f"\nYou placed {place(ranked)} of {len(ranked)}. {verdict(ranked)}\n")


def _row(standing: Standing) -> list[str]:
    """A standing as table cells: the player's return is of one episode, a policy's has its interval."""
    if standing.ci95 is None:
        realized = f"{standing.mean_return:.3f} (one episode)"
        attacks = str(int(standing.heart_attacks))
    else:
        low, high = standing.ci95
        realized = f"{standing.mean_return:.3f}" + (f" [{low:.2f}, {high:.2f}]" if math.isfinite(low) else "")
        attacks = f"{standing.heart_attacks:.3f}"
    return [standing.name, f"{standing.expected_return:.3f}", realized, attacks, f"{standing.score:.3f}"]
