"""The productivity-risk frontier as a picture: expected heart attacks against expected score, penalty by penalty,
with evaluated policies drawn as points with their 95% intervals."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from heartpole.plots.canvas import ATTACK_COLOR, CURVE_COLOR, EXTRA_COLORS, new_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from heartpole.optimum import Frontier, FrontierRow


LOWER_LABEL = "the best solved policy (not proven optimal: the optimum is at or above it)"
SAME_PLACE = 1e-3
"""Points closer than this (relative, on both axes) share one label: the same policy at several penalties."""
OFF_SCALE = 3.0
"""How far below the frontier (in units of its span in score, at least 0.5) a policy may score and still be drawn."""


@dataclass(frozen=True)
class FrontierMark:
    """A policy measured by the evaluator, for the frontier's picture.

    Attributes:
        label: its name in the legend.
        heart_attacks: expected heart attacks per episode (the summed risks' mean), and its 95% interval.
        score: mean final score, and its 95% interval.
    """

    label: str
    heart_attacks: float
    heart_attacks_ci95: tuple[float, float]
    score: float
    score_ci95: tuple[float, float]


def frontier_figure(frontier: Frontier, marks: Sequence[FrontierMark] = ()) -> Figure:
    """The frontier's points (expected heart attacks per episode, expected score) joined by a line and labelled
    by their penalty, the no-drink threshold's point marked, and each of ``marks`` as a point with its 95%
    intervals on both axes. The heart attacks' axis is logarithmic where they span more than a factor of 20."""
    from heartpole.optimum.tradeoff import LOWER_BOUND

    figure = new_figure(8.0, 5.2)
    axes = figure.add_subplot()
    points = sorted(frontier.points, key=lambda p: p.expected_heart_attacks)
    x = [p.expected_heart_attacks for p in points]
    y = [p.expected_score for p in points]
    axes.plot(x, y, "-", color=CURVE_COLOR, linewidth=2, zorder=3)
    proven = [p for p in points if p.solver != LOWER_BOUND]
    bounds = [p for p in points if p.solver == LOWER_BOUND]
    for group, style, label in ((proven, "o", "the optimum at each penalty"), (bounds, "o", LOWER_LABEL)):
        if group:
            axes.plot(
                [p.expected_heart_attacks for p in group],
                [p.expected_score for p in group],
                style,
                color=CURVE_COLOR,
                markerfacecolor=CURVE_COLOR if group is proven else "white",
                markersize=6,
                label=label,
                zorder=5 if group is proven else 4,  # the proven point in front where both lie at one place
            )
    for (attacks, score), penalties in _places(points):
        text = f"{penalties[0]:g}" if len(penalties) == 1 else f"{penalties[0]:g} to {penalties[-1]:g}"
        axes.annotate(text, (attacks, score), xytext=(6, 4), textcoords="offset points", fontsize=8, color="#495057")
    shown, off = _on_scale(y, marks)
    for index, mark in enumerate(marks):
        if mark in shown:
            _draw_mark(axes, mark, EXTRA_COLORS[index % len(EXTRA_COLORS)])
    floor = min(x, default=math.nan)
    if math.isfinite(floor):
        axes.axvline(floor, color=ATTACK_COLOR, linestyle=":", linewidth=1, label="fewest heart attacks (no drinks)")
    every = x + [m.heart_attacks for m in shown]
    if every and min(every) > 0 and max(every) / min(every) > 20:
        axes.set_xscale("log")
    notes = [f"drinks never pay from penalty {frontier.threshold:.4g} on (the per-step check)"]
    if frontier.proven_from < frontier.threshold:
        notes[0] += f", proven from {frontier.proven_from:g} on (the solver's check)"
    if frontier.missing:
        notes.append(f"not solved: penalties {', '.join(f'{p:g}' for p, _ in frontier.missing)}")
    notes += [f"off the scale: {m.label} (score {m.score:.3g}, {m.heart_attacks:.3g} heart attacks)" for m in off]
    axes.set(
        xlabel="expected heart attacks per episode",
        ylabel="expected final score (work / time)",
        title=f"{frontier.env_id}{_kwargs(frontier.env_kwargs)}: the productivity-risk frontier (labels: penalty)",
    )
    axes.text(
        0.01,
        0.01,
        "\n".join(notes),
        transform=axes.transAxes,
        fontsize=8,
        color="#495057",
    )
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8, loc="best")
    return figure


def _kwargs(env_kwargs: dict[str, object]) -> str:
    """`` max_steps=100`` for the title: the env's keyword arguments, if any."""
    return "".join(f" {name}={value}" for name, value in env_kwargs.items())


def _places(points: Sequence[FrontierRow]) -> list[tuple[tuple[float, float], list[float]]]:
    """The points' places, each with the penalties there (the same policy at several penalties: one label)."""
    places: list[tuple[tuple[float, float], list[float]]] = []
    for point in points:
        here = (point.expected_heart_attacks, point.expected_score)
        if places and all(
            math.isclose(a, b, rel_tol=SAME_PLACE, abs_tol=SAME_PLACE) for a, b in zip(places[-1][0], here)
        ):
            places[-1][1].append(point.penalty)
        else:
            places.append((here, [point.penalty]))
    return [(place, sorted(penalties)) for place, penalties in places]


def _on_scale(scores: list[float], marks: Sequence[FrontierMark]) -> tuple[list[FrontierMark], list[FrontierMark]]:
    """The marks drawn, and those left off because their score lies far below the frontier's (more than
    `OFF_SCALE` times the frontier's span, at least `OFF_SCALE` / 2 below its lowest point): drawn, a policy that
    scores -195 would squash the frontier into a line."""
    if not scores:
        return list(marks), []
    reach = OFF_SCALE * max(max(scores) - min(scores), 0.5)
    shown = [m for m in marks if m.score >= min(scores) - reach]
    return shown, [m for m in marks if m not in shown]


def _draw_mark(axes: Axes, mark: FrontierMark, color: str) -> None:
    """One policy: a point with horizontal and vertical 95% error bars."""
    low_x, high_x = mark.heart_attacks_ci95
    low_y, high_y = mark.score_ci95
    error_x = [[max(mark.heart_attacks - low_x, 0.0)], [max(high_x - mark.heart_attacks, 0.0)]]
    error_y = [[max(mark.score - low_y, 0.0)], [max(high_y - mark.score, 0.0)]]
    axes.errorbar(
        [mark.heart_attacks],
        [mark.score],
        xerr=error_x,
        yerr=error_y,
        fmt="s",
        color=color,
        markersize=5,
        capsize=3,
        label=f"{mark.label} (95% intervals)",
        zorder=4,
    )
