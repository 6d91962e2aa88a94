"""HeartPole's pictures: the tutorial's curves, one episode as a dashboard, learning curves and videos.

matplotlib (and, for videos, imageio with ffmpeg, or Pillow for GIFs) is an optional extra,
``pip install "heartpole[plot]"``; it is imported inside the functions that need it, so
``import heartpole`` stays light. Figures are built as :class:`matplotlib.figure.Figure` objects without
pyplot, so nothing here touches a display or matplotlib's global state.

Everything is drawn from the package's own model (:mod:`heartpole.model`) and envs, so a change to the
model shows up in the pictures.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np

from heartpole import model
from heartpole.model import Params
from heartpole.policies import CURVE_COLUMNS, CURVE_NAME, Policy
from heartpole.render import EPISODE_START_MINUTES, landmarks

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from heartpole.env import HeartPole

DPI = 100
ACTION_COLORS = {
    "do_nothing": "#7f8c8d",
    "drink_coffee": "#8e5a2b",
    "drink_beer": "#e0a526",
    "sleep": "#3b5bdb",
}
EXTRA_COLORS = ("#12b886", "#ae3ec9", "#f76707", "#1098ad")
ATTACK_COLOR = "#e03131"
SLEEP_SHADE = "#dbe4ff"
CURVE_COLOR = "#1c7ed6"
VIDEO_SUFFIXES = (".mp4", ".gif")


def require_matplotlib() -> None:
    """Raise ``ImportError`` with the install command if matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError as error:
        raise ImportError('plots need matplotlib: pip install "heartpole[plot]"') from error


def require_video_writer(suffix: str) -> None:
    """Raise ``ImportError`` naming what is missing if videos of type ``suffix`` cannot be written: ``.mp4``
    needs imageio and imageio-ffmpeg, ``.gif`` Pillow."""
    try:
        if suffix == ".mp4":
            import imageio  # noqa: F401
            import imageio_ffmpeg  # noqa: F401
        else:
            import PIL  # noqa: F401
    except ImportError as error:
        needed = "imageio and imageio-ffmpeg" if suffix == ".mp4" else "Pillow"
        raise ImportError(f"{suffix} videos need {needed}") from error


def _figure(width: float, height: float) -> Figure:
    """A new figure on matplotlib's Agg canvas, detached from pyplot (no display, no global state)."""
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def save_figure(figure: Figure, path: str | Path) -> None:
    """Write ``figure`` as a PNG to ``path``."""
    figure.savefig(path, format="png", dpi=DPI)


# --------------------------------------------------------------------------------------------------------
# The tutorial's figures (facts 4, 6, 7 and fiction 8) and the productivity heat map.
def _curve_figure(x: np.ndarray, y: np.ndarray, xlabel: str, ylabel: str, title: str) -> tuple[Figure, Axes]:
    figure = _figure(7.0, 4.5)
    axes = figure.add_subplot()
    axes.plot(x, y, color=CURVE_COLOR, linewidth=2.2)
    axes.set(xlabel=xlabel, ylabel=ylabel, title=title, xlim=(x[0], x[-1]))
    axes.grid(alpha=0.3)
    return figure, axes


def _annotate(axes: Axes, x: float, y: float, text: str, offset: tuple[float, float] = (20, -30)) -> None:
    axes.plot([x], [y], "o", color=ATTACK_COLOR, zorder=3)
    axes.annotate(
        text,
        (x, y),
        xytext=offset,
        textcoords="offset points",
        fontsize=10,
        arrowprops={"arrowstyle": "->", "color": "#495057"},
    )


def heart_attack_risk_figure(params: Params | None = None) -> Figure:
    """Fact 4: the chance of a heart attack in one step against hypertension."""
    x = np.linspace(0.0, 10.0, 400)
    proclivity = (params or Params()).heart_attack_proclivity
    figure, axes = _curve_figure(
        x,
        model.heart_attack_risk(x, proclivity),
        "hypertension",
        "heart attack risk per step",
        "Fact 4: hypertension is a risk factor for heart attacks",
    )
    pressure = landmarks().high_pressure
    half = float(model.heart_attack_risk(pressure, proclivity))
    _annotate(axes, pressure, half, f"hypertension {pressure:g}: risk {half:.0%} per half-hour", (-230, 10))
    axes.axhline(proclivity, color="#868e96", linestyle=":", linewidth=1)
    axes.text(0.2, proclivity * 0.95, f"heart_attack_proclivity = {proclivity:g}", va="top", color="#495057")
    return figure


def alertness_decay_figure(params: Params | None = None) -> Figure:
    """Fact 6: alertness lost per half-hour against half-hours since sleeping."""
    x = np.linspace(0.0, 100.0, 400)
    figure, axes = _curve_figure(
        x,
        model.alertness_decay(x),
        "half-hours since slept",
        "alertness lost per half-hour",
        "Fact 6: alertness decays if you haven't slept for a long time",
    )
    half_hours = 2 * landmarks().fading_hours
    _annotate(
        axes,
        half_hours,
        float(model.alertness_decay(half_hours)),
        f"{half_hours:g} half-hours ({half_hours / 2:g} h) awake:\nhalf a point lost per half-hour",
        (30, -40),
    )
    return figure


def crippling_anxiety_figure(params: Params | None = None) -> Figure:
    """Fact 7: the share of work lost to anxiety against alertness."""
    x = np.linspace(0.0, 10.0, 400)
    figure, axes = _curve_figure(
        x,
        model.crippling_anxiety(x),
        "alertness",
        "crippling anxiety (share of work lost)",
        "Fact 7: too alert, and crippling anxiety hits",
    )
    anxious = landmarks().anxious
    _annotate(
        axes, anxious, float(model.crippling_anxiety(anxious)), f"alertness {anxious:g}: half the work lost", (20, -40)
    )
    return figure


def ballmer_figure(params: Params | None = None) -> Figure:
    """Fiction 8: programming skill against blood alcohol content, the Ballmer function."""
    x = np.linspace(0.0, 0.26, 1000)
    figure, axes = _curve_figure(
        x,
        model.ballmer(x),
        "blood alcohol content (intoxication)",
        "programming skill",
        "Fiction 8: the Ballmer function",
    )
    peak = float(x[np.argmax(model.ballmer(x))])
    _annotate(axes, peak, float(model.ballmer(peak)), f"the Ballmer peak, BAC {peak:.3f}", (25, -20))
    return figure


def productivity_figure(params: Params | None = None) -> Figure:
    """Facts 7 and 8 together: work done in a half-hour over alertness x intoxication, as a heat map."""
    alertness = np.linspace(-0.5, 7.0, 301)
    intoxication = np.linspace(0.0, 0.25, 501)
    work = model.productivity(alertness[None, :], intoxication[:, None])
    figure = _figure(7.5, 5.0)
    axes = figure.add_subplot()
    image = axes.pcolormesh(alertness, intoxication, work, cmap="viridis", shading="auto")
    figure.colorbar(image, ax=axes, label="work done in one half-hour (productivity)")
    lines = axes.contour(alertness, intoxication, work, levels=[0.5, 1.0, 2.0], colors="white", linewidths=0.8)
    axes.clabel(lines, fmt="%.1f", fontsize=8)
    row, column = np.unravel_index(np.argmax(work), work.shape)
    axes.plot(alertness[column], intoxication[row], "*", color="white", markersize=14)
    axes.annotate(
        f"best: alertness {alertness[column]:.1f}, BAC {intoxication[row]:.3f}",
        (alertness[column], intoxication[row]),
        xytext=(15, 12),
        textcoords="offset points",
        color="white",
    )
    axes.set(
        xlabel="alertness",
        ylabel="intoxication (blood alcohol)",
        title="Productivity = alertness x (1 - anxiety) x Ballmer(intoxication)",
    )
    return figure


MODEL_FIGURES: dict[str, Callable[[Params | None], Figure]] = {
    "heart_attack_risk": heart_attack_risk_figure,
    "alertness_decay": alertness_decay_figure,
    "crippling_anxiety": crippling_anxiety_figure,
    "ballmer": ballmer_figure,
    "productivity": productivity_figure,
}
"""The model's figures by file stem: ``heartpole plot model`` writes ``<stem>.png`` for each."""


# --------------------------------------------------------------------------------------------------------
# One episode.
@dataclass(frozen=True)
class EpisodeTrace:
    """What happened in one episode, step by step.

    Attributes:
        names: the state variables, in observation order.
        states: ``(steps + 1, num_variables)``: the state after reset, then after each step.
        actions: the index of each step's action, ``(steps,)``.
        action_names: the name of every action index of the env.
        sleeps: for every action index, whether the action sleeps.
        heart_attacks: whether each step caused a heart attack, ``(steps,)``.
        rewards: each step's reward, ``(steps,)``.
    """

    names: tuple[str, ...]
    states: np.ndarray
    actions: np.ndarray
    action_names: tuple[str, ...]
    sleeps: tuple[bool, ...]
    heart_attacks: np.ndarray
    rewards: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """One state variable over the episode, ``(steps + 1,)``."""
        return self.states[:, self.names.index(name)]

    @property
    def episode_return(self) -> float:
        """The sum of the rewards."""
        return float(self.rewards.sum())

    @property
    def score(self) -> np.ndarray:
        """The running score ``work_done / time_elapsed`` over the episode, ``(steps + 1,)``."""
        return model.score(self.column("work_done"), self.column("time_elapsed"))


def act(policy: Policy, observation: np.ndarray, decisions_left: int | None = None) -> int:
    """The action ``policy`` chooses for one observation (policies work on batches).

    ``decisions_left`` goes to a policy that ``needs_decisions_left`` (see :mod:`heartpole.policies`).
    """
    from heartpole.policies import act_batch

    batch = observation[None].astype(np.float32)
    left = None if decisions_left is None else np.array([decisions_left], dtype=np.int64)
    return int(np.asarray(act_batch(policy, batch, left)).reshape(-1)[0])


def trace_episode(policy: Policy, env_id: str = "HeartPole-v0", seed: int = 0, **env_kwargs: Any) -> EpisodeTrace:
    """Run one episode of ``env_id`` with ``policy`` from ``reset(seed=seed)`` and record it."""
    env = gym.make(env_id, **env_kwargs)
    core = cast("HeartPole", env.unwrapped)
    observation, _ = env.reset(seed=seed)
    actions: list[int]
    states, actions, attacks, rewards = [observation], [], [], []
    truncated = terminated = False
    while not (truncated or terminated):
        action = act(policy, observation, int(core.max_steps) - len(actions))
        observation, reward, terminated, truncated, info = env.step(action)
        states.append(observation)
        actions.append(action)
        attacks.append(bool(info["heart_attack"]))
        rewards.append(float(reward))
    env.close()
    return EpisodeTrace(
        names=tuple(core.dynamics.names),
        states=np.array(states, dtype=np.float64),
        actions=np.array(actions, dtype=np.int64),
        action_names=tuple(a.name for a in core.actions),
        sleeps=tuple(a.sleeps for a in core.actions),
        heart_attacks=np.array(attacks, dtype=bool),
        rewards=np.array(rewards, dtype=np.float64),
    )


def _sleep_spans(trace: EpisodeTrace, days: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) in days of every sleep: from the decision until the half-hour of work that follows it."""
    steps = np.flatnonzero(np.array(trace.sleeps)[trace.actions])
    return [(float(days[step]), float(days[step + 1]) - 1.0 / 48.0) for step in steps]


def _episode_panels(trace: EpisodeTrace) -> list[tuple[str, str, np.ndarray]]:
    """(variable, y label, values) for each state panel of the dashboard, v0's first and then a variant's."""
    panels = [
        ("alertness", "alertness", trace.column("alertness")),
        ("hypertension", "blood pressure\n(hypertension)", trace.column("hypertension")),
        ("intoxication", "intoxication\n(blood alcohol)", trace.column("intoxication")),
    ]
    v0 = {v.name for v in model.V0_VARIABLES}
    panels += [(name, name.replace("_", " "), trace.column(name)) for name in trace.names if name not in v0]
    score = trace.score.copy()
    score[0] = np.nan  # no score before any time has passed
    panels.append(("score", "running score\n(work / time)", score))
    return panels


def _decorate_panel(axes: Axes, name: str, values: np.ndarray) -> None:
    """The model's landmarks on a state panel: productive alertness, high risk, the Ballmer peak."""
    marks = landmarks()
    finite = values[np.isfinite(values)]
    if name == "alertness":
        low, high = marks.productive
        axes.axhspan(low, high, color="#8ce99a", alpha=0.35, zorder=1, linewidth=0, label="most productive")
        axes.legend(loc="upper right", fontsize=8, framealpha=0.8)
    elif name == "hypertension":
        _guide(axes, marks.high_pressure, f" risk {marks.high_risk:.0%} per half-hour", ATTACK_COLOR)
        axes.set_ylim(bottom=0.0, top=max(float(finite.max()) * 1.1, marks.high_pressure * 1.15))
    elif name == "intoxication":
        _guide(axes, marks.ballmer_peak, " Ballmer peak", "#e67700")
        axes.set_ylim(bottom=0.0, top=max(float(finite.max()) * 1.1, marks.ballmer_peak * 1.2))


def _guide(axes: Axes, level: float, text: str, color: str) -> None:
    """A dotted horizontal line at ``level``, labelled at the left."""
    axes.axhline(level, color=color, linestyle=":", linewidth=1)
    axes.text(0.005, level, text, color=color, fontsize=8, va="bottom", transform=axes.get_yaxis_transform())


def _action_strip(axes: Axes, trace: EpisodeTrace, days: np.ndarray) -> None:
    """One marker per decision, at the time it was taken, on the row of its action."""
    for index, name in enumerate(trace.action_names):
        taken = trace.actions == index
        color = ACTION_COLORS.get(name, EXTRA_COLORS[index % len(EXTRA_COLORS)])
        axes.scatter(days[:-1][taken], np.full(taken.sum(), index), marker="|", s=80, color=color, linewidths=1.2)
    axes.set_yticks(range(len(trace.action_names)), [n.replace("_", " ") for n in trace.action_names])
    axes.set_ylim(-0.6, len(trace.action_names) - 0.4)
    axes.set_ylabel("action")


START_DAY = EPISODE_START_MINUTES / (24 * 60)  # the episode starts at 09:00 on day 1


def episode_days(trace: EpisodeTrace) -> np.ndarray:
    """The time of each state in days since midnight before the episode, ``(steps + 1,)``; day 1 is [0, 1)."""
    return START_DAY + trace.column("time_elapsed") / 48.0


def episode_figure(trace: EpisodeTrace, title: str = "") -> Figure:
    """One episode as a dashboard: state variables over time, actions, sleep shaded, heart attacks marked.

    Time runs along the x axis in days, sleep included; the episode starts at 09:00 on day 1.
    """
    panels = _episode_panels(trace)
    strip_ratio = max(1.2, 0.3 * len(trace.action_names))  # room for every action's row
    figure = _figure(12.0, 1.7 * (len(panels) + strip_ratio / 1.2) + 0.8)
    grid = figure.add_gridspec(len(panels) + 1, 1, height_ratios=[2] * len(panels) + [strip_ratio])
    days = episode_days(trace)
    gaps = np.flatnonzero(np.array(trace.sleeps)[trace.actions]) + 1
    all_axes: list[Axes] = []
    for row, (name, label, values) in enumerate(panels):
        axes = figure.add_subplot(grid[row], sharex=all_axes[0] if all_axes else None)
        axes.plot(days, values, color=CURVE_COLOR, linewidth=0.8, linestyle=":", alpha=0.7)  # across sleep
        axes.plot(np.insert(days, gaps, np.nan), np.insert(values, gaps, np.nan), color=CURVE_COLOR, linewidth=1.2)
        axes.set_ylabel(label)
        _decorate_panel(axes, name, values)
        axes.tick_params(labelbottom=False)
        all_axes.append(axes)
    strip = figure.add_subplot(grid[len(panels)], sharex=all_axes[0])
    _action_strip(strip, trace, days)
    all_axes.append(strip)
    _shade_sleep_and_attacks(all_axes, trace, days)
    _mark_attacks(all_axes[1], trace)
    _day_axis(strip, days)
    figure.suptitle(title or _episode_title(trace), fontsize=12)
    return figure


def _shade_sleep_and_attacks(all_axes: list[Axes], trace: EpisodeTrace, days: np.ndarray) -> None:
    sleep = _sleep_spans(trace, days)
    attacks = days[1:][trace.heart_attacks]
    for axes in all_axes:
        for start, end in sleep:
            axes.axvspan(start, end, color=SLEEP_SHADE, zorder=0, linewidth=0)
        for day in attacks:
            axes.axvline(day, color=ATTACK_COLOR, linewidth=1.2, alpha=0.85)
        axes.grid(alpha=0.25)


def _day_axis(axes: Axes, days: np.ndarray) -> None:
    """Ticks at midnight labelled with the day that begins there."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    axes.set_xlim(float(days[0]), float(days[-1]))
    axes.xaxis.set_major_locator(MaxNLocator(integer=True, min_n_ticks=1))
    axes.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"day {int(round(x)) + 1}"))
    axes.set_xlabel(
        "time (ticks at midnight; the episode starts on day 1 at 09:00)   "
        "blue shade: asleep (dotted line)   red lines: heart attacks"
    )


def _mark_attacks(axes: Axes, trace: EpisodeTrace) -> None:
    """Red heart-attack markers along the top of the blood-pressure panel."""
    if not trace.heart_attacks.any():
        return
    when = episode_days(trace)[1:][trace.heart_attacks]
    axes.scatter(
        when,
        np.full(len(when), 0.92),
        marker="X",
        s=70,
        color=ATTACK_COLOR,
        zorder=4,
        label="heart attack",
        transform=axes.get_xaxis_transform(),
        clip_on=False,
    )
    axes.legend(loc="upper right", fontsize=8, framealpha=0.8)


def _episode_title(trace: EpisodeTrace) -> str:
    steps = len(trace.actions)
    return (
        f"{steps} decisions over {trace.column('time_elapsed')[-1] / 48.0:.1f} days: return "
        f"{trace.episode_return:.2f}, final score {trace.score[-1]:.3f}, heart attacks {int(trace.heart_attacks.sum())}"
    )


# --------------------------------------------------------------------------------------------------------
# Learning curves.


def read_learning_curve(path: str | Path) -> dict[str, np.ndarray]:
    """Read one ``learning_curve.csv`` (columns timesteps, mean_return, heart_attacks, score).

    Raises:
        ValueError: if a column is missing, a value is not a number or there are no rows.
    """
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        missing = [c for c in CURVE_COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing column(s) {missing}; expected {list(CURVE_COLUMNS)}")
        rows = list(reader)
    if not rows:
        raise ValueError(f"{path}: no rows")
    try:
        table = {c: np.array([float(row[c]) for row in rows]) for c in CURVE_COLUMNS}
    except (TypeError, ValueError) as error:
        raise ValueError(f"{path}: not a number in the learning curve ({error})") from None
    order = np.argsort(table["timesteps"], kind="stable")
    return {c: values[order] for c, values in table.items()}


def find_learning_curves(folder: str | Path) -> dict[str, Path]:
    """The learning curves of a ``heartpole train --out`` folder: one per ``seed_<s>`` subfolder, or the single one.

    Returns ``{label: path}``; empty if there are none.
    """
    folder = Path(folder)
    seeds = sorted(folder.glob(f"seed_*/{CURVE_NAME}"), key=lambda p: _seed_number(p.parent.name))
    if seeds:
        return {p.parent.name.replace("_", " "): p for p in seeds}
    single = folder / CURVE_NAME
    return {"run": single} if single.is_file() else {}


def _seed_number(name: str) -> tuple[int, str]:
    digits = name.removeprefix("seed_")
    return (int(digits), name) if digits.isdigit() else (1 << 62, name)


def _common_grid(curves: Mapping[str, Mapping[str, np.ndarray]]) -> np.ndarray:
    """The timesteps at which every curve can be read: the union of their points inside their common range."""
    low = max(c["timesteps"][0] for c in curves.values())
    high = min(c["timesteps"][-1] for c in curves.values())
    points = np.unique(np.concatenate([c["timesteps"] for c in curves.values()]))
    return points[(points >= low) & (points <= high)]


TRAINING_PANELS = (
    ("mean_return", "mean episode return"),
    ("heart_attacks", "heart attacks per episode"),
    ("score", "final score (work / time)"),
)


def training_figure(curves: Mapping[str, Mapping[str, np.ndarray]], title: str = "") -> Figure:
    """Return, heart attacks and score against timesteps; several seeds as their mean and min-max band."""
    figure = _figure(12.0, 4.2)
    panels = figure.subplots(1, len(TRAINING_PANELS))
    several = len(curves) > 1
    grid = _common_grid(curves) if several else None
    for axes, (column, label) in zip(panels, TRAINING_PANELS):
        if several and grid is not None and len(grid):
            values = np.array([np.interp(grid, c["timesteps"], c[column]) for c in curves.values()])
            axes.fill_between(
                grid,
                values.min(0),
                values.max(0),
                color=CURVE_COLOR,
                alpha=0.2,
                label=f"range over {len(curves)} seeds",
            )
            axes.plot(grid, values.mean(0), color=CURVE_COLOR, linewidth=2, marker=".", label="mean")
        else:
            for name, curve in curves.items():
                axes.plot(curve["timesteps"], curve[column], color=CURVE_COLOR, linewidth=2, marker=".", label=name)
        axes.set(xlabel="timesteps", title=label)
        axes.grid(alpha=0.3)
    panels[0].legend(fontsize=9)
    figure.suptitle(title or "Learning curve", fontsize=12)
    return figure


# --------------------------------------------------------------------------------------------------------
# Videos.
def episode_frames(
    policy: Policy, env_id: str = "HeartPole-v0", seed: int = 0, **env_kwargs: Any
) -> Iterator[np.ndarray]:
    """The ``rgb_array`` frames of one episode: the first state after reset, then one frame per step."""
    env = gym.make(env_id, render_mode="rgb_array", **env_kwargs)
    try:
        observation, _ = env.reset(seed=seed)
        yield cast(np.ndarray, env.render())  # render_mode="rgb_array"
        done, steps = False, 0
        while not done:
            left = int(cast("HeartPole", env.unwrapped).max_steps) - steps
            observation, _, terminated, truncated, _ = env.step(act(policy, observation, left))
            steps += 1
            yield cast(np.ndarray, env.render())
            done = terminated or truncated
    finally:
        env.close()


def write_video(frames: Iterable[np.ndarray], path: str | Path, fps: float = 8.0) -> int:
    """Write RGB frames to ``path`` (``.mp4`` through imageio-ffmpeg, ``.gif`` through Pillow); return the count.

    Frames are streamed: an MP4 of a long episode never holds all its frames in memory.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ValueError(f"unsupported video type {suffix or '(none)'!r}; use one of {list(VIDEO_SUFFIXES)}")
    return _write_mp4(frames, path, fps) if suffix == ".mp4" else _write_gif(frames, path, fps)


def _write_mp4(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    try:
        import imageio.v2 as imageio
    except ImportError as error:
        raise ImportError('MP4 videos need imageio and imageio-ffmpeg: pip install "heartpole[plot]"') from error
    count = 0
    with imageio.get_writer(path, format="FFMPEG", fps=fps, codec="libx264", quality=7, macro_block_size=2) as writer:
        for frame in frames:
            writer.append_data(frame)  # type: ignore[attr-defined]  # typed as v3's base; v2's writers have it
            count += 1
    return count


def _write_gif(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    try:
        from PIL import Image
    except ImportError as error:
        raise ImportError('GIF videos need Pillow: pip install "heartpole[plot]"') from error
    images = (Image.fromarray(frame) for frame in frames)
    first = next(images)
    count = [1]

    def counted() -> Iterator[Any]:
        for image in images:
            count[0] += 1
            yield image

    first.save(path, format="GIF", save_all=True, append_images=counted(), duration=round(1000 / fps), loop=0)
    return count[0]
