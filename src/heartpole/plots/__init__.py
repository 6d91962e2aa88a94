"""HeartPole's pictures: the tutorial's curves, one episode as a dashboard, learning curves and videos.

matplotlib (and, for videos, imageio with ffmpeg, or Pillow for GIFs) is an optional extra,
``pip install "heartpole[plot]"``; it is imported inside the functions that need it, so
``import heartpole`` stays light. Figures are built as ``matplotlib.figure.Figure`` objects without
pyplot, so nothing here touches a display or matplotlib's global state.

Everything is drawn from the package's own model ([`heartpole.model`][heartpole.model]) and envs, so a
change to the model shows up in the pictures. One module per kind of picture, every name importable from
here: `canvas` (the figures' canvas, colours, dependency checks), `curves` (the tutorial's figures),
`episode` (one episode's dashboard), `frontier` (the
productivity-risk frontier), `learning` (learning curves) and `video` (videos of episodes).
"""

from __future__ import annotations

from heartpole.plots.canvas import (
    ACTION_COLORS,
    ATTACK_COLOR,
    CURVE_COLOR,
    DPI,
    EXTRA_COLORS,
    SLEEP_SHADE,
    VIDEO_SUFFIXES,
    new_figure,
    require_matplotlib,
    require_video_writer,
    save_figure,
)
from heartpole.plots.curves import (
    MODEL_FIGURES,
    alertness_decay_figure,
    ballmer_figure,
    crippling_anxiety_figure,
    heart_attack_risk_figure,
    productivity_figure,
)
from heartpole.plots.episode import START_DAY, EpisodeTrace, act, episode_days, episode_figure, trace_episode
from heartpole.plots.frontier import FrontierMark, frontier_figure
from heartpole.plots.learning import (
    TRAINING_PANELS,
    find_learning_curves,
    not_finite,
    read_learning_curve,
    training_figure,
)
from heartpole.plots.video import GIF_FRAME_BYTES, episode_frames, write_video

__all__ = [
    "ACTION_COLORS",
    "ATTACK_COLOR",
    "CURVE_COLOR",
    "DPI",
    "EXTRA_COLORS",
    "GIF_FRAME_BYTES",
    "MODEL_FIGURES",
    "SLEEP_SHADE",
    "START_DAY",
    "TRAINING_PANELS",
    "VIDEO_SUFFIXES",
    "EpisodeTrace",
    "FrontierMark",
    "act",
    "alertness_decay_figure",
    "ballmer_figure",
    "crippling_anxiety_figure",
    "episode_days",
    "episode_figure",
    "episode_frames",
    "find_learning_curves",
    "frontier_figure",
    "heart_attack_risk_figure",
    "new_figure",
    "productivity_figure",
    "not_finite",
    "read_learning_curve",
    "require_matplotlib",
    "require_video_writer",
    "save_figure",
    "trace_episode",
    "training_figure",
    "write_video",
]
