"""The reward the agent learns from: the env's own, or the default preset's shaped reward."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole.parameters import Params, check_number, is_number

# ------------------------------------------------------------------------------------------------------
# the training reward


@dataclass(frozen=True)
class TrainingReward:
    """The reward an agent is trained on. Evaluation always uses the env's own return.

    Attributes:
        expected_risk: replace the realised ``-penalty x heart_attack`` by
            ``-penalty x (heart_attack_risk - risk at zero blood pressure)``: the same expectation for every
            policy (up to a constant per step), without the coin's noise.
        score_rate: ``None`` keeps the env's score reward (the change of ``work_done / time_elapsed``); a
            number ``rate`` uses ``(productivity - rate x half_hours_passed) / horizon`` instead; ``"auto"``
            uses the running work per half-hour of the policy being trained as the rate (an exponential
            average over about ``rate_window`` steps of all envs together), for variants whose best score
            is unknown.
        rate_window: the averaging window of ``score_rate="auto"``, in vector steps.
        horizon: half-hours of a typical episode, the scale of the score part when ``score_rate`` is set.
    """

    expected_risk: bool = False
    score_rate: float | Literal["auto"] | None = None
    rate_window: float = 2000.0
    horizon: float = 2000.0

    def __post_init__(self) -> None:
        rate = self.score_rate
        if rate is not None and rate != "auto" and not (is_number(rate) and math.isfinite(rate)):
            raise ValueError(f"score_rate must be a finite number, 'auto' or None, got {rate!r}")
        check_number("rate_window", self.rate_window, 1.0)
        check_number("horizon", self.horizon, 0.0, low_open=True)

    @property
    def is_env_reward(self) -> bool:
        """Whether this is exactly the env's reward."""
        return not self.expected_risk and self.score_rate is None

    def describe(self, penalty: float = Params.heart_attack_penalty) -> str:
        """One line for humans, with the env's heart-attack ``penalty`` (v0's by default)."""
        if self.is_env_reward:
            return f"the env's reward (score change - {penalty:g} x heart attack)"
        score = (
            "score change"
            if self.score_rate is None
            else f"(productivity - {self.score_rate} x half-hours) / {self.horizon:g}"
        )
        risk = f"{penalty:g} x " + ("(heart-attack risk - floor)" if self.expected_risk else "heart attack")
        return f"{score} - {risk}"


ENV_REWARD = TrainingReward()
SHAPED_REWARD = TrainingReward(expected_risk=True, score_rate=0.32, horizon=2000.0)
