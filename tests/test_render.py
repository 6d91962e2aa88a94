"""The RGB frame: drawn with NumPy alone, legible, and it shows what changed."""

from __future__ import annotations

import itertools
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import heartpole
from heartpole import render
from heartpole.render import ATTACK_RED, TEXT, clock, draw_frame, landmarks, text_mask

STATE = {
    "alertness": 1.2,
    "hypertension": 0.5,
    "intoxication": 0.02,
    "time_since_slept": 4.0,
    "time_elapsed": 3.0,
    "work_done": 2.5,
}


def frame(state: dict[str, float] | None = None, **options) -> np.ndarray:
    settings = {"action": "drink_coffee", "heart_attack": False, "heart_attacks": 0, "step": 3, "max_steps": 1000}
    return draw_frame(STATE if state is None else state, **{**settings, **options})


def attack_pixels(image: np.ndarray) -> int:
    return int((image == ATTACK_RED).all(axis=2).sum())


def test_frame_is_a_nontrivial_rgb_image() -> None:
    image = frame()
    assert image.shape == (400, 600, 3) and image.dtype == np.uint8
    colors = np.unique(image.reshape(-1, 3), axis=0)
    assert len(colors) >= 15  # panels, gauges, text, heart, icon
    assert (image == TEXT).all(axis=2).sum() > 2000  # plenty of text


@pytest.mark.parametrize("name", list(STATE))
def test_every_state_variable_changes_the_frame(name: str) -> None:
    changed = {**STATE, name: STATE[name] * 2 + 1}
    assert not np.array_equal(frame(), frame(changed))


def test_last_action_heart_attacks_and_step_change_the_frame() -> None:
    base = frame()
    for options in ({"action": "drink_beer"}, {"action": "sleep"}, {"action": None}, {"heart_attacks": 4}, {"step": 9}):
        assert not np.array_equal(base, frame(**options)), options


def test_each_action_is_drawn_differently() -> None:
    images = [frame(action=a.name) for a in heartpole.V0_ACTIONS] + [frame(action=None)]
    for a, b in itertools.combinations(images, 2):
        assert not np.array_equal(a, b)


def test_clock_starts_at_nine_and_counts_half_hours() -> None:
    assert clock(0) == (1, 9, 0)
    assert clock(1) == (1, 9, 30)
    assert clock(29) == (1, 23, 30)
    assert clock(30) == (2, 0, 0)
    assert clock(48 * 3 + 1) == (4, 9, 30)


def test_the_clock_is_written_in_the_header() -> None:
    image = frame({**STATE, "time_elapsed": 31.0})  # 09:00 + 15.5 h = day 2, 00:30
    mask = text_mask("DAY 2  00:30", 4)
    region = image[19 : 19 + mask.shape[0], 66 : 66 + mask.shape[1]]
    assert (region[mask] == TEXT).all()
    later = frame({**STATE, "time_elapsed": 32.0})
    rows = np.flatnonzero((image != later).any(axis=(1, 2)))
    gauges = (rows >= render.ROWS_TOP) & (rows < render._row_y(4))
    assert rows.min() < render.HEADER_HEIGHT and not gauges.any()  # the clock changed, the body did not


def test_heart_attack_marker_only_on_attack_steps() -> None:
    assert attack_pixels(frame()) == 0
    assert attack_pixels(frame(heart_attack=True, heart_attacks=1)) > 20_000  # red border and panel

    env = heartpole.HeartPole(render_mode="rgb_array", heart_attack_proclivity=1.0, max_steps=150)
    env.reset(seed=0)
    assert attack_pixels(env.render()) == 0
    attacks = 0
    for _ in range(150):
        _, _, _, _, info = env.step(1)  # coffee every half-hour
        attacks += info["heart_attack"]
        assert (attack_pixels(env.render()) > 0) == info["heart_attack"]
    assert attacks >= 2


def test_extra_variables_get_their_own_gauge() -> None:
    state = {**STATE, "thc": 0.3}
    image = frame(state)
    assert image.shape == (400 + render.ROW_HEIGHT, 600, 3)
    assert not np.array_equal(image, frame({**state, "thc": 3.0}))
    assert not np.array_equal(image, frame(state, action="smoke_joint"))  # an action without an icon


def test_values_out_of_range_are_clipped_not_crashing() -> None:
    wild = {**STATE, "alertness": -7.5, "hypertension": 80.0, "intoxication": 3.0, "time_since_slept": 400.0}
    image = frame(wild, step=10**6, max_steps=10, heart_attacks=12345)
    assert image.shape == (400, 600, 3)


def test_font_glyphs_are_distinct_and_sized() -> None:
    glyphs = {char: render._glyph(char).tobytes() for char in render.FONT}
    assert len(set(glyphs.values())) == len(glyphs)  # no two characters look the same
    assert text_mask("09:30", 3).shape == (21, (5 * 6 - 1) * 3)
    assert np.array_equal(render._glyph("a"), render._glyph("A"))
    assert np.array_equal(render._glyph("~"), render._glyph("?"))


def test_landmarks_follow_the_model() -> None:
    marks = landmarks()
    assert marks.ballmer_peak == pytest.approx(0.135, abs=1e-3)
    assert marks.high_pressure == pytest.approx(6.0, abs=0.01)
    assert marks.high_risk == pytest.approx(0.25, abs=1e-3)
    assert marks.anxious == pytest.approx(3.0, abs=0.01)
    assert marks.fading_hours == pytest.approx(20.0, abs=0.01)
    assert marks.productive[0] < marks.best_alertness < marks.productive[1]


def test_vector_env_renders_one_frame_per_env() -> None:
    env = gym.make_vec("HeartPole-v0", num_envs=3, vectorization_mode="vector_entry_point", render_mode="rgb_array")
    env.reset(seed=1)
    env.step(np.array([0, 1, 3]))
    frames = env.render()
    assert len(frames) == 3 and all(f.shape == (400, 600, 3) for f in frames)
    assert not np.array_equal(frames[0], frames[1])


def test_drawing_a_frame_needs_neither_matplotlib_nor_pillow() -> None:
    code = (
        "import sys, heartpole\n"
        "env = heartpole.HeartPole(render_mode='rgb_array'); env.reset(seed=0); env.step(3)\n"
        "assert env.render().shape == (400, 600, 3)\n"
        "loaded = [m for m in ('matplotlib', 'PIL', 'imageio') if m in sys.modules]\n"
        "assert not loaded, loaded\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
