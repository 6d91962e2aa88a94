"""``heartpole plot`` (model, episode, training) and ``heartpole record``: HeartPole's pictures and videos.

They need the optional extra ``pip install "heartpole[plot]"`` (matplotlib; imageio and imageio-ffmpeg
for MP4 videos). Every output is checked before any work is done (its folder exists and is writable,
its type is supported) and written to a temporary file that is moved into place when complete, so a
failure never leaves a partial file behind.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from heartpole import files, paths, plots
from heartpole.cli.common import (
    CommandError,
    Subparsers,
    add_trust_pickles,
    output_file,
    output_files,
    positive_int,
    seed_int,
    tell_normalization,
)
from heartpole.cli.envs import add_env_options, choose_env
from heartpole.parameters import Params
from heartpole.progress import Progress, progress

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from heartpole.policies import Policy

ORDER = 30

INSTALL_HINT = 'install the plot extra: pip install "heartpole[plot]"'

DEFAULT_FPS = 8
"""``record``'s frames (half-hour decisions) per second."""
MAX_DRAWN_STEPS = 100_000
"""The longest episode ``plot episode`` draws and ``record`` films: 100,000 half-hour decisions are 5.7 years of
the game, a video of 3.5 hours at the default fps and a dashboard of 100,000 markers a panel; longer would run
for hours and be no picture of it."""


def register(subparsers: Subparsers) -> None:
    """Add ``plot`` (with ``model``, ``episode`` and ``training``) and ``record`` to the ``heartpole`` command."""
    plot = subparsers.add_parser(
        "plot",
        help="draw the model's curves, an episode or a learning curve as PNGs",
        description='Draw HeartPole as PNG figures (needs matplotlib: pip install "heartpole[plot]").',
    )
    kinds = plot.add_subparsers(dest="figure", metavar="FIGURE", required=True)
    _add_model(kinds)
    _add_episode(kinds)
    _add_training(kinds)
    _add_record(subparsers)


def _add_model(kinds: Subparsers) -> None:
    parser = kinds.add_parser(
        "model",
        help="the tutorial's curves and the productivity heat map",
        description="The tutorial's figures, drawn from heartpole.model: heart-attack risk vs hypertension, "
        "alertness decay vs half-hours since sleep, crippling anxiety vs alertness, the Ballmer function, "
        "and productivity over alertness x intoxication. Writes one PNG each into DIR (created if missing).",
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="folder for the PNGs")
    _add_force(parser)
    parser.set_defaults(handler=plot_model)


def _add_episode(kinds: Subparsers) -> None:
    parser = kinds.add_parser(
        "episode",
        help="one episode as a dashboard",
        description="Run one episode and draw it: the state variables over time, each decision as a marker, "
        "sleep shaded, heart attacks marked, the running score.",
    )
    _add_episode_options(parser)
    parser.add_argument("--out", required=True, metavar="FILE.png", help="the PNG to write")
    _add_force(parser)
    parser.set_defaults(handler=plot_episode)


def _add_training(kinds: Subparsers) -> None:
    parser = kinds.add_parser(
        "training",
        help="the learning curve of 'heartpole train'",
        description="Plot DIR/learning_curve.csv written by 'heartpole train --out DIR': return, heart attacks "
        "and score against timesteps. With several seeds (DIR/seed_<s>/learning_curve.csv) it draws their mean "
        "and the range between the lowest and the highest seed.",
    )
    parser.add_argument("dir", metavar="DIR", help="the folder given to 'heartpole train --out'")
    parser.add_argument("--out", metavar="FILE.png", help="the PNG to write (default: DIR/learning_curve.png)")
    _add_force(parser)
    parser.set_defaults(handler=plot_training)


def _add_record(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "record",
        help="a video of one episode (MP4 or GIF)",
        description="Run one episode and write its rgb_array frames as a video: the clock, alertness, blood "
        "pressure, intoxication, hours awake, work done, the score, the last action and heart attacks. "
        "MP4 needs imageio-ffmpeg, GIF needs Pillow (both come with heartpole[plot]).",
    )
    _add_episode_options(parser)
    parser.add_argument("--fps", type=positive_int, default=DEFAULT_FPS,
                        help=f"frames (half-hour decisions) per second ({DEFAULT_FPS})")  # fmt: skip
    parser.add_argument("--out", required=True, metavar="FILE.mp4|FILE.gif", help="the video to write")
    _add_force(parser)
    parser.set_defaults(handler=record)


def _add_force(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true", help="replace existing files (missing folders are created)")


def _add_episode_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--policy",
        required=True,
        metavar="P",
        help="a built-in policy (random, nothing, coffee, reference, expert, optimal) "
        "or a model .zip from 'heartpole train'",
    )
    parser.add_argument("--seed", type=seed_int, default=0, help="seed of the episode (0)")
    parser.add_argument("--steps", type=positive_int, default=None,
                        help=f"decisions in the episode (the env's, 1000; at most {MAX_DRAWN_STEPS:,})")  # fmt: skip
    add_env_options(parser)
    add_trust_pickles(parser)


# --------------------------------------------------------------------------------------------------------
def _require_matplotlib() -> None:
    """A clear error when matplotlib is missing."""
    try:
        plots.require_matplotlib()
    except ImportError:
        raise CommandError(f"plots need matplotlib; {INSTALL_HINT}") from None


def _env_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """Set ``args.env`` (``--env``, else the env the model's folder records, else HeartPole-v0) and return its
    keyword arguments, ``--steps`` as ``max_steps``; an episode longer than
    [`MAX_DRAWN_STEPS`][heartpole.cli.plot.MAX_DRAWN_STEPS] is refused."""
    args.env, kwargs = choose_env(args, [args.policy])
    kwargs = kwargs if args.steps is None else {**kwargs, "max_steps": args.steps}
    steps = _default_steps(args.env, kwargs)
    if steps > MAX_DRAWN_STEPS:
        years, hours = MAX_DRAWN_STEPS / (2 * 24 * 365.25), MAX_DRAWN_STEPS / DEFAULT_FPS / 3600
        raise CommandError(f"{_steps_option(args)} {steps:,}: an episode drawn or recorded has at most "
                           f"{MAX_DRAWN_STEPS:,} decisions ({years:.1f} years of half-hours, a video of {hours:.1f} "
                           f"hours at {DEFAULT_FPS} fps)")  # fmt: skip
    return kwargs


def _steps_option(args: argparse.Namespace) -> str:
    """What set the episode's length: ``--steps``, else the env's ``max_steps`` (``--env-kwargs``, the model's
    folder)."""
    return "--steps" if args.steps is not None else "max_steps"


def _check_gif_memory(args: argparse.Namespace, kwargs: dict[str, Any]) -> None:
    """Refuse a GIF whose frames, which Pillow holds until it writes, would not fit in memory."""
    frames = _default_steps(args.env, kwargs) + 1
    try:
        paths.check_memory(frames * plots.GIF_FRAME_BYTES, f"{_steps_option(args)} {frames - 1:,} as a GIF "
                           f"({frames:,} frames Pillow holds until it writes)")  # fmt: skip
    except ValueError as error:
        raise CommandError(f"{error}; record an MP4, which streams its frames") from None


def _policy(args: argparse.Namespace, env_kwargs: dict[str, Any]) -> Policy:
    """The policy named by ``--policy`` for ``--env`` made with ``env_kwargs``, or a one-line error."""
    from heartpole.policies import load_policy
    from heartpole.policies.trained_env import model_file

    try:
        policy = load_policy(
            model_file(args.policy), args.env, env_kwargs=env_kwargs, rng=args.seed, trust_pickles=args.trust_pickles
        )
    except (ValueError, FileNotFoundError) as error:
        raise CommandError(str(error)) from None
    tell_normalization(policy)
    return policy


def _write_figure(figure: Figure, path: Path) -> None:
    files.atomic_write(path, lambda temporary: plots.save_figure(figure, temporary))
    print(f"wrote {path}")


# --------------------------------------------------------------------------------------------------------
def plot_model(args: argparse.Namespace) -> int:
    """``heartpole plot model --out DIR``: one PNG per model figure, moved into place together."""
    _require_matplotlib()
    targets = output_files(args.out, [f"{stem}.png" for stem in plots.MODEL_FIGURES], force=args.force)
    with files.atomic_files(*targets) as temporaries:
        for make, temporary in zip(plots.MODEL_FIGURES.values(), temporaries):
            plots.save_figure(make(Params()), temporary)
    print("\n".join(f"wrote {target}" for target in targets))
    return 0


def plot_episode(args: argparse.Namespace) -> int:
    """``heartpole plot episode --policy P --out FILE.png``: one episode as a dashboard."""
    _require_matplotlib()
    target = output_file(args.out, force=args.force, suffixes=[".png"])
    kwargs = _env_kwargs(args)
    policy = _policy(args, kwargs)
    trace = plots.trace_episode(policy, args.env, args.seed, **kwargs)
    title = (
        f"{args.env}, policy {args.policy}, seed {args.seed}: return {trace.episode_return:.2f}, "
        f"final score {trace.score[-1]:.3f}, heart attacks {int(trace.heart_attacks.sum())}"
    )
    _write_figure(plots.episode_figure(trace, title), target)
    return 0


def plot_training(args: argparse.Namespace) -> int:
    """``heartpole plot training DIR``: the learning curve(s) of a training run."""
    _require_matplotlib()
    folder = Path(args.dir)
    if not folder.is_dir():
        raise CommandError(f"{folder}: no such folder (give the folder of 'heartpole train --out')")
    target = output_file(args.out or folder / "learning_curve.png", force=args.force, suffixes=[".png"])
    found = plots.find_learning_curves(folder)
    if not found:
        raise CommandError(
            f"{folder}: no learning_curve.csv here or in seed_*/ (written by 'heartpole train --out {folder}')"
        )
    try:
        curves = {label: plots.read_learning_curve(path) for label, path in found.items()}
    except (OSError, ValueError) as error:
        raise CommandError(str(error)) from None
    for label, curve in curves.items():
        for problem in plots.not_finite(curve):
            print(f"warning: {found[label]}: {problem}; the figure leaves those points out", file=sys.stderr)
    seeds = f", {len(curves)} seeds" if len(curves) > 1 else ""
    _write_figure(plots.training_figure(curves, f"Learning curve: {folder}{seeds}"), target)
    return 0


def record(args: argparse.Namespace) -> int:
    """``heartpole record --policy P --out FILE.mp4|.gif``: a video of one episode from its rgb_array frames."""
    target = output_file(args.out, force=args.force, suffixes=list(plots.VIDEO_SUFFIXES))
    _check_video_writer(target.suffix.lower())
    kwargs = _env_kwargs(args)
    if target.suffix.lower() == ".gif":
        _check_gif_memory(args, kwargs)
    policy = _policy(args, kwargs)
    frames = plots.episode_frames(policy, args.env, args.seed, **kwargs)
    total = _default_steps(args.env, kwargs) + 1
    with progress(total, f"recording {target.name}") as bar:
        count = 0

        def write(temporary: Path) -> None:
            nonlocal count
            count = plots.write_video(_counted(frames, bar), temporary, fps=args.fps)

        files.atomic_write(target, write)
    print(f"wrote {target} ({count} frames, {count / args.fps:.1f} s at {args.fps} fps)")
    return 0


def _counted(frames: Iterator[np.ndarray], bar: Progress) -> Iterator[np.ndarray]:
    for frame in frames:
        bar.update()
        yield frame


def _default_steps(env_id: str, env_kwargs: dict[str, Any]) -> int:
    """The episode length of ``env_id`` made with ``env_kwargs`` (for the progress bar)."""
    from heartpole.registry import env_dynamics

    try:
        return int(env_dynamics(env_id, env_kwargs).params.max_steps)
    except (ValueError, TypeError):
        return 1000


def _check_video_writer(suffix: str) -> None:
    """A clear error before any work when the writer for ``suffix`` is not installed."""
    try:
        plots.require_video_writer(suffix)
    except ImportError as error:
        raise CommandError(f"{error}; {INSTALL_HINT}") from None
