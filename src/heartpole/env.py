"""The HeartPole Gymnasium environment: one person, one working day after another."""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence
from types import MappingProxyType
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from heartpole import kernel
from heartpole import render as rendering
from heartpole.actions import Action
from heartpole.dynamics import Dynamics
from heartpole.measurement import Measurement
from heartpole.model import score
from heartpole.observation import Observer, Seen, observe
from heartpole.parameters import Params, Variable, check_keywords
from heartpole.people import People, Sample
from heartpole.person_tables import PersonTables
from heartpole.time_limit import OwnTimeLimit, episode_length

CONSTRUCTOR_KEYWORDS = (
    "heart_attack_proclivity", "max_steps", "render_mode", "actions", "variables", "max_episode_steps", "people",
    "observe_traits", "measurement",
)  # fmt: skip
"""The env constructors' own keywords; every other keyword is a [`heartpole.Params`][heartpole.parameters.Params]
field."""

# The text log keeps at most this many steps between two renders (the tutorial's log grew without bound).
LOG_MAX_STEPS = 1000

NO_ACTION = -1
"""``info["action_taken"]`` before any step (in ``reset``'s ``info``): no action taken yet."""

RESET_INFO: Mapping[str, Any] = MappingProxyType(
    {
        "action_taken": NO_ACTION,
        "heart_attack": False,
        "heart_attack_risk": 0.0,  # no coin flipped yet
        "productivity": 0.0,  # no work done yet
        "score": float(score(0.0, 0.0)),
    }
)
"""``reset``'s ``info``: a step's keys with their values before any step, of the same Python types, so
that tools which record infos (Minari's ``DataCollector``, TorchRL's specs) see one structure throughout."""


def observation_space(dynamics: Dynamics) -> spaces.Box:
    """The float32 ``Box`` of one observation: each state variable within its documented bounds.

    Unbounded sides are the largest finite float32 rather than infinity, which Gymnasium's env checker
    warns about; every reachable state lies inside either way.
    """
    largest = float(np.finfo(np.float32).max)
    low = np.array([max(v.low, -largest) for v in dynamics.variables], dtype=np.float32)
    high = np.array([min(v.high, largest) for v in dynamics.variables], dtype=np.float32)
    return spaces.Box(low, high, dtype=np.float32)


def build_dynamics(
    heart_attack_proclivity: float,
    max_steps: int,
    actions: Sequence[Action] | None,
    variables: Sequence[Variable] | None,
    model_params: dict[str, Any],
    constructor: str = "HeartPole.__init__",
) -> Dynamics:
    """The [`Dynamics`][heartpole.dynamics.Dynamics] for an env's constructor arguments; ``TypeError`` names any
    unknown keyword."""
    accepted = [*CONSTRUCTOR_KEYWORDS, *(set(Params.__dataclass_fields__) - set(CONSTRUCTOR_KEYWORDS))]
    check_keywords(constructor, model_params, accepted)
    params = Params(heart_attack_proclivity=heart_attack_proclivity, max_steps=max_steps, **model_params)
    extra: dict[str, Any] = {}
    if actions is not None:
        extra["actions"] = actions
    if variables is not None:
        extra["variables"] = variables
    return Dynamics(params=params, **extra)


def compiled_for(function: Any, arguments: tuple[Any, ...]) -> Any:
    """The compiled code of ``function`` (a numba dispatcher) for the types of ``arguments``, to be called without
    numba's dispatch, which types every argument at every call (about 0.35 us of the single env's step, half its
    compiled call). Later calls must pass arguments of the same types: the env's arrays keep theirs, and its action
    is always a Python int. ``function`` itself where it is not compiled (``NUMBA_DISABLE_JIT=1``)."""
    typeof, compile = getattr(function, "typeof_pyval", None), getattr(function, "compile", None)
    if typeof is None or compile is None:
        return function
    return compile(tuple(typeof(argument) for argument in arguments))


def check_render_mode(render_mode: str | None, modes: Sequence[str]) -> None:
    """Raise ``ValueError`` unless ``render_mode`` is ``None`` or one of ``modes``."""
    if render_mode is not None and render_mode not in modes:
        raise ValueError(f"render_mode must be None or one of {list(modes)}, got {render_mode!r}")


class HeartPole(OwnTimeLimit, gym.Env[np.ndarray, np.int64]):
    """HeartPole: balance your productivity against your heart, one half-hour at a time.

    ## Description
    "CartPole for health", after Vadim Liventsev's tutorial on writing a custom Gym environment. You are
    at work. Every half-hour you stop and choose to do nothing, drink coffee, drink beer or go to sleep;
    then you work for a half-hour. Coffee makes you alert, beer can put you at the Ballmer peak, sleep
    restores alertness, but every drink raises your blood pressure, and blood pressure raises the risk
    of a heart attack. The dynamics are the tutorial's facts 0-8, written once as
    [`heartpole.model.step`][heartpole.model.step] (the actions are data: [`heartpole.actions`][heartpole.actions]) and
    compiled by [`heartpole.kernel`][heartpole.kernel].
    [`heartpole.HeartPoleVectorEnv`][heartpole.vector.HeartPoleVectorEnv] runs the same compiled step: env 0 of a vector
    env reset with the same seed follows this env bit for bit.

    ## Action Space
    ``Discrete(4)``:

    | action | name         | effect                                                                  |
    |--------|--------------|-------------------------------------------------------------------------|
    | 0      | do_nothing   | nothing                                                                 |
    | 1      | drink_coffee | alertness += U(0, 1), hypertension += U(0, 0.3)                         |
    | 2      | drink_beer   | alertness -= U(0, 0.5), hypertension += U(0, 0.3), intoxication += U(0.01, 0.03) |
    | 3      | sleep        | 16 half-hours pass, then you wake up: alertness = U(0.7, 1.3), time_since_slept = 0 |

    Python ints, NumPy integer scalars and 0-d integer arrays are accepted; anything else raises
    ``ValueError`` and leaves the env untouched (state and random stream).

    ## Observation Space
    ``Box(6,)`` of float32, in the tutorial's order (an infinite bound is the largest finite float32):

    | index | variable         | bounds     | meaning                                         |
    |-------|------------------|------------|-------------------------------------------------|
    | 0     | alertness        | (-inf, inf)| sleepy vs alert; about 1 on waking              |
    | 1     | hypertension     | [0, inf)   | blood pressure above normal; fades 0.97 per half-hour |
    | 2     | intoxication     | [0, inf)   | blood alcohol; fades 0.97 per half-hour         |
    | 3     | time_since_slept | [0, inf)   | half-hours since waking                         |
    | 4     | time_elapsed     | [0, inf)   | half-hours since the start, sleep included      |
    | 5     | work_done        | (-inf, inf)| total productivity so far                       |

    After each action a half-hour of work adds ``productivity = alertness * (1 - sigmoid(alertness - 3))
    * ballmer(intoxication)`` to ``work_done``; then alertness drops by
    ``sigmoid((time_since_slept - 40) / 10)`` and hypertension and intoxication fade by 0.97.

    ## Rewards
    The change of the score ``work_done / time_elapsed`` over the step, minus 100 if a heart attack
    occurred. A heart attack happens with probability ``0.5 * sigmoid(hypertension - 6)`` after the
    half-hour of work, and resets hypertension to 0. Rewards telescope: an episode's return is its final
    score minus 100 times its heart attacks.

    ## Starting State
    All variables 0, then you wake up: alertness uniform in [0.7, 1.3].

    ## Episode End
    Nobody dies of HeartPole's heart attacks, so episodes never terminate. They are truncated after
    ``max_steps`` decisions (1000 by default, the tutorial's ``done``): the env is its own time limit. The
    registered spec declares that length in its kwargs (``gymnasium.spec(id).kwargs["max_steps"]``) and no
    ``max_episode_steps``, so ``gymnasium.make`` adds no ``TimeLimit`` wrapper, and ``env.spec.max_episode_steps``
    reports the env's ``max_steps``: set the length with ``gymnasium.make(id, max_steps=n)`` (or a variant's
    ``max_steps``). ``gymnasium.make(id, max_episode_steps=k)`` gives ``k`` to a ``TimeLimit`` wrapper only, never
    to the env (Gymnasium's rule): ``k`` below ``max_steps`` shortens the episodes to ``k``; above it, the episodes
    still end at ``max_steps`` though ``env.spec.max_episode_steps`` (the wrapper's) says ``k``. The env built
    directly takes ``max_episode_steps`` as the same kind of limit: alone it is the length; with ``max_steps`` it
    may shorten it, and one above it is refused (``ValueError``); so does the vector env, which
    ``gymnasium.make_vec`` gives it along with the spec's ``max_steps``
    ([`episode_length`][heartpole.time_limit.episode_length]). Stepping on after truncation continues the same day
    with ``truncated=True`` on every step (Gymnasium's ``OrderEnforcing`` wrapper lets it). Call ``reset`` to start
    afresh.

    ## Info
    ``action_taken`` (the index of the action taken, an int; ``env.unwrapped.action_names[i]`` is its name),
    ``heart_attack`` (bool), ``heart_attack_risk`` (the probability the coin was flipped with, used by the
    expected-risk estimate), ``productivity`` (this half-hour's work) and ``score`` (``work_done /
    time_elapsed``). ``reset`` returns the same keys with the same types and their values before any step
    ([`heartpole.env.RESET_INFO`][heartpole.env.RESET_INFO]): ``action_taken`` -1 (none yet), ``heart_attack`` False and
    0.0 for the others, so tools that record infos (Minari's ``DataCollector(record_infos=True)``, TorchRL) see one
    structure throughout. No key is named like the step's own values (``action``, ``observation``, ``reward``, ...):
    TorchRL puts the info keys beside those, and an ``info["action"]`` replaced its action.

    ## Rendering
    ``"ansi"`` returns the tutorial's log of the steps since the last render (action names, HEART ATTACK
    lines, the state) of up to the last 1000 steps; ``"human"`` prints it every step; ``"rgb_array"`` draws
    the current state as an image for videos.

    ## People and measurements
    ``people=`` draws a person for each episode (at ``reset``; the vector env also at every autoreset) from a
    population, `heartpole.people.People` or ``"default"`` (24 people the optimum solves), with the
    env's seeded generator: their ``heart_attack_proclivity``, ``decay_rate``, ``sleep_half_hours`` and
    ``wake_alertness`` replace the env's. ``info["person"]`` is their cohort index (-1 for a distribution),
    ``info["traits"]`` their traits (float32, ``env.people.traits`` order); the traits are hidden unless
    ``observe_traits=True`` appends them to the observation and its space. ``measurement=``
    (`heartpole.measurement.Measurement`) adds Gaussian noise to the variables it names and
    measures them every ``every`` half-hours, the last reading carried forward and its age one more column
    (before the traits); the state itself is unchanged. Both are off by default: the env is then v0 exactly.

    >>> import gymnasium as gym
    >>> from heartpole.measurement import Measurement
    >>> env = gym.make("HeartPole-v0", people="default", observe_traits=True)
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape, info["person"], env.unwrapped.people.traits[:2]
    ((11,), 19, ('heart_attack_proclivity', 'decay_rate'))
    >>> bool((obs[6:] == info["traits"]).all())
    True
    >>> HeartPole(measurement=Measurement({"alertness": 0.2}, every=4)).observation_space.shape  # and the age
    (7,)

    ## Arguments
    ``gymnasium.make("HeartPole-v0", heart_attack_proclivity=0.5, max_steps=1000, render_mode=None)``.
    ``heart_attack_proclivity`` in [0, 1] scales the risk; ``max_steps`` >= 1. Variants (see
    [`heartpole.register_variant`][heartpole.registry.register_variant]) also pass ``actions``, ``variables`` and other
    [`heartpole.Params`][heartpole.parameters.Params] fields such as ``decay_rate`` or ``sleep_half_hours``.

    ## Differences from the tutorial's code (API only, same dynamics)
    * Gymnasium's API: ``reset(seed=...)`` returns ``(obs, info)`` and ``step`` returns
      ``(obs, reward, terminated, truncated, info)``; the step limit is a truncation, not a termination.
    * Randomness comes from ``self.np_random`` (seeded by ``reset(seed=...)``), never from NumPy's
      global state, so runs are reproducible bit for bit: each episode draws one 64-bit key from it, and
      the step's uniforms are a counter-based hash of that key ([`heartpole.kernel`][heartpole.kernel]).
    * The step computes in float32 (observations are float32 anyway): an episode's rewards add up to its
      final score minus 100 per heart attack within about 1e-5.
    * Observations are float32 in a float32 ``Box``, so Gymnasium does not warn about precision.
    * Sleep's 16 half-hours are computed in closed form (``0.97 ** 16``), equal to 16 repeated
      half-hours up to rounding.
    * The log is only kept when rendering as text, and is bounded: the tutorial's log grew every step
      until ``render()`` and slowed training to a crawl.

    ## Version History
    * v0: the tutorial's HeartPole with Gymnasium's API.
    * v0, package 0.2: same dynamics, faster; the draws were reorganised (four uniforms a step instead of
      five), so a seed gives another trajectory than in 0.1, with the same distribution.
    * v0, package 0.3: same dynamics; the step is compiled (numba) in float32 with a counter-based random
      number generator, so a seed gives another trajectory than in 0.2, with the same distribution.
      ``info["action"]`` (the action's name) became ``info["action_taken"]`` (its index); ``reset``'s ``info``
      has a step's keys (it was empty).
    """

    metadata = {"render_modes": ["human", "ansi", "rgb_array"], "render_fps": 8}

    def __init__(
        self,
        heart_attack_proclivity: float = 0.5,
        max_steps: int | None = None,
        render_mode: str | None = None,
        *,
        actions: Sequence[Action] | None = None,
        variables: Sequence[Variable] | None = None,
        max_episode_steps: int | None = None,
        people: People | str | None = None,
        observe_traits: bool = False,
        measurement: Measurement | None = None,
        **model_params: Any,
    ) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        max_steps = episode_length(max_steps, max_episode_steps)
        self.dynamics = build_dynamics(heart_attack_proclivity, max_steps, actions, variables, model_params)
        self._observer = Observer(self.dynamics, people, observe_traits, measurement)
        self.people: People | None = self._observer.people
        """The population each episode's person is drawn from (``None``: everyone has the env's parameters)."""
        self._persons = None if self.people is None else PersonTables(self.dynamics, self.people)
        self._sample: Sample | None = None  # the person of the episode
        self._cells = None if self._persons is None else self._persons.cells(1)  # the kernel's numbers of the person
        self._seen: Seen | None = None
        self._person: int | None = None  # the episode's person's cohort index and traits, as info hands them out
        self._traits: np.ndarray | None = None
        self.render_mode = render_mode
        self.heart_attack_proclivity = float(heart_attack_proclivity)
        self.max_steps = int(max_steps)
        self.action_space = spaces.Discrete(len(self.dynamics.actions))
        self.observation_space = self._observer.space(observation_space(self.dynamics))
        # One env of the kernel's loop over envs: its state (num_variables, 1) and its generator state (the
        # key's two halves and the draw counter).
        self._envs: np.ndarray | None = None
        self._rng = np.zeros((3, 1), dtype=np.uint32)
        self._plan()
        self._action_names = tuple(a.name for a in self.dynamics.actions)
        self._num_actions = len(self._action_names)
        self._steps = 0
        self._last_action: int | None = None
        self._last_attack = False
        self._heart_attacks = 0
        self._log: deque[tuple[str, tuple[float, ...], bool]] = deque(maxlen=LOG_MAX_STEPS)

    # ----------------------------------------------------------------------------------------------------
    @property
    def actions(self) -> tuple[Action, ...]:
        """The action set, in action-index order."""
        return self.dynamics.actions

    @property
    def action_names(self) -> tuple[str, ...]:
        """The actions' names, in action-index order: ``action_names[info["action_taken"]]`` names a step's."""
        return self._action_names

    @property
    def _state(self) -> np.ndarray | None:
        """The state of the episode (a view of the kernel's one env), ``None`` before ``reset``."""
        return self._row

    @property
    def state(self) -> dict[str, float]:
        """The current state as ``{variable: value}`` (a copy)."""
        if self._state is None:
            raise ResetNeeded("call reset() before reading the state of HeartPole")
        return dict(zip(self.dynamics.names, self._state.tolist()))

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new episode: everything at 0, then wake up (fact 1). ``options`` is accepted and unused.

        The episode's random numbers are keyed by one 64-bit draw from ``self.np_random``, as env 0 of a
        [`heartpole.HeartPoleVectorEnv`][heartpole.vector.HeartPoleVectorEnv] reset with the same seed: the two then
        agree bit for bit."""
        super().reset(seed=seed)
        people_rng, sensor_rng = self._observer.generators(self.np_random)
        envs = np.zeros((len(self.dynamics.variables), 1), dtype=np.float32)
        rng = kernel.generator_states(self.np_random, 1)
        which = np.ones(1, dtype=bool)
        if self._persons is not None:
            assert self.people is not None and people_rng is not None
            self._sample = self.people.sample(people_rng, 1)
            self._person, self._traits = int(self._sample.person[0]), self._sample.traits()
            self._persons.assign(self._cells, which, self._sample)  # type: ignore[arg-type]
        kernel.reset_envs(envs, rng, which, self.dynamics.packed, *self._loop_spec())
        self._envs, self._rng = envs, rng
        self._plan()
        if self._observer.sensor is not None:
            self._seen = Seen(self._observer.sensor, 1)
            self._seen.rng = sensor_rng  # type: ignore[assignment]
            self._seen.reset(envs.T, which)
        self._steps = 0
        self._last_action, self._last_attack, self._heart_attacks = None, False, 0
        self._log.clear()
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._with_person(dict(RESET_INFO))

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Take ``action`` (0..n-1), then work a half-hour; see the class docstring for the details."""
        index = action if type(action) is int and 0 <= action < self._num_actions else self._index(action)
        envs = self._envs
        if envs is None:
            raise ResetNeeded("call reset() before step() in HeartPole")
        rng, packed, cells, spec = self._kernel_arguments  # spelled out: a call with *arguments costs 40 ns more
        reward, worked, risk, attack, new_score = self._step_kernel(envs, index, rng, packed, cells, spec)
        self._steps = steps = self._steps + 1
        info = {
            "action_taken": index,
            "heart_attack": attack,
            "heart_attack_risk": risk,
            "productivity": worked,
            "score": new_score,
        }
        if self._plain and self.render_mode is None:  # v0: the state is the observation, nothing to remember
            return self._row.copy(), reward, False, steps >= self.max_steps, info  # type: ignore[union-attr]
        if self._seen is not None:
            self._seen.step(envs.T, None)
        if self.render_mode is not None:
            self._remember(index, attack)
        return self._observation(), reward, False, steps >= self.max_steps, self._with_person(info)

    def render(self) -> str | np.ndarray | None:
        """Render as chosen by ``render_mode``: text since the last render, printed text, or an RGB frame."""
        if self.render_mode is None:
            gym.logger.warn("HeartPole.render() called without a render_mode; pass render_mode= to make().")
            return None
        if self.render_mode == "rgb_array":
            return rendering.draw_frame(
                self.state,
                action=None if self._last_action is None else self._action_names[self._last_action],
                heart_attack=self._last_attack,
                heart_attacks=self._heart_attacks,
                step=self._steps,
                max_steps=self.max_steps,
            )
        lines: list[str] = []
        for name, values, attack in self._log:
            lines += rendering.log_lines(name, dict(zip(self.dynamics.names, values)), attack)
        text = "\n".join(lines) + ("\n" if lines else "")
        self._log.clear()
        if self.render_mode == "human":
            print(text, end="")
            return None
        return text

    # ----------------------------------------------------------------------------------------------------
    def _plan(self) -> None:
        """What every step of the episode reuses, derived from its arrays (at ``__init__``, ``reset`` and when a
        copy or a pickle is restored): the state's view, whether the step is v0's plain path, and the compiled
        step with the arguments that follow the action."""
        self._row = None if self._envs is None else self._envs[:, 0]
        self._plain = self._observer.plain and self.people is None
        step: Any = kernel.step_one
        arguments = (self._rng, self.dynamics.packed, *self._loop_spec())
        self._kernel_arguments = arguments
        if self._envs is None:
            self._step_kernel = step
        elif getattr(self, "_step_kernel", step) is step:  # typed once: every episode's arrays have the same types
            self._step_kernel = compiled_for(step, (self._envs, 0, *arguments))

    def _loop_spec(self) -> tuple[np.ndarray, np.ndarray]:
        """The loop's ``cells`` and ``spec`` arguments after ``packed``: the person's numbers, if any."""
        if self._persons is None:
            return kernel.NO_CELLS, self.dynamics.spec.argument
        return self._cells, self._persons.spec.argument  # type: ignore[return-value]

    def __getstate__(self) -> dict[str, Any]:
        """The env's state for ``pickle`` and ``copy``: without what `_plan` derives (views and compiled code)."""
        state = self.__dict__.copy()
        for derived in ("_row", "_plain", "_kernel_arguments", "_step_kernel"):
            state.pop(derived, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a pickled or copied env, its derived state planned anew."""
        self.__dict__.update(state)
        self._plan()

    def _observation(self) -> np.ndarray:
        """The observation: the state itself, or as measured, with the person's traits if observed."""
        assert self._envs is not None and self._row is not None
        if self._observer.plain:
            return self._row.copy()
        assert self._traits is not None or not self._observer.observe_traits
        traits = self._traits if self._observer.observe_traits else None
        return observe(self._envs.T, self._seen, traits)[0]

    def _with_person(self, info: dict[str, Any]) -> dict[str, Any]:
        """``info`` with the episode's person (its cohort index, -1 for a distribution) and traits, if any."""
        if self._traits is not None:
            info["person"], info["traits"] = self._person, self._traits[0].copy()
        return info

    def _remember(self, index: int, attack: bool) -> None:
        """Keep what rendering shows of the last step: the action, the heart attack and the text log."""
        self._last_action, self._last_attack = index, attack
        self._heart_attacks += attack
        if self.render_mode in ("ansi", "human"):
            assert self._state is not None  # step() checked it
            state = tuple(self._state.tolist())
            self._log.append((self._action_names[index], state, attack))  # formatted only when rendered
            if self.render_mode == "human":
                self.render()

    def _index(self, action: Any) -> int:
        """Validate an action that is not a plain in-range int; raise a ``ValueError`` naming valid ones."""
        n = len(self.dynamics.actions)
        is_integer = isinstance(action, (int, np.integer)) and not isinstance(action, (bool, np.bool_))
        if isinstance(action, np.ndarray) and action.shape == () and np.issubdtype(action.dtype, np.integer):
            action, is_integer = action.item(), True
        if is_integer and 0 <= action < n:
            return int(action)
        valid = ", ".join(f"{i} ({a.name})" for i, a in enumerate(self.dynamics.actions))
        raise ValueError(f"invalid HeartPole action {action!r} ({type(action).__name__}); valid actions: {valid}")


HeartPoleEnv = HeartPole


def final_infos(info: dict[str, Any], obs: np.ndarray, ended: np.ndarray) -> dict[str, Any]:
    """A vector env's SAME_STEP ``final_obs`` and ``final_info`` for the envs ``ended``, laid out as Gymnasium's vector
    envs lay them out: an object array of the last observations (``None`` elsewhere) and the last step's
    ``info`` arrays (0 elsewhere), each with its own mask."""
    final_obs = np.full(len(ended), None, dtype=object)
    for i, row in zip(np.flatnonzero(ended), np.ascontiguousarray(obs[ended])):
        final_obs[i] = row
    final_info: dict[str, Any] = {}
    for key in [key for key in info if not key.startswith("_")]:  # INFO_KEYS, and the person's with people
        where = ended.reshape((-1,) + (1,) * (info[key].ndim - 1))
        final_info[key] = np.where(where, info[key], np.zeros((), dtype=info[key].dtype))
        final_info["_" + key] = ended.copy()
    return {"final_obs": final_obs, "_final_obs": ended.copy(), "final_info": final_info, "_final_info": ended.copy()}
