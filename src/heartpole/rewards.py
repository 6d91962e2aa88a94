"""The expected-risk correction and the shaped training reward, written once for NumPy and JAX alike.

A heart attack is a coin flipped with a known probability, ``info["heart_attack_risk"]``. Charging
``penalty x probability`` instead of ``penalty x coin`` keeps the expected value and drops the coin's noise
(the difference is a martingale): [`expected_risk`][heartpole.rewards.expected_risk] is that correction,
whether applied to one step's reward or to an episode's final score and summed risks.
[`training_reward`][heartpole.rewards.training_reward] is the reward agents are trained on (the
training extra's `TrainingReward` and the JAX trainer's settings choose its parts).

Both are written with arithmetic operators only, so they take floats, NumPy arrays and ``jax.numpy``
arrays (traced or not) alike, and compute in the arguments' own dtypes.
"""

from __future__ import annotations

from typing import Any, TypeAlias

import numpy as np

from heartpole.model import heart_attack_risk
from heartpole.parameters import Params

Array: TypeAlias = Any
"""A float, a NumPy array or a ``jax.numpy`` array: anything with arithmetic operators."""


def expected_risk(value: Array, risk: Array, penalty: Array, baseline: Array = 0.0) -> Array:
    """``value - penalty x (risk - baseline)``: the heart-attack charge at its probability ``risk``.

    Three uses, one formula:

    * an episode's expected-risk return: its final score, the risks summed over its steps, no baseline;
    * one step's expected-risk reward: the env's reward, the step's risk, the step's coin (0 or 1) as the
      baseline, so that the realized charge is given back and the expected one taken;
    * a training reward's charge: its score part, the step's risk (or the coin itself, to charge the
      realized attack), less the floor of the risk (a constant per step that every policy pays).
    """
    return value - penalty * (risk - baseline)


def exact_risk(pressure: np.ndarray, proclivity: np.ndarray, risk: np.ndarray, heart_attack: np.ndarray) -> np.ndarray:
    """Each env's heart-attack risk of the step just taken, in float64: ``proclivity * sigmoid(hypertension - 6)``
    at the float32 blood pressure and proclivity the step used, where the step reported ``risk`` rounded to float32
    (and computed with float32's ``exp``).

    Summed over an episode, the float32 risks drift: on v0 every step at zero blood pressure carries the same
    rounding, and 1,000 of them put the expected-risk return 6.9e-6 above its exact value. These sum as exactly
    as float64 does.

    Args:
        pressure: ``(n,)`` the blood pressures (hypertension) the step left, float32 (a vector env's
            ``variable("hypertension")``).
        proclivity: ``(n,)`` each env's proclivity (float32, as its step used it).
        risk: ``(n,)`` the step's reported risks (``info["heart_attack_risk"]``).
        heart_attack: ``(n,)`` the step's coins: where one fell, the attack reset blood pressure to 0 and the
            state no longer shows the pressure the risk was computed at, so the reported risk is kept there.
    """
    exact = np.asarray(proclivity, dtype=np.float64) / (1.0 + np.exp(6.0 - np.asarray(pressure, dtype=np.float64)))
    attacks = np.flatnonzero(heart_attack)  # rare: cheaper than a where over every env
    exact[attacks] = np.asarray(risk)[attacks]
    return exact


def risk_floor(proclivity: float) -> float:
    """The heart-attack risk at zero blood pressure: the least any step can carry."""
    return float(heart_attack_risk(0.0, proclivity))


def least_heart_attacks(params: Params) -> float:
    """The expected heart attacks of an episode of ``params.max_steps`` steps at the risk floor: what a policy
    that never drinks pays (blood pressure stays 0), and no policy pays less."""
    return params.max_steps * risk_floor(params.heart_attack_proclivity)


def training_reward(
    env_reward: Array,
    heart_attack: Array,
    risk: Array,
    productivity: Array,
    half_hours: Array,
    *,
    penalty: Array,
    floor: Array,
    expected: bool,
    score_rate: Array | None,
    horizon: Array,
) -> Array:
    """The shaped reward of one step: a score part less a heart-attack charge.

    Args:
        env_reward: the env's reward (the change of ``work_done / time_elapsed`` less ``penalty`` per attack).
        heart_attack: the step's coin, 0 or 1, as a float.
        risk: the step's heart-attack probability.
        productivity: the work the step did.
        half_hours: the half-hours the step took.
        penalty: the env's heart-attack penalty.
        floor: the risk's floor ([`risk_floor`][heartpole.rewards.risk_floor]), taken off the expected charge.
        expected: charge ``penalty x (risk - floor)`` rather than ``penalty x heart_attack``.
        score_rate: ``None`` keeps the env's score change as the score part; a rate uses
            ``(productivity - score_rate x half_hours) / horizon`` instead.
        horizon: half-hours of a typical episode, the scale of the rate-based score part.
    """
    if score_rate is None:
        score_part = env_reward + penalty * heart_attack
    else:
        score_part = (productivity - score_rate * half_hours) / horizon
    if expected:
        return expected_risk(score_part, risk, penalty, floor)
    return expected_risk(score_part, heart_attack, penalty)
