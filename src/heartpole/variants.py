"""HeartPole-v1, the tutorial's homework: v0 plus tea, naps, exercise and cannabis.

[`HeartPoleV1`][heartpole.variants.HeartPoleV1] and [`HeartPoleV1VectorEnv`][heartpole.variants.HeartPoleV1VectorEnv]
are v0's envs with v1's actions and state ([`heartpole.actions.V1_ACTIONS`][heartpole.actions.V1_ACTIONS],
[`heartpole.actions.V1_VARIABLES`][heartpole.actions.V1_VARIABLES]); the class docstring below is v1's manual. Users
build their own variants the same way, without a class, through
[`heartpole.register_variant`][heartpole.registry.register_variant]."""

from __future__ import annotations

from typing import Any

from heartpole.actions import V1_ACTIONS, V1_VARIABLES
from heartpole.env import HeartPole
from heartpole.vector import HeartPoleVectorEnv

_FIXED = ("actions", "variables")


def _refuse_fixed(kwargs: dict[str, Any]) -> None:
    given = [name for name in _FIXED if name in kwargs]
    if given:
        raise ValueError(
            f"HeartPole-v1's {' and '.join(given)} are fixed; to change them define your own variant, e.g. "
            "heartpole.register_variant('MyPole-v0', actions=[*heartpole.V1_ACTIONS, my_action], "
            "variables=heartpole.V1_VARIABLES)"
        )


class HeartPoleV1(HeartPole):
    """HeartPole-v1: v0's working day with four more choices: tea, a nap, exercise and cannabis.

    ## Description
    The tutorial's homework ("Make HeartPole-v1! Add cannabis, some new actions that can modify your health
    and productivity!"). Everything in v0 stays as it was (its six state variables, its four actions with
    their indices, its rewards, its parameters); v1 adds four actions, each grounded like the tutorial's
    facts (a one-line fact, its random amounts, a source), and one state variable, ``thc``, which cannabis
    needs. Amounts are in HeartPole's units, set against v0's: a coffee's U(0, 0.3) of hypertension stands
    for caffeine's acute rise of about 8 mm Hg systolic (Mesas et al. 2011, Am J Clin Nutr 94:1113), so 0.1
    of hypertension is about 5 mm Hg, and alertness is about 1 on waking.

    ## Action Space
    ``Discrete(8)``. Effects are uniform draws added to the state before the half-hour of work; "rest"
    half-hours pass without work (hypertension, intoxication and THC fade, alertness keeps draining as in
    any waking half-hour, fact 6).

    | action | name           | effect                                                                       |
    |--------|----------------|------------------------------------------------------------------------------|
    | 0      | do_nothing     | nothing                                                                      |
    | 1      | drink_coffee   | alertness += U(0, 1), hypertension += U(0, 0.3)                              |
    | 2      | drink_beer     | alertness -= U(0, 0.5), hypertension += U(0, 0.3), intoxication += U(0.01, 0.03) |
    | 3      | sleep          | 16 half-hours pass, then alertness = U(0.7, 1.3), time_since_slept = 0       |
    | 4      | drink_tea      | alertness += U(0, 0.5), hypertension += U(0, 0.15)                           |
    | 5      | take_nap       | alertness += U(0.3, 0.6), then 1 rest half-hour                              |
    | 6      | exercise       | hypertension -= U(0.05, 0.15) (not below 0), then 2 rest half-hours          |
    | 7      | smoke_cannabis | thc += U(0.5, 1), alertness -= U(0, 0.4), hypertension += U(0, 0.2)          |

    The facts behind the new actions:

    * ``drink_tea``: tea holds about half the caffeine of coffee (black tea ~47 mg a cup, brewed coffee
      ~96 mg), so it has half of each of coffee's effects. Source: Mayo Clinic, "Caffeine content for
      coffee, tea, soda and more".
    * ``take_nap``: a short nap restores alertness. NASA's planned 40-minute cockpit rest (26 minutes
      asleep on average) improved pilots' performance by 34% and physiological alertness by 54%: a third
      to a half of a morning's alertness. Source: Rosekind MR et al. (1995) Alertness management:
      strategic naps in operational settings. J Sleep Res 4(Suppl 2):62-66; NASA TM-108839 (1994).
      Unlike ``sleep``, a nap does not reset ``time_since_slept``: the day goes on.
    * ``exercise``: an hour of aerobic exercise lowers blood pressure by about 5-7 mm Hg (0.05-0.15 here)
      for up to 22 hours; it costs an hour without work, in which alertness keeps draining. Source:
      Pescatello LS et al. (2004) American College of Sports Medicine position stand: Exercise and
      hypertension. Med Sci Sports Exerc 36(3):533-553. Hypertension never goes below 0.
    * ``smoke_cannabis``: cannabis relieves anxiety but dulls attention, and raises heart rate and blood
      pressure; the risk of a heart attack is 4.8 times higher in the hour after smoking. Sources: Cuttler
      C, Spradlin A, McLaughlin RJ (2018) A naturalistic examination of the perceived effects of cannabis
      on negative affect. J Affect Disord 235:198-205 (58% less anxiety reported); Mittleman MA et al.
      (2001) Triggering myocardial infarction by marijuana. Circulation 103(23):2805-2809. The
      relief is modelled as THC moving the onset of crippling anxiety (fact 7) to higher alertness; the
      heart as a blood-pressure rise (v0's only route to a heart attack), two-thirds of a coffee's.

    ## Observation Space
    ``Box(7,)`` of float32: v0's six variables, in v0's order, then ``thc``:

    | index | variable         | bounds     | meaning                                               |
    |-------|------------------|------------|-------------------------------------------------------|
    | 0     | alertness        | (-inf, inf)| sleepy vs alert; about 1 on waking                    |
    | 1     | hypertension     | [0, inf)   | blood pressure above normal; fades 0.97 per half-hour |
    | 2     | intoxication     | [0, inf)   | blood alcohol; fades 0.97 per half-hour               |
    | 3     | time_since_slept | [0, inf)   | half-hours since waking                               |
    | 4     | time_elapsed     | [0, inf)   | half-hours since the start, sleep, naps and exercise included |
    | 5     | work_done        | (-inf, inf)| total productivity so far                             |
    | 6     | thc              | [0, inf)   | THC level; fades 0.7 per half-hour (half-life about an hour) |

    THC: smoked cannabis acts within minutes, peaks after 15-30 minutes and wears off over 2-3 hours
    (Grotenhermen F (2003) Clin Pharmacokinet 42(4):327-360), hence 0.7 a half-hour: 12% is left after
    three hours. A half-hour of work earns ``productivity = alertness * (1 - sigmoid(alertness - 3 - thc))
    * ballmer(intoxication)``: with no THC it is v0's formula.

    ## Rewards
    v0's, so results compare: the change of the score ``work_done / time_elapsed``, minus 100 for a heart
    attack (probability ``0.5 * sigmoid(hypertension - 6)`` after each half-hour of work, resetting
    hypertension to 0). An episode's return is its final score minus 100 times its heart attacks. Rest
    half-hours (naps, exercise) count in ``time_elapsed`` like sleep, so they lower the score unless they
    pay for themselves.

    ## Starting State, Episode End, Info, Rendering
    As v0's ([`heartpole.HeartPole`][heartpole.env.HeartPole]): all variables 0 (``thc`` included), then waking up;
    truncated after ``max_steps`` decisions, never terminated; the same ``info`` keys; ``"rgb_array"`` frames show
    ``thc`` as one more gauge.

    ## Arguments
    ``gymnasium.make("HeartPole-v1", heart_attack_proclivity=0.5, max_steps=1000, render_mode=None)`` and
    the other [`heartpole.Params`][heartpole.parameters.Params] fields (``decay_rate``, ``sleep_half_hours``, ...). The
    action set and state are fixed; for other ones, define a variant with
    [`heartpole.register_variant`][heartpole.registry.register_variant].

    ## Version History
    * v1: v0 plus drink_tea, take_nap, exercise and smoke_cannabis, and the ``thc`` state variable.
    * v0: the tutorial's HeartPole with Gymnasium's API.
    """

    def __init__(
        self,
        heart_attack_proclivity: float = 0.5,
        max_steps: int | None = None,
        render_mode: str | None = None,
        **model_params: Any,
    ) -> None:
        _refuse_fixed(model_params)
        super().__init__(
            heart_attack_proclivity,
            max_steps,
            render_mode,
            actions=V1_ACTIONS,
            variables=V1_VARIABLES,
            **model_params,
        )


class HeartPoleV1VectorEnv(HeartPoleVectorEnv):
    """HeartPole-v1 as a native vector env: [`HeartPoleV1`][heartpole.variants.HeartPoleV1]'s dynamics over ``num_envs``
    episodes.

    Spaces are batched: observations ``(num_envs, 7)`` float32, actions ``MultiDiscrete([8] * num_envs)``.
    Everything else (autoreset, ``info``, bad input) is
    [`heartpole.HeartPoleVectorEnv`][heartpole.vector.HeartPoleVectorEnv]'s."""

    def __init__(
        self,
        num_envs: int = 1,
        heart_attack_proclivity: float = 0.5,
        max_steps: int | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        _refuse_fixed(kwargs)
        super().__init__(
            num_envs,
            heart_attack_proclivity,
            max_steps,
            render_mode,
            actions=V1_ACTIONS,
            variables=V1_VARIABLES,
            **kwargs,
        )
