"""Where coffee may pay: a dynamic program over (decisions left, alertness, hypertension, half-hours awake).

With a low ``heart_attack_penalty`` (or proclivity) a coffee's alertness may be worth its blood pressure, so
hypertension becomes part of the state. Intoxication is left out: the program's policies never drink beer (see
docs/optimum.md for what that assumes). The objective is linearised as Dinkelbach's is: for a rate ``lam`` and a
time scale ``c`` the program maximises ``E[work - lam * time - c * penalty * extra]``, ``extra`` the sum of the
steps' heart-attack probabilities above the floor ``r(0)`` that no policy avoids (the expected attacks the drinks
add). [`heartpole.optimum.lifetime`][heartpole.optimum.lifetime] runs it at the no-drink rate and ``c =
max_steps`` to show that no drink pays; [`heartpole.optimum.coffee`][heartpole.optimum.coffee] iterates ``lam`` and
``c`` to a fixed point where drinks may pay.

The grid follows the dynamics without interpolating them, as [`DrinkingGrid`][heartpole.optimum.drinking.DrinkingGrid]
does for intoxication:

* **Alertness** is stored as ``b = alertness + drain(t)``, which a half-hour of work does not change; at each ``t`` a
  window of the ``alertness_step`` lattice covers ``alertness_range``. A coffee's ``U(0, 1)`` is the trapezoid rule.
* **Hypertension** lies on 0 and a geometric grid of ratio ``decay_rate`` up to ``max_hypertension``: a half-hour's
  fading moves a point exactly one down, a sleep's ``sleep_half_hours + 1``; only below the lowest positive point
  does it interpolate towards 0. A heart attack resets it to 0. A coffee's ``U(0, 0.3)`` is integrated exactly for
  the piecewise-linear interpolant.

A drink that would leave the grid (alertness above the window, hypertension above ``max_hypertension``) is not
taken; staying awake at ``max_awake - 1`` half-hours is not allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from heartpole.kernel import CACHE
from heartpole.model import alertness_decay, heart_attack_risk, productivity
from heartpole.parameters import Params, check_integer

NOTHING, COFFEE, BEER, SLEEP = range(4)
"""Action codes, in v0's order (the program never chooses ``BEER``)."""
MAX_ITERATIONS = 30
COFFEE_RISE = (0.0, 0.3)
"""A coffee's hypertension rise (checked against v0's action data by `PressureGrid`)."""


@dataclass(frozen=True)
class PressureGrid:
    """The program's discretisation (module docstring). Arrays are laid out ``(t, hypertension, alertness window)``."""

    params: Params
    alertness_step: float = 0.05
    alertness_range: tuple[float, float] = (-1.0, 4.0)
    max_hypertension: float = 4.0
    min_hypertension: float = 0.01
    max_awake: int = 80
    tables: dict[str, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        from heartpole.actions import DRINK_COFFEE

        if DRINK_COFFEE.effects["hypertension"] != COFFEE_RISE or DRINK_COFFEE.effects["alertness"] != (0.0, 1.0):
            raise ValueError(f"the program models v0's coffee, got {dict(DRINK_COFFEE.effects)}")
        object.__setattr__(self, "tables", _tables(self))

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(max_awake, hypertension points, alertness window)``."""
        return self.tables["work"].shape[0], len(self.tables["h"]), self.tables["work"].shape[1]

    def locate(self, alertness: np.ndarray, hypertension: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """Nearest grid indices ``(t, hypertension, alertness)`` of observed states (clamped to the grid)."""
        tab = self.tables
        t = np.clip(np.asarray(t).round().astype(np.int64), 0, self.max_awake - 1)
        b = np.asarray(alertness, dtype=np.float64) + tab["drained"][t]
        i = np.clip(np.round(b / self.alertness_step - tab["start"][t]).astype(np.int64), 0, self.shape[2] - 1)
        h = tab["h"]
        j = np.clip(np.searchsorted(h, np.asarray(hypertension, dtype=np.float64)), 1, len(h) - 1)
        j = np.where(np.abs(hypertension - h[j - 1]) <= np.abs(h[j] - hypertension), j - 1, j)
        return t, j, i


def _tables(grid: PressureGrid) -> dict[str, np.ndarray]:
    params, step = grid.params, grid.alertness_step
    awake = check_integer("max_awake", grid.max_awake, 3)
    coffee_points = int(round(1.0 / step))
    if abs(coffee_points * step - 1.0) > 1e-9:
        raise ValueError(f"alertness_step {step} must divide a coffee's U(0, 1) (e.g. 0.05 or 0.1)")
    drained = np.concatenate([[0.0], np.cumsum(alertness_decay(np.arange(awake, dtype=np.float64)))])
    low, high = grid.alertness_range
    width = int(round((high - low) / step)) + 1
    start = np.floor((low + drained[:awake]) / step + 1e-9).astype(np.int64)
    alertness = (start[:, None] + np.arange(width)[None, :]) * step - drained[:awake, None]
    r = params.decay_rate
    if not 0 < r < 1:
        raise ValueError(f"the hypertension grid needs decay_rate in (0, 1), got {r}")
    points = int(math.ceil(math.log(grid.min_hypertension / grid.max_hypertension) / math.log(r))) + 1
    h = np.concatenate([[0.0], grid.max_hypertension * r ** np.arange(points - 1, -1, -1)])
    p = params.heart_attack_proclivity
    rises = int(params.sleep_half_hours) + 1
    # hypertension after a half-hour's fading (stay) and after a sleep's: lower index and weight of the upper one
    fade_low, fade_w = _faded(h, 1)
    sleep_low, sleep_w = _faded(h, rises)
    coffee_low, coffee_w = _bracket(h, h + COFFEE_RISE[1])
    wake_low, wake_high = params.wake_alertness
    b1 = (start[1] + np.arange(width)) * step
    waking = ((b1 >= wake_low - 1e-9) & (b1 <= wake_high + 1e-9)).astype(np.float64)
    ends = np.flatnonzero(waking)
    if len(ends) < 2 or abs(b1[ends[0]] - wake_low) > 1e-9 or abs(b1[ends[-1]] - wake_high) > 1e-9:
        raise ValueError(f"alertness_step {step} must divide the waking interval's ends {params.wake_alertness}")
    waking[ends[[0, -1]]] = 0.5  # the trapezoid rule over the waking interval
    b0 = (start[0] + np.arange(width)) * step
    if np.any(np.abs(b0[ends] - b1[ends]) > 1e-9):
        raise ValueError("the waking alertness must lie in the windows of t = 0 and t = 1 alike")
    return {
        "work": productivity(alertness, 0.0),
        "alertness": alertness,
        "drained": drained,
        "start": start,
        "shift": np.diff(start),
        "h": h,
        # the risk above the floor r(0) that no policy avoids: what the drinks cost
        "risk_stay": heart_attack_risk(h * r, p) - heart_attack_risk(0.0, p),
        "risk_sleep": heart_attack_risk(h * r**rises, p) - heart_attack_risk(0.0, p),
        "floor": np.array([heart_attack_risk(0.0, p)]),
        "fade_low": fade_low,
        "fade_w": fade_w,
        "sleep_low": sleep_low,
        "sleep_w": sleep_w,
        "coffee_low": coffee_low,
        "coffee_w": coffee_w,
        "coffee_ok": (h + COFFEE_RISE[1] <= h[-1] * (1 + 1e-12)).astype(np.bool_),
        "wake_index": ends[0] + np.arange(len(ends)),
        "wake_weight": waking[ends[0] : ends[-1] + 1] / waking.sum(),
        "wake_work": productivity(b1[ends[0] : ends[-1] + 1], 0.0),
        "coffee_points": np.array([coffee_points]),
        "sleep_time": np.array([1.0 + params.sleep_half_hours]),
    }


def _faded(h: np.ndarray, shifts: int) -> tuple[np.ndarray, np.ndarray]:
    """Where ``h * r ** shifts`` lies: ``shifts`` points down on the geometric part, interpolated towards 0 below."""
    index = np.arange(len(h))
    low = np.maximum(index - shifts, 0)
    weight = np.zeros(len(h))
    below = (index >= 1) & (index - shifts < 1)
    low[below] = 0
    weight[below] = h[index[below]] * (h[2] / h[1]) ** -shifts / h[1] if len(h) > 2 else 0.0
    weight[0] = 0.0
    return low.astype(np.int64), weight


def _bracket(h: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    y = np.minimum(y, h[-1])
    low = np.clip(np.searchsorted(h, y * (1 + 1e-12), side="right") - 1, 0, len(h) - 2)
    weight = np.clip((y - h[low]) / (h[low + 1] - h[low]), 0.0, 1.0)
    return low.astype(np.int64), weight


@dataclass(frozen=True)
class Sweep:
    """One backward pass at ``(rate, scale)``: expected work, time and attacks above the floor from the start, the
    start's value, and the policy's rows (``actions[k]`` for ``k + 1`` decisions left, up to ``kept`` rows; the last
    serves beyond)."""

    rate: float
    scale: float
    work: float
    time: float
    attacks: float
    value: float
    floor: float
    actions: np.ndarray = field(repr=False)
    gains: tuple[float, float] = (-math.inf, -math.inf)


def backward(
    grid: PressureGrid,
    rate: float,
    scale: float,
    kept: int,
    fixed: np.ndarray | None = None,
    bonus: float = math.nan,
    stop_at_gain: bool = False,
) -> Sweep:
    """Maximise ``E[work - rate * time - scale * penalty * extra]`` over every policy on the grid (``extra``: the
    summed risk above the floor ``max_steps * r(0)``, the expected attacks the drinks add), by a backward
    pass over all ``max_steps`` decisions (or, with ``fixed``, follow those rows: policy evaluation). With a
    ``bonus`` (not NaN) it checks drinks in every state and decision (``Sweep.gains``: see `_step`; a beer's
    intoxication is credited ``bonus * (1 - decay_rate ** n)`` with ``n`` decisions left); ``stop_at_gain`` stops
    the pass at the first decision where a drink gains (the figures are then those of a shorter episode)."""
    tab, params = grid.tables, grid.params
    shape = grid.shape
    arrays, out, stay, coffee = (np.zeros((3, *shape)) for _ in range(4))
    beer = np.zeros((2, *shape)) if not math.isnan(bonus) else np.zeros((0, *shape))
    gains = np.full(2, -np.inf)
    kept = min(kept, params.max_steps)
    actions = np.zeros((kept, *shape), dtype=np.int8)
    weight = np.array([1.0, -rate, -scale * params.heart_attack_penalty])
    for n in range(1, params.max_steps + 1):
        row = min(n, kept) - 1
        forced = fixed[min(n, len(fixed)) - 1] if fixed is not None else np.empty((0, 0, 0), dtype=np.int8)
        later = bonus * (1.0 - params.decay_rate**n)  # what intoxication can add over n decisions, at most
        _step(arrays, out, stay, coffee, beer, gains, later, weight, forced, actions[row], *_kernel_tables(tab))
        arrays, out = out, arrays
        if stop_at_gain and gains.max() > 0:
            break
    start = arrays[:, 0, 0][:, tab["wake_index"]] @ tab["wake_weight"]
    work, time, attacks = (float(v) for v in start)
    floor = float(tab["floor"][0])
    return Sweep(rate, scale, work, time, attacks, float(weight @ start), floor, actions, tuple(gains.tolist()))


def _kernel_tables(tab: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    names = ("work", "shift", "h", "risk_stay", "risk_sleep", "fade_low", "fade_w", "sleep_low", "sleep_w")
    more = ("coffee_low", "coffee_w", "coffee_ok", "wake_index", "wake_weight", "wake_work", "coffee_points")
    return (*(tab[k] for k in names + more), tab["sleep_time"], tab["floor"])


@njit(cache=CACHE)
def _step(
    nxt: Any,
    out: Any,
    stay: Any,
    coffee: Any,
    beer: Any,
    gains: Any,
    bonus: Any,
    weight: Any,
    forced: Any,
    actions: Any,
    work: Any,
    shift: Any,
    h: Any,
    risk_stay: Any,
    risk_sleep: Any,
    fade_low: Any,
    fade_w: Any,
    sleep_low: Any,
    sleep_w: Any,
    coffee_low: Any,
    coffee_w: Any,
    coffee_ok: Any,
    wake_index: Any,
    wake_weight: Any,
    wake_work: Any,
    coffee_points: Any,
    sleep_time: Any,
    floor: Any,
) -> Any:
    """One decision back: ``out`` (work, time, attacks) for one more decision left than ``nxt``, and its actions
    (``stay``, ``coffee`` and ``beer`` are work space). With ``beer`` of length > 0 it also raises ``gains[0]`` to
    the most a coffee gains over the best other action in any state, and ``gains[1]`` to the most a beer (its
    alertness and hypertension, plus ``bonus`` for its intoxication) gains over the best action."""
    awake, hp, width = nxt.shape[1], nxt.shape[2], nxt.shape[3]
    reward = np.empty(3)
    # staying awake after the action's effects: the half-hour's work, fading, the coin
    for t in range(awake):
        for j in range(hp):
            rho = risk_stay[j] + floor[0]
            lo, w = fade_low[j], fade_w[j]
            for i in range(width):
                if t == awake - 1:
                    for k in range(3):
                        stay[k, t, j, i] = np.nan
                    continue
                i2 = max(i - shift[t], 0)
                reward[0], reward[1], reward[2] = work[t, i], 1.0, risk_stay[j]
                for k in range(3):
                    faded = nxt[k, t + 1, lo, i2] * (1 - w) + nxt[k, t + 1, min(lo + 1, hp - 1), i2] * w
                    stay[k, t, j, i] = reward[k] + (1 - rho) * faded + rho * nxt[k, t + 1, 0, i2]
    # a sleep: hypertension fades through the rest, a fresh day's first half-hour, the coin
    sleep = np.zeros((3, hp))
    for j in range(hp):
        rho = risk_sleep[j] + floor[0]
        lo, w = sleep_low[j], sleep_w[j]
        for m in range(len(wake_index)):
            i = wake_index[m]
            reward[0], reward[1], reward[2] = wake_work[m], sleep_time[0], risk_sleep[j]
            for k in range(3):
                faded = nxt[k, 1, lo, i] * (1 - w) + nxt[k, 1, min(lo + 1, hp - 1), i] * w
                sleep[k, j] += wake_weight[m] * (reward[k] + (1 - rho) * faded + rho * nxt[k, 1, 0, i])
    _drink(stay, coffee, h, coffee_low, coffee_w, coffee_ok, 0, coffee_points[0])
    checking = beer.shape[0] > 0
    if checking:
        beer[0] = weight[0] * stay[0] + weight[1] * stay[1] + weight[2] * stay[2]
        _drink(beer[:1], beer[1:], h, coffee_low, coffee_w, coffee_ok, -(coffee_points[0] // 2), 0)
    for t in range(awake):
        for j in range(hp):
            for i in range(width):
                a = NOTHING
                if forced.shape[0] > 0:
                    a = forced[t, j, i]
                else:
                    best = -np.inf
                    if t < awake - 1:
                        best = (
                            weight[0] * stay[0, t, j, i] + weight[1] * stay[1, t, j, i] + weight[2] * stay[2, t, j, i]
                        )
                    slept = weight[0] * sleep[0, j] + weight[1] * sleep[1, j] + weight[2] * sleep[2, j]
                    if slept > best:
                        best, a = slept, SLEEP
                    if not np.isnan(coffee[0, t, j, i]):
                        drunk = (
                            weight[0] * coffee[0, t, j, i]
                            + weight[1] * coffee[1, t, j, i]
                            + weight[2] * coffee[2, t, j, i]
                        )
                        if checking:
                            gains[0] = max(gains[0], drunk - best)
                        if drunk > best:
                            best, a = drunk, COFFEE
                    if checking and not np.isnan(beer[1, t, j, i]):
                        gains[1] = max(gains[1], beer[1, t, j, i] + bonus - best)
                actions[t, j, i] = a
                for k in range(3):
                    if a == SLEEP:
                        out[k, t, j, i] = sleep[k, j]
                    elif a == COFFEE:
                        out[k, t, j, i] = coffee[k, t, j, i]
                    else:
                        out[k, t, j, i] = stay[k, t, j, i]


@njit(cache=CACHE)
def _drink(
    stay: Any,
    out: Any,
    h: Any,
    coffee_low: Any,
    coffee_w: Any,
    coffee_ok: Any,
    first: Any,
    last: Any,
) -> Any:
    """A drink's value: ``stay`` averaged over hypertension ``+ U(0, 0.3)`` (exact for the piecewise-linear
    interpolant) and alertness ``+ U(first, last) * step`` (the trapezoid rule over the lattice) into ``out``; NaN off
    the grid."""
    points = last - first
    arrays, awake, hp, width = stay.shape
    out[:] = np.nan
    column = np.empty(hp)
    integral = np.empty(hp)
    prefix = np.empty(width + 1)
    mean_h = np.empty((hp, width))
    for k in range(arrays):
        for t in range(awake - 1):
            for i in range(width):
                for j in range(hp):
                    column[j] = stay[k, t, j, i]
                integral[0] = 0.0
                for j in range(1, hp):
                    integral[j] = integral[j - 1] + (column[j] + column[j - 1]) * (h[j] - h[j - 1]) / 2
                for j in range(hp):
                    if not coffee_ok[j]:
                        continue
                    lo, w = coffee_low[j], coffee_w[j]
                    gap = h[lo + 1] - h[lo]
                    upper = integral[lo] + w * gap * (column[lo] + (column[lo] + w * (column[lo + 1] - column[lo]))) / 2
                    mean_h[j, i] = (upper - integral[j]) / (h[lo] + w * gap - h[j])
            for j in range(hp):
                if not coffee_ok[j]:
                    continue
                prefix[0] = 0.0
                for i in range(width):
                    prefix[i + 1] = prefix[i] + mean_h[j, i]
                for i in range(max(0, -first), width - last):
                    a, b = i + first, i + last
                    total = prefix[b + 1] - prefix[a] - (mean_h[j, a] + mean_h[j, b]) / 2
                    out[k, t, j, i] = total / points
