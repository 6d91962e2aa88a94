"""How HeartPole shows itself: the text log of the tutorial and the RGB frame for videos.

The frame is drawn with NumPy alone (no matplotlib, no pillow): rectangles, a few cached shape masks
and a 5x7 pixel font, so ``render_mode="rgb_array"`` works with HeartPole's runtime dependencies.
Everything that does not change between steps (panels, labels, scales) is drawn once per set of state
variables and copied for each frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache, lru_cache
from typing import NamedTuple

import numpy as np

from heartpole.model import alertness_decay, ballmer, crippling_anxiety, heart_attack_risk, productivity

Color = tuple[int, int, int]


def log_lines(action: str, state: Mapping[str, float], heart_attack: bool) -> list[str]:
    """The tutorial's log for one step: the chosen action, ``HEART ATTACK`` if one occurred, the state."""
    lines = [f"Chosen action: {action}"]
    if heart_attack:
        lines.append("HEART ATTACK")
    lines.append("{" + ", ".join(f"'{name}': {value:.6g}" for name, value in state.items()) + "}")
    return lines


class Landmarks(NamedTuple):
    """The model's landmarks that the frame, the dashboard and ``heartpole play`` point out, read off
    [`heartpole.model`][heartpole.model]'s functions (so they follow the model when it changes).

    Attributes:
        productive: the alertness range where a sober half-hour earns at least 90% of the most it can.
        best_alertness: the alertness where a sober half-hour earns the most.
        anxious: the alertness where crippling anxiety takes half the work.
        ballmer_peak: the blood alcohol content where programming skill peaks.
        high_pressure: the hypertension where the heart-attack risk reaches half its maximum.
        high_risk: the heart-attack risk per half-hour at ``high_pressure`` (default proclivity).
        fading_hours: hours awake after which alertness falls by half a point every half-hour.
    """

    productive: tuple[float, float]
    best_alertness: float
    anxious: float
    ballmer_peak: float
    high_pressure: float
    high_risk: float
    fading_hours: float


@lru_cache(maxsize=1)
def landmarks() -> Landmarks:
    """The [`Landmarks`][heartpole.render.Landmarks] of the model, computed once on fine grids."""
    alertness = np.linspace(0.0, 10.0, 10001)
    work = productivity(alertness, 0.0)
    productive = alertness[work >= 0.9 * work.max()]
    drink = np.linspace(0.0, 0.5, 50001)
    pressure = np.linspace(0.0, 30.0, 30001)
    risk = heart_attack_risk(pressure)
    awake = np.linspace(0.0, 200.0, 20001)
    high_pressure = float(pressure[np.argmax(risk >= risk[-1] / 2)])
    return Landmarks(
        productive=(float(productive[0]), float(productive[-1])),
        best_alertness=float(alertness[np.argmax(work)]),
        anxious=float(alertness[np.argmax(crippling_anxiety(alertness) >= 0.5)]),
        ballmer_peak=float(drink[np.argmax(ballmer(drink))]),
        high_pressure=high_pressure,
        high_risk=float(heart_attack_risk(high_pressure)),
        fading_hours=float(awake[np.argmax(alertness_decay(awake) >= 0.5)]) / 2,
    )


# --------------------------------------------------------------------------------------------------------
# The 5x7 pixel font: each glyph is seven rows of five bits (most significant bit on the left), in hex.
# fmt: off
FONT: dict[str, str] = {
    "0": "0e11131519110e", "1": "040c040404040e", "2": "0e11010204081f", "3": "1f02040201110e",
    "4": "02060a121f0202", "5": "1f101e0101110e", "6": "0608101e11110e", "7": "1f010204080808",
    "8": "0e11110e11110e", "9": "0e11110f01020c", "A": "0e1111111f1111", "B": "1e11111e11111e",
    "C": "0e11101010110e", "D": "1c12111111121c", "E": "1f10101e10101f", "F": "1f10101e101010",
    "G": "0e11101711110f", "H": "1111111f111111", "I": "0e04040404040e", "J": "0702020202120c",
    "K": "11121418141211", "L": "1010101010101f", "M": "111b1515111111", "N": "11111915131111",
    "O": "0e11111111110e", "P": "1e11111e101010", "Q": "0e11111115120d", "R": "1e11111e141211",
    "S": "0f10100e01011e", "T": "1f040404040404", "U": "1111111111110e", "V": "11111111110a04",
    "W": "1111111515150a", "X": "11110a040a1111", "Y": "1111110a040404", "Z": "1f01020408101f",
    " ": "00000000000000", ":": "000c0c000c0c00", ".": "00000000000c0c", "/": "00010204081000",
    "-": "0000001f000000", "%": "18190204081303", "+": "0004041f040400", "(": "02040808080402",
    ")": "08040202020408", "!": "04040404040004", "?": "0e110102040004", ",": "0000000c0c0408",
    "=": "00001f001f0000", "<": "02040810080402", ">": "08040201020408", "_": "0000000000001f",
    "*": "0004150e150400", "#": "0a0a1f0a1f0a0a", "[": "0e08080808080e", "]": "0e02020202020e",
    "'": "04040800000000", "|": "04040404040404",
}
# fmt: on
GLYPH_WIDTH, GLYPH_HEIGHT = 5, 7


@cache
def _glyph(char: str) -> np.ndarray:
    """The (7, 5) boolean mask of one character; lower case is drawn as upper case, unknowns as '?'."""
    code = FONT.get(char.upper(), FONT["?"])
    rows = [int(code[2 * i : 2 * i + 2], 16) for i in range(GLYPH_HEIGHT)]
    bits = 1 << np.arange(GLYPH_WIDTH - 1, -1, -1)
    return (np.array(rows)[:, None] & bits) > 0


@lru_cache(maxsize=4096)
def text_mask(text: str, scale: int = 1) -> np.ndarray:
    """The boolean mask of ``text`` in the pixel font, each font pixel drawn as a ``scale`` x ``scale`` block."""
    if not text:
        return np.zeros((GLYPH_HEIGHT * scale, 0), dtype=bool)
    gap = np.zeros((GLYPH_HEIGHT, 1), dtype=bool)
    columns = [part for char in text for part in (_glyph(char), gap)][:-1]
    return np.repeat(np.repeat(np.hstack(columns), scale, axis=0), scale, axis=1)


def text_width(text: str, scale: int) -> int:
    """The width in pixels of ``text`` drawn at ``scale``."""
    return max(len(text) * (GLYPH_WIDTH + 1) - 1, 0) * scale


# --------------------------------------------------------------------------------------------------------
# Colours and layout.
WIDTH, BASE_HEIGHT, ROW_HEIGHT = 600, 400, 54
BACKGROUND: Color = (28, 32, 44)
PANEL: Color = (40, 45, 60)
TRACK: Color = (62, 68, 86)
TEXT: Color = (236, 238, 244)
DIM_TEXT: Color = (150, 158, 178)
SHADOW: Color = (10, 12, 20)
ATTACK_RED: Color = (235, 16, 40)  # used by the heart-attack marker and nothing else
ALERT_BLUE: Color = (80, 170, 255)
SWEET_SPOT: Color = (58, 110, 80)
DRINK_AMBER: Color = (240, 170, 40)
AWAKE_VIOLET: Color = (170, 130, 240)
EXTRA_TEAL: Color = (60, 200, 180)
WORK_GREEN: Color = (110, 220, 120)
NIGHT_SKY: Color = (16, 22, 58)
DAY_SKY: Color = (92, 158, 222)
SUN: Color = (255, 214, 70)
MOON: Color = (226, 230, 240)

LEFT_X, RIGHT_X, BAR_WIDTH, BAR_HEIGHT = 10, 212, 376, 16
HEADER_HEIGHT, ROWS_TOP = 66, 84
EPISODE_START_MINUTES = 9 * 60  # the episode starts at 09:00 on day 1

V0_GAUGES = ("alertness", "hypertension", "intoxication", "time_since_slept")
V0_NAMES = (*V0_GAUGES, "time_elapsed", "work_done")
ALERTNESS_RANGE, HYPERTENSION_RANGE, INTOXICATION_RANGE, AWAKE_HOURS_RANGE = 5.0, 10.0, 0.25, 30.0
LABELS = {
    "alertness": "ALERTNESS",
    "hypertension": "BLOOD PRESSURE",
    "intoxication": "INTOXICATION",
    "time_since_slept": "AWAKE FOR",
}


def _fill(image: np.ndarray, x: int, y: int, w: int, h: int, color: Color) -> None:
    image[max(y, 0) : max(y + h, 0), max(x, 0) : max(x + w, 0)] = color


def _paint(image: np.ndarray, mask: np.ndarray, x: int, y: int, color: Color) -> None:
    """Paint ``color`` where ``mask`` is true, with the mask's top-left corner at (x, y), clipped to the image."""
    height, width = image.shape[:2]
    x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + mask.shape[1], width), min(y + mask.shape[0], height)
    if x0 < x1 and y0 < y1:
        image[y0:y1, x0:x1][mask[y0 - y : y1 - y, x0 - x : x1 - x]] = color


def put_text(
    image: np.ndarray,
    text: str,
    x: int,
    y: int,
    scale: int = 2,
    color: Color = TEXT,
    align: str = "left",
    shadow: bool = False,
) -> None:
    """Draw ``text`` with its top at ``y``; ``x`` is its left edge, centre or right edge as ``align`` says."""
    mask = text_mask(text, scale)
    x = {"left": x, "center": x - mask.shape[1] // 2, "right": x - mask.shape[1]}[align]
    if shadow:
        _paint(image, mask, x + max(scale // 2, 1), y + max(scale // 2, 1), SHADOW)
    _paint(image, mask, x, y, color)


@cache
def _disc(radius: int) -> np.ndarray:
    yy, xx = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    return xx**2 + yy**2 <= radius**2


@cache
def _heart(size: int) -> np.ndarray:
    """A heart-shaped mask ``size`` pixels wide, from the curve ``(x^2 + y^2 - 1)^3 = x^2 y^3``."""
    yy, xx = np.mgrid[0:size, 0:size].astype(float)
    x = (xx + 0.5) / size * 2.5 - 1.25
    y = 1.3 - (yy + 0.5) / size * 2.45
    return (x**2 + y**2 - 1) ** 3 - x**2 * y**3 <= 0


@cache
def _crack(size: int) -> np.ndarray:
    """A zig-zag crack down the middle of `_heart`, for the heart-attack marker."""
    mask = np.zeros((size, size), dtype=bool)
    points = [(0.5, 0.18), (0.42, 0.38), (0.58, 0.52), (0.44, 0.68), (0.52, 0.86)]
    width = max(size // 18, 2)
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        for t in np.linspace(0.0, 1.0, size):
            cx, cy = int((x0 + (x1 - x0) * t) * size), int((y0 + (y1 - y0) * t) * size)
            mask[max(cy - width, 0) : cy + width, max(cx - width, 0) : cx + width] = True
    return mask & _heart(size)


# Pixel-art icons for the built-in actions: one character per pixel, '.' transparent.
# fmt: off
ICONS: dict[str, tuple[str, ...]] = {
    "drink_coffee": (
        "....s...s.....", "...s...s......", "....s...s.....", "...s...s......", "..............",
        "wwwwwwwwwww...", "wbbbbbbbbbwww.", "wbbbbbbbbbw..w", "wwwwwwwwwww..w", "wwwwwwwwwwwwww",
        ".wwwwwwwwww...", "..wwwwwwww....", "...wwwwww.....", "..............",
    ),
    "drink_beer": (
        "..ffffffff....", ".ffffffffff...", ".ffffffffff...", ".gyyyyyyyyg...", ".gyyyyyyyyggg.",
        ".gyyyyyyyyg.g.", ".gyyyyyyyyg.g.", ".gyyyyyyyyg.g.", ".gyyyyyyyyg.g.", ".gyyyyyyyyggg.",
        ".gyyyyyyyyg...", ".gyyyyyyyyg...", ".gggggggggg...", "..............",
    ),
    "do_nothing": (
        "..............", ".kkkkkkkkkkkk.", ".kqqqqqqqqqqk.", ".kqcccqcqqqqk.", ".kqqqqqqqqqqk.",
        ".kqqcqcccqqqk.", ".kqqqqqqqqqqk.", ".kqccqcqqqqqk.", ".kqqqqqqqqqqk.", ".kkkkkkkkkkkk.",
        "kkkkkkkkkkkkkk", "kkkkkkkkkkkkkk", "..............", "..............",
    ),
}
ICON_COLORS: dict[str, Color] = {
    "s": (170, 176, 190), "w": (245, 245, 240), "b": (120, 72, 36), "f": (250, 250, 245),
    "y": (240, 170, 40), "g": (190, 200, 210), "k": (150, 156, 170), "q": (30, 60, 110),
    "c": (110, 220, 120), "z": (200, 210, 255), "m": (240, 220, 120),
}
# fmt: on
ICON_SCALE = 4


@cache
def _icon_layers(name: str) -> tuple[tuple[np.ndarray, Color], ...]:
    """The icon of action ``name`` as (mask, colour) layers scaled by ``ICON_SCALE``; none for unknown actions."""
    if name == "sleep":
        return _sleep_layers()
    rows = ICONS.get(name)
    if rows is None:
        return ()
    pixels = np.array([list(row) for row in rows])
    layers = []
    for key, color in ICON_COLORS.items():
        mask = pixels == key
        if mask.any():
            layers.append((np.repeat(np.repeat(mask, ICON_SCALE, 0), ICON_SCALE, 1), color))
    return tuple(layers)


def _sleep_layers() -> tuple[tuple[np.ndarray, Color], ...]:
    """The sleep icon: a crescent moon and two Zs."""
    size = 14 * ICON_SCALE
    moon = np.zeros((size, size), dtype=bool)
    _paint_mask(moon, _disc(20), 2, 14)
    _paint_mask(moon, _disc(17), 14, 6, value=False)
    z = np.zeros((size, size), dtype=bool)
    _paint_mask(z, text_mask("Z", 3), 34, 2)
    _paint_mask(z, text_mask("Z", 2), 46, 26)
    return ((moon, ICON_COLORS["m"]), (z, ICON_COLORS["z"]))


def _paint_mask(target: np.ndarray, mask: np.ndarray, x: int, y: int, value: bool = True) -> None:
    """Set ``target`` to ``value`` where ``mask`` is true, its corner at (x, y), clipped to ``target``."""
    _paint(target[..., None], mask, x, y, (value,))  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------------------
# The static part of a frame, drawn once per set of extra variables.
def _row_y(index: int) -> int:
    return ROWS_TOP + index * ROW_HEIGHT


def _gauge_names(extras: tuple[str, ...]) -> tuple[str, ...]:
    return (*V0_GAUGES, *extras)


def _label(name: str) -> str:
    return LABELS.get(name, name.upper().replace("_", " "))


@lru_cache(maxsize=8)
def _template(extras: tuple[str, ...]) -> np.ndarray:
    """The frame without the state: panels, gauge labels, tracks and scale marks."""
    names = _gauge_names(extras)
    height = BASE_HEIGHT + ROW_HEIGHT * len(extras)
    image = np.empty((height, WIDTH, 3), dtype=np.uint8)
    image[:] = BACKGROUND
    _fill(image, 0, HEADER_HEIGHT, WIDTH, 8, TRACK)  # the episode's progress track
    _fill(image, LEFT_X, ROWS_TOP, 192, height - ROWS_TOP - 8, PANEL)
    for index, name in enumerate(names):
        y = _row_y(index)
        put_text(image, _label(name), RIGHT_X, y, 2, DIM_TEXT)
        _fill(image, RIGHT_X, y + 20, BAR_WIDTH, BAR_HEIGHT, TRACK)
    _draw_scales(image)
    bottom = _row_y(len(names)) + 4
    _fill(image, RIGHT_X - 6, bottom, BAR_WIDTH + 12, height - bottom - 8, PANEL)
    put_text(image, "WORK DONE", RIGHT_X + 4, bottom + 10, 2, DIM_TEXT)
    put_text(image, "SCORE", RIGHT_X + 4, bottom + 42, 2, DIM_TEXT)
    put_text(image, "HEART ATTACKS", LEFT_X + 96, 228, 2, DIM_TEXT, align="center")
    put_text(image, "LAST ACTION", LEFT_X + 96, 282, 2, DIM_TEXT, align="center")
    return image


def _draw_scales(image: np.ndarray) -> None:
    """The marks that give the v0 gauges their meaning: alertness's productive zone, high risk, the Ballmer
    peak and the hours awake after which alertness fades fast."""
    marks = landmarks()
    low, high = (int(a / ALERTNESS_RANGE * BAR_WIDTH) for a in marks.productive)
    y = _row_y(0) + 20
    _fill(image, RIGHT_X + low, y, high - low, BAR_HEIGHT, SWEET_SPOT)
    put_text(image, "SLEEPY", RIGHT_X, y + 19, 1, DIM_TEXT)
    put_text(image, "PRODUCTIVE", RIGHT_X + (low + high) // 2, y + 19, 1, DIM_TEXT, align="center")
    put_text(image, "ANXIOUS", RIGHT_X + BAR_WIDTH, y + 19, 1, DIM_TEXT, align="right")
    _mark(image, 1, marks.high_pressure / HYPERTENSION_RANGE, f"RISK {100 * marks.high_risk:.0f}%")
    _mark(image, 2, marks.ballmer_peak / INTOXICATION_RANGE, "BALLMER PEAK")
    _mark(image, 3, marks.fading_hours / AWAKE_HOURS_RANGE, f"{marks.fading_hours:.0f} H: ALERTNESS FADES")


def _mark(image: np.ndarray, index: int, fraction: float, text: str) -> None:
    """A tick across gauge ``index`` at ``fraction`` of its width, labelled below."""
    y = _row_y(index) + 20
    x = RIGHT_X + int(fraction * BAR_WIDTH)
    _fill(image, x - 1, y - 3, 3, BAR_HEIGHT + 6, DIM_TEXT)
    put_text(image, text, x, y + 19, 1, DIM_TEXT, align="center")


# --------------------------------------------------------------------------------------------------------
# The dynamic part.
def clock(time_elapsed: float) -> tuple[int, int, int]:
    """``(day, hour, minute)`` after ``time_elapsed`` half-hours, the episode starting at 09:00 on day 1.

    >>> clock(0), clock(1), clock(31)
    ((1, 9, 0), (1, 9, 30), (2, 0, 30))
    """
    minutes = EPISODE_START_MINUTES + 30 * int(round(time_elapsed))
    day, minute_of_day = divmod(minutes, 24 * 60)
    return day + 1, minute_of_day // 60, minute_of_day % 60


def _mix(a: Color, b: Color, t: float) -> Color:
    t = min(max(t, 0.0), 1.0)
    return tuple(int(round(x + (y - x) * t)) for x, y in zip(a, b))  # type: ignore[return-value]


def _daylight(hour: float) -> float:
    """0 at night, 1 in the day, a smooth dawn around 06:00 and dusk around 20:00."""
    return float(np.clip((np.sin((hour - 7.0) / 24.0 * 2 * np.pi) + 0.25) * 1.6, 0.0, 1.0))


def _draw_header(image: np.ndarray, time_elapsed: float, step: int, max_steps: int) -> None:
    day, hour, minute = clock(time_elapsed)
    light = _daylight(hour + minute / 60)
    image[:HEADER_HEIGHT] = _mix(NIGHT_SKY, DAY_SKY, light)
    if light > 0.5:
        _paint(image, _disc(20), 14, 12, SUN)
    else:
        _paint(image, _disc(18), 16, 14, MOON)
        _paint(image, _disc(18), 26, 8, _mix(NIGHT_SKY, DAY_SKY, light))
    put_text(image, f"DAY {day}  {hour:02d}:{minute:02d}", 66, 19, 4, TEXT, shadow=True)
    put_text(image, f"STEP {step}/{max_steps}", WIDTH - 14, 14, 2, TEXT, align="right", shadow=True)
    put_text(image, f"{time_elapsed / 2:.1f} H ELAPSED", WIDTH - 14, 40, 2, TEXT, align="right", shadow=True)
    done = int(WIDTH * min(step / max(max_steps, 1), 1.0))
    _fill(image, 0, HEADER_HEIGHT, done, 8, DIM_TEXT)


def _gradient(start: Color, end: Color) -> np.ndarray:
    t = np.linspace(0.0, 1.0, BAR_WIDTH)[None, :, None]
    return (np.array(start) * (1 - t) + np.array(end) * t).astype(np.uint8)


HYPERTENSION_COLORS = _gradient((90, 200, 110), (250, 110, 40))


def _bar(image: np.ndarray, index: int, fraction: float, color: Color | np.ndarray, value: str) -> None:
    """Fill gauge ``index`` to ``fraction`` (clipped to [0, 1]) and write ``value`` at its right."""
    y = _row_y(index)
    filled = int(round(min(max(fraction, 0.0), 1.0) * BAR_WIDTH))
    target = image[y + 24 : y + 20 + BAR_HEIGHT - 4, RIGHT_X : RIGHT_X + filled]
    target[:] = color[:, :filled] if isinstance(color, np.ndarray) else color
    put_text(image, value, RIGHT_X + BAR_WIDTH, y, 2, TEXT, align="right")


def _draw_gauges(image: np.ndarray, state: Mapping[str, float], extras: tuple[str, ...]) -> None:
    alertness, pressure = state["alertness"], state["hypertension"]
    drink, awake_hours = state["intoxication"], state["time_since_slept"] / 2
    _bar(image, 0, alertness / ALERTNESS_RANGE, ALERT_BLUE, f"{alertness:.2f}")
    _bar(image, 1, pressure / HYPERTENSION_RANGE, HYPERTENSION_COLORS, f"{pressure:.2f}")
    _bar(image, 2, drink / INTOXICATION_RANGE, DRINK_AMBER, f"BAC {drink:.3f}")
    _bar(image, 3, awake_hours / AWAKE_HOURS_RANGE, AWAKE_VIOLET, f"{awake_hours:.1f} H")
    for index, name in enumerate(extras, start=len(V0_GAUGES)):
        value = state[name]
        _bar(image, index, abs(value) / (abs(value) + 1.0), EXTRA_TEAL, f"{value:.3g}")


def _draw_work(image: np.ndarray, state: Mapping[str, float], rows: int) -> None:
    bottom = _row_y(rows) + 4
    elapsed = state["time_elapsed"]
    score = state["work_done"] / elapsed if elapsed else 0.0
    put_text(image, f"{state['work_done']:.1f}", RIGHT_X + BAR_WIDTH - 4, bottom + 6, 3, WORK_GREEN, align="right")
    put_text(image, f"{score:.3f}", RIGHT_X + BAR_WIDTH - 4, bottom + 38, 3, WORK_GREEN, align="right")
    put_text(image, "WORK DONE / TIME ELAPSED", RIGHT_X + 4, bottom + 60, 1, DIM_TEXT)


def _draw_heart(image: np.ndarray, hypertension: float, heart_attack: bool, heart_attacks: int) -> None:
    """The heart, coloured by blood pressure, the risk of a heart attack and the count of heart attacks.

    On the step of a heart attack the left panel flashes red and the heart cracks.
    """
    center_x = LEFT_X + 96
    if heart_attack:
        _fill(image, LEFT_X, ROWS_TOP, 192, 140, ATTACK_RED)
        size = 92
        _paint(image, _heart(size), center_x - size // 2, ROWS_TOP + 6, TEXT)
        _paint(image, _crack(size), center_x - size // 2, ROWS_TOP + 6, SHADOW)
        put_text(image, "HEART ATTACK!", center_x, ROWS_TOP + 100, 2, TEXT, align="center", shadow=True)
        put_text(image, "-100 REWARD", center_x, ROWS_TOP + 122, 1, TEXT, align="center")
    else:
        size = 96
        color = _mix((255, 150, 170), (200, 30, 60), hypertension / landmarks().high_pressure)
        _paint(image, _heart(size), center_x - size // 2, ROWS_TOP + 12, color)
        risk = float(heart_attack_risk(hypertension))
        put_text(image, f"RISK {100 * risk:.2f}%", center_x, 204, 2, TEXT, align="center")
    put_text(image, str(heart_attacks), center_x, 248, 3, ATTACK_RED if heart_attack else TEXT, align="center")


def _draw_action(image: np.ndarray, action: str | None) -> None:
    center_x = LEFT_X + 96
    if action is None:
        put_text(image, "START", center_x, 318, 3, TEXT, align="center")
        return
    layers = _icon_layers(action)
    for mask, color in layers:
        _paint(image, mask, center_x - mask.shape[1] // 2, 302, color)
    words = action.upper().replace("_", " ")
    scale = 2 if text_width(words, 2) <= 180 else 1
    put_text(image, words, center_x, 362 if layers else 320, scale, TEXT, align="center")


def _draw_attack_border(image: np.ndarray) -> None:
    """The red flash of a heart attack around the whole frame."""
    height, width = image.shape[:2]
    border = 8
    _fill(image, 0, 0, width, border, ATTACK_RED)
    _fill(image, 0, height - border, width, border, ATTACK_RED)
    _fill(image, 0, 0, border, height, ATTACK_RED)
    _fill(image, width - border, 0, border, height, ATTACK_RED)


def draw_frame(
    state: Mapping[str, float],
    *,
    action: str | None,
    heart_attack: bool,
    heart_attacks: int,
    step: int,
    max_steps: int,
) -> np.ndarray:
    """Draw one HeartPole state as an RGB ``uint8`` image of shape ``(height, 600, 3)``.

    The frame shows the clock (day and time, the episode starting at 09:00), the step, gauges for
    alertness (with its productive zone), blood pressure (hypertension), intoxication (with the Ballmer
    peak) and hours awake, work done and the running score, a heart coloured by blood pressure with the
    risk of a heart attack, the number of heart attacks and the last action. On the step of a heart attack
    the frame flashes: a red border and a red panel with a cracked heart and the words HEART ATTACK!

    Args:
        state: ``{variable: value}`` with at least HeartPole-v0's six variables; any others (a variant's)
            are drawn as extra gauges, which make the frame 54 pixels taller each.
        action: the name of the last action, or ``None`` before the first step.
        heart_attack: whether the last step caused a heart attack.
        heart_attacks: heart attacks so far in the episode.
        step: steps taken in the episode; ``max_steps``: the episode's length.
    """
    extras = tuple(name for name in state if name not in V0_NAMES)
    image = _template(extras).copy()
    _draw_header(image, float(state["time_elapsed"]), step, max_steps)
    _draw_gauges(image, state, extras)
    _draw_work(image, state, len(V0_GAUGES) + len(extras))
    _draw_heart(image, float(state["hypertension"]), heart_attack, heart_attacks)
    _draw_action(image, action)
    if heart_attack:
        _draw_attack_border(image)
    return image
