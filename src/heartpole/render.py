"""How HeartPole shows itself: the text log of the tutorial and the RGB frame for videos."""

from __future__ import annotations

from typing import Mapping


def log_lines(action: str, state: Mapping[str, float], heart_attack: bool) -> list[str]:
    """The tutorial's log for one step: the chosen action, ``HEART ATTACK`` if one occurred, the state."""
    lines = [f"Chosen action: {action}"]
    if heart_attack:
        lines.append("HEART ATTACK")
    lines.append("{" + ", ".join(f"'{name}': {value:.6g}" for name, value in state.items()) + "}")
    return lines
