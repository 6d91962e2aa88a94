"""Stable-Baselines3 callbacks: the reward statistics' window, the learning curve, the progress bar."""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

import heartpole  # noqa: F401  (registers the HeartPole ids)
from heartpole.progress import Progress

# ------------------------------------------------------------------------------------------------------
# callbacks


class RewardStatsWindow(BaseCallback):
    """Keep VecNormalize's reward statistics to about the last ``window`` samples.

    ``VecNormalize`` divides rewards by the standard deviation of discounted returns seen so far, weighing
    the whole run alike. Capping the sample count makes the statistics an exponential moving estimate that
    follows the current policy (whose returns shrink by orders of magnitude once it stops drinking).
    """

    def __init__(self, normalizer: VecNormalize, window: float) -> None:
        super().__init__()
        if not window > 0:
            raise ValueError(f"window must be positive, got {window!r}")
        self.normalizer, self.window = normalizer, float(window)

    def _on_step(self) -> bool:
        rms = self.normalizer.ret_rms
        if rms.count > self.window:
            rms.count = self.window
        return True


class LearningCurve(BaseCallback):
    """Collect training episodes' true return, heart attacks and final score into rows of a learning curve.

    A row is written each time at least ``episodes_per_row`` episodes have ended since the last row (and at
    the end of training for any left over); it holds the timestep and the means over those episodes.
    """

    def __init__(self, episodes_per_row: int = 16) -> None:
        super().__init__()
        self.episodes_per_row = max(1, int(episodes_per_row))
        self.rows: list[dict[str, float]] = []
        self._pending: list[dict[str, Any]] = []

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            episode = info.get("episode")
            if episode is not None and "heart_attacks" in episode:
                self._pending.append(episode)
        if len(self._pending) >= self.episodes_per_row:
            self._flush()
        return True

    def _on_training_end(self) -> None:
        self._flush()

    def _flush(self) -> None:
        if not self._pending:
            return
        self.rows.append(
            {
                "timesteps": int(self.num_timesteps),
                "mean_return": float(np.mean([e["r"] for e in self._pending])),
                "heart_attacks": float(np.mean([e["heart_attacks"] for e in self._pending])),
                "score": float(np.mean([e["score"] for e in self._pending])),
            }
        )
        self._pending = []


class ProgressBar(BaseCallback):
    """A [`Progress`][heartpole.progress.Progress] bar over the timesteps (shown when stderr is a terminal,
    with ``HEARTPOLE_PROGRESS=1``, or when ``force`` is set)."""

    def __init__(self, total: int, description: str = "training", force: bool = False) -> None:
        super().__init__()
        self.total, self.description, self.force = int(total), description, force
        self._bar: Progress | None = None

    def _on_training_start(self) -> None:
        self._bar = Progress(self.total, self.description, enabled=True if self.force else None, unit="step")

    def _on_step(self) -> bool:
        if self._bar is not None:
            self._bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
