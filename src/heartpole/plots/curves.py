"""The tutorial's figures (facts 4, 6, 7 and fiction 8) and the productivity heat map."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from heartpole import model
from heartpole.parameters import Params
from heartpole.plots.canvas import ATTACK_COLOR, CURVE_COLOR, new_figure
from heartpole.render import landmarks

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


def _curve_figure(x: np.ndarray, y: np.ndarray, xlabel: str, ylabel: str, title: str) -> tuple[Figure, Axes]:
    figure = new_figure(7.0, 4.5)
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
    figure = new_figure(7.5, 5.0)
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
