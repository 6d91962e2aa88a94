"""Learning curves: reading ``learning_curve.csv`` files and drawing one or several seeds."""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from heartpole.plots.canvas import CURVE_COLOR, new_figure
from heartpole.policies import CURVE_COLUMNS, CURVE_NAME

if TYPE_CHECKING:
    from matplotlib.figure import Figure


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


def not_finite(curve: dict[str, np.ndarray]) -> list[str]:
    """What a learning curve holds that cannot be drawn: per column, how many values are NaN or infinite (a CSV's
    ``1e400`` reads as infinity). A plot leaves those points out without a word, so say it.

    >>> not_finite({"timesteps": np.array([1.0, 2.0]), "score": np.array([np.nan, np.inf])})
    ['score: 2 of 2 values NaN or infinite']
    """
    said = []
    for column, values in curve.items():
        bad = int(np.count_nonzero(~np.isfinite(values)))
        if bad:
            said.append(f"{column}: {bad} of {len(values)} values NaN or infinite")
    return said


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
    figure = new_figure(12.0, 4.2)
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
