"""One episode: what happened step by step (`EpisodeTrace`) and its dashboard."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np

from heartpole import model, parameters
from heartpole.plots.canvas import ACTION_COLORS, ATTACK_COLOR, CURVE_COLOR, EXTRA_COLORS, SLEEP_SHADE, new_figure
from heartpole.policies import Policy, quiet_version_warnings
from heartpole.render import EPISODE_START_MINUTES, landmarks

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from heartpole.env import HeartPole


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

    ``decisions_left`` goes to a policy that ``needs_decisions_left`` (see [`heartpole.policies`][heartpole.policies]).
    """
    from heartpole.policies import act_batch

    batch = observation[None].astype(np.float32)
    left = None if decisions_left is None else np.array([decisions_left], dtype=np.int64)
    return int(np.asarray(act_batch(policy, batch, left)).reshape(-1)[0])


def make_env(env_id: str, **env_kwargs: Any) -> gym.Env[Any, Any]:
    """``gymnasium.make(env_id, **env_kwargs)``, without Gymnasium's warning that v0 is out of date."""
    with quiet_version_warnings():  # drawing or filming v0 is deliberate
        return gym.make(env_id, **env_kwargs)


def trace_episode(policy: Policy, env_id: str = "HeartPole-v0", seed: int = 0, **env_kwargs: Any) -> EpisodeTrace:
    """Run one episode of ``env_id`` with ``policy`` from ``reset(seed=seed)`` and record it."""
    env = make_env(env_id, **env_kwargs)
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
    v0 = {v.name for v in parameters.V0_VARIABLES}
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
    figure = new_figure(12.0, 1.7 * (len(panels) + strip_ratio / 1.2) + 0.8)
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
