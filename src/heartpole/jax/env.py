"""HeartPole as a JAX environment with gymnax's ``Environment`` API: `HeartPoleJax`.

The step is [`step`][heartpole.model.step] itself: `MODEL` is [`heartpole.model`][heartpole.model]'s functions
rebound to ``jax.numpy`` (``exp``, ``where``) with tuples for states, so JAX traces the very code the
NumPy envs compile with numba. What this module adds is the gymnax machinery around it: the state and
parameter pytrees, key handling, the step counter, truncation and autoreset.

The random numbers are [`heartpole.rng`][heartpole.rng]'s counter-based generator, the NumPy envs' own, traced
(`RNG`). gymnax's ``step(key, ...)`` takes its randomness from ``key`` (one state stepped with two keys may
have two futures): a step's uniforms are the generator's hash of ``key``'s own 64 bits. A rollout that carries the
NumPy envs' generator states instead ([`heartpole.jax.evaluate`][heartpole.jax.evaluation.evaluate]) plays
the NumPy envs' very episodes.

The state keeps one float32 scalar per state variable (``state.variables`` is a tuple, as gymnax's CartPole
keeps ``x``, ``x_dot``, ...): under ``vmap`` each is one contiguous array, and the observation stacks them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from heartpole.dynamics import Dynamics
from heartpole.jax.population import Population
from heartpole.jax.spaces import Box, Discrete
from heartpole.jax.traced import MODEL, NOISE, RESET_DRAW, RNG, key_draw
from heartpole.measurement import Measurement, Sensor
from heartpole.model import TIME_ELAPSED, ActionEffects, StepTables, TableFields, table_fields
from heartpole.people import People, Sample, check_observe_traits


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class EnvState:
    """One episode's state: the state variables (a tuple of float32 scalars, observation order: one array per
    variable under ``vmap``), the decisions taken and the episode's person (an env with ``people``): the cohort
    index (an int32 scalar, -1 for a distribution) and a distribution's person's values (float32, one per column
    of ``people.columns``; a cohort's person is their index, and `HeartPoleJax.person_values` reads their row).

    What an env does not use is an empty array (``person`` without people, ``person_values`` without a
    distribution, ``seen`` and ``age`` without measurement): every field that is carried costs each step its
    read and write, and on a GPU, where a large batch of steps is bound by memory traffic, v0's two unused
    scalars were 15% of it and a cohort's five values a third of the people's."""

    variables: tuple[jax.Array, ...]
    time: jax.Array
    person: jax.Array = field(default_factory=lambda: jnp.zeros(0, jnp.int32))
    person_values: jax.Array = field(default_factory=lambda: jnp.zeros(0, jnp.float32))
    seen: jax.Array = field(default_factory=lambda: jnp.zeros(0, jnp.float32))
    """With ``measurement``: the variables as last measured (float32, observation order); else empty."""
    age: jax.Array = field(default_factory=lambda: jnp.zeros(0, jnp.float32))
    """With ``measurement``: the half-hours since ``seen`` was measured (a float32 scalar); else empty."""


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class EnvParams:
    """A variant's numbers as arrays, so that they can be changed, batched and ``vmap``-ed over.

    The model's own tables, their numbers as float32 arrays: ``effects`` is an
    [`ActionEffects`][heartpole.model.ActionEffects] with one row per action (a ``PerVariable`` field is a
    ``(num_actions, num_variables)`` array, a ``Number`` field ``(num_actions,)``), ``tables`` a
    [`StepTables`][heartpole.model.StepTables] (``(num_variables,)`` and scalars; its ``Shape`` fields, which
    fix the step's loops, stay with the env and are empty here). ``max_steps_in_episode`` is the truncation
    limit (gymnax's name). Every field of either table reads by its name too (``params.heart_attack_penalty``),
    and `replace` changes fields by name.
    """

    effects: ActionEffects
    tables: StepTables
    max_steps_in_episode: jax.Array

    def __getattr__(self, name: str) -> jax.Array:
        for table in ("effects", "tables"):
            if name in _NUMBERS[table]:
                return getattr(self.__dict__[table], name)
        raise AttributeError(f"EnvParams has no field {name!r}; it has {[*_NUMBERS['effects'], *_NUMBERS['tables']]}")

    def replace(self, **changes: Any) -> EnvParams:
        """A copy with ``changes``: fields of either table or ``max_steps_in_episode``, by name."""
        effects = {k: v for k, v in changes.items() if k in _NUMBERS["effects"]}
        tables = {k: v for k, v in changes.items() if k in _NUMBERS["tables"]}
        unknown = set(changes) - set(effects) - set(tables) - {"max_steps_in_episode"}
        if unknown:
            raise TypeError(f"EnvParams.replace() got unknown field(s) {sorted(unknown)}")
        return EnvParams(
            self.effects._replace(**effects),
            self.tables._replace(**tables),
            changes.get("max_steps_in_episode", self.max_steps_in_episode),
        )

    @classmethod
    def from_dynamics(cls, dynamics: Dynamics) -> EnvParams:
        """The parameters of a [`Dynamics`][heartpole.dynamics.Dynamics] (float32; the step limit int32)."""
        f32: Callable[[Any], jax.Array]
        f32 = lambda values: jnp.asarray(np.asarray(values, dtype=np.float32))  # noqa: E731
        effects = ActionEffects._make(
            f32([getattr(e, name) for e in dynamics.effects]) for name in ActionEffects._fields
        )
        tables = StepTables._make(
            f32(getattr(dynamics.tables, name)) if name in _NUMBERS["tables"] else () for name in StepTables._fields
        )
        return cls(effects, tables, jnp.asarray(dynamics.params.max_steps, dtype=jnp.int32))


EFFECTS, TABLES = table_fields(ActionEffects), table_fields(StepTables)
_NUMBERS = {
    "effects": (*EFFECTS.per_variable, *EFFECTS.numbers),
    "tables": (*TABLES.per_variable, *TABLES.numbers),
}


class HeartPoleJax:
    """HeartPole with gymnax's ``Environment`` API: pure functions of keys, states and parameters.

    The API of gymnax 1.0: ``reset(key, params) -> (obs, state)`` and ``step(key, state, action, params)
    -> (obs, state, reward, terminated, truncated, info)``, both jittable and ``vmap``-able over keys,
    states, actions and parameters; ``step_env`` (no reset) returns ``(obs, state, reward, terminated,
    info)``. ``step`` resets an episode that ended within the same call (gymnax's autoreset): ``obs`` and
    ``state`` are then the new episode's, and ``info["final_observation"]`` is the observation the episode
    ended on, which a learner needs to bootstrap through the time limit. Episodes never terminate (nobody
    dies of HeartPole's heart attacks): ``terminated`` is always ``False``; they are truncated after
    ``params.max_steps_in_episode`` decisions. ``info`` also holds ``terminated``, ``truncated``,
    ``discount`` (always 1.0) and, as the NumPy envs' info, ``heart_attack``, ``heart_attack_risk``,
    ``productivity`` and ``score``. gymnax's wrappers (``LogWrapper`` ...) accept the env.

    **People.** With ``people``, every episode (at `reset` and at the autoreset inside `step`) draws its
    person from the reset key, and the state carries them (``state.person``; a distribution's person's values in
    ``state.person_values``, any person's through `person_values`):
    `step_env` runs on `person_params`, the given params with the person's entries. ``vmap`` over envs
    gives each env its own people; ``info["person"]`` (cohort index, -1 for a distribution) and
    ``info["traits"]`` name the person of the step just taken (at an autoreset the ended episode's, as
    ``info["final_observation"]``; the new episode's is in the returned ``state``). The gymnax way, one
    fixed person per env, is `params_for`: a batch of ``EnvParams`` to ``vmap`` over.

    Everything is float32 (actions int32).

    Args:
        dynamics: the variant (``env.unwrapped.dynamics`` of any HeartPole env); default: HeartPole-v0's.
        people: a population ([`People`][heartpole.people.People] or a name such as ``"default"``), or
            ``None``: everyone has ``dynamics``' params. Fields it does not set are ``dynamics``'.
        observe_traits: append the person's traits ([`People.traits`][heartpole.people.People.traits]) to
            the observation (the observation space's bounds extended with
            [`People.trait_bounds`][heartpole.people.People.trait_bounds]).
        measurement: noisy, sparse measurements ([`Measurement`][heartpole.measurement.Measurement]): the
            observation shows the variables as measured (then the measurement's age if it is taken less
            often than every half-hour), the state keeps the truth (``state.variables``) and the last
            reading (``state.seen``, ``state.age``). Its noise comes from a key folded off the step's key.

    Raises:
        ValueError: an unknown population name, or ``observe_traits=True`` without people.
        TypeError: ``people``, ``observe_traits`` or ``measurement`` of another type.
    """

    def __init__(
        self,
        dynamics: Dynamics | None = None,
        people: People | str | None = None,
        observe_traits: bool = False,
        measurement: Measurement | None = None,
    ) -> None:
        self.dynamics = Dynamics() if dynamics is None else dynamics
        self.people = People.resolve(people)
        self.observe_traits = check_observe_traits(observe_traits, self.people)
        self.population = None if self.people is None else Population(self.people, self.dynamics)
        self.measurement = measurement = Measurement.resolve(measurement)
        self.sensor = None if measurement is None else measurement.sensor(self.dynamics.names)
        self.num_variables = len(self.dynamics.variables)
        self._num_actions = len(self.dynamics.actions)
        # static: the Shape fields fix the step's loops (how many drowsy half-hours to unroll)
        self._shape = {name: getattr(self.dynamics.tables, name) for name in TABLES.shape}
        self._default_params = EnvParams.from_dynamics(self.dynamics)

    @classmethod
    def from_id(cls, env_id: str = "HeartPole-v0", **env_kwargs: Any) -> HeartPoleJax:
        """The JAX env of a registered HeartPole id (v0, v1, or a `heartpole.register_variant` one),
        made with the keyword arguments ``gymnasium.make`` takes (``max_steps``, ``heart_attack_proclivity``...),
        ``people``, ``observe_traits`` and ``measurement`` among them.

        Raises:
            ValueError: a ``render_mode`` (the JAX env draws no frames: render with ``gymnasium.make``'s env).
        """
        from heartpole.policies import env_dynamics

        if env_kwargs.get("render_mode") is not None:
            raise ValueError(
                f"heartpole.jax envs do not render (render_mode={env_kwargs['render_mode']!r}); render_mode=None "
                "is accepted. Render with gymnasium.make(env_id, render_mode='rgb_array') instead"
            )
        env_kwargs.pop("render_mode", None)
        ours = ("people", "observe_traits", "measurement")
        mine = {name: env_kwargs.pop(name) for name in ours if name in env_kwargs}
        return cls(env_dynamics(env_id, env_kwargs), **mine)

    # -- gymnax's Environment API ----------------------------------------------------------------------
    @property
    def default_params(self) -> EnvParams:
        """The variant's own parameters."""
        return self._default_params

    @property
    def name(self) -> str:
        """The environment's name."""
        return "HeartPole"

    @property
    def num_actions(self) -> int:
        """How many actions there are."""
        return self._num_actions

    def reset(self, key: jax.Array, params: EnvParams | None = None) -> tuple[jax.Array, EnvState]:
        """Start an episode: every variable at 0, then wake up (fact 1)."""
        return self.reset_env(key, self.default_params if params is None else params)

    def step(
        self, key: jax.Array, state: EnvState, action: Any, params: EnvParams | None = None
    ) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, jax.Array, dict[str, jax.Array]]:
        """One decision and the half-hour after it: ``(obs, state, reward, terminated, truncated, info)``;
        an episode that reaches its step limit restarts at once.

        All its randomness comes from ``key``'s 64 bits taken as a generator key (`key_draw`): the step's
        uniforms are that generator key's draw 0 (as `step_env`'s), the next episode's (its person, its waking
        up) draw `RESET_DRAW`; no threefry call of its own, where a split and a call for each part were four."""
        params = self.default_params if params is None else params
        action = self.check_action(action)
        low, high = key_draw(key)
        obs_step, state_step, reward, terminated, info = self._step_from(key, low, high, state, action, params)
        truncated = self.is_truncated(state_step, params)
        done = jnp.logical_or(terminated, truncated)
        obs_reset, state_reset = self._reset_from(key, low, high, RESET_DRAW, params)
        state = jax.tree_util.tree_map(lambda new, old: jnp.where(done, new, old), state_reset, state_step)
        obs = jnp.where(done, obs_reset, obs_step)
        info = {**info, "terminated": terminated, "truncated": truncated, "final_observation": obs_step}
        return obs, state, reward, terminated, truncated, info

    def reset_env(self, key: jax.Array, params: EnvParams) -> tuple[jax.Array, EnvState]:
        """[`initial_state`][heartpole.model.initial_state] with the wake-up uniform of ``key``'s generator key;
        with people, the episode's person is drawn first and wakes up by their own params."""
        return self._reset_from(key, *key_draw(key), 0, params)

    def _reset_from(
        self, key: jax.Array, low: jax.Array, high: jax.Array, draw: int, params: EnvParams
    ) -> tuple[jax.Array, EnvState]:
        """`reset_env` from draw ``draw`` of the generator key ``(low, high)``: its wake-up uniform wakes the
        person up, the uniform after it picks a cohort's person (`NOISE` says how ``key`` is folded for a
        distribution's person and the first measurement)."""
        n = self.num_variables
        person, values = jnp.zeros(0, jnp.int32), jnp.zeros(0, jnp.float32)
        if self.population is not None:
            chooser = RNG.uniform(low, high, draw, n + 1)
            person, values = self.population.draw(jax.random.fold_in(key, 3 + 2 * draw), chooser)
            if not self._carries_values():
                values = jnp.zeros(0, jnp.float32)  # a cohort's person is their index (`person_values`)
        noise_key = jax.random.fold_in(key, 2 + 2 * draw)
        return self.start(noise_key, person, values, RNG.wake_uniform(low, high, draw, n), params)

    def start(
        self, key: jax.Array, person: jax.Array, values: jax.Array, uniform: jax.Array, params: EnvParams
    ) -> tuple[jax.Array, EnvState]:
        """``(obs, state)`` of an episode of ``person`` (cohort index, -1, or empty without people) with ``values``
        that wakes up with ``uniform``; ``key`` draws the first measurement's noise (with ``measurement``)."""
        zeros = (jnp.float32(0.0),) * self.num_variables
        state = EnvState(variables=zeros, time=jnp.int32(0), person=person, person_values=values)
        tables = self._tables(self.person_params(state, params).tables)
        state = dataclasses.replace(state, variables=_floats(MODEL.initial_state(zeros, uniform, tables)))
        if self.sensor is not None:
            state = dataclasses.replace(state, seen=jnp.stack(state.variables), age=jnp.float32(0.0))
            state = self._measure(self.sensor, key, state, jnp.float32(jnp.inf))
        return self.get_obs(state), state

    def step_env(
        self, key: jax.Array, state: EnvState, action: Any, params: EnvParams
    ) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, dict[str, jax.Array]]:
        """[`step`][heartpole.model.step] with the ``len(state) + 2`` uniforms of ``key``
        ([`draws`][heartpole.rng.draws] of its generator key, `key_draw`), no reset: ``(obs, state, reward,
        terminated, info)``.

        An action that is not one of the env's is refused with the NumPy envs' ``ValueError`` where it is
        concrete, and ``TypeError`` for a non-integer dtype; under ``jit`` an out-of-range integer changes
        nothing (the state is returned as it was, the reward is 0) and ``info["invalid_action"]`` is true.
        """
        return self._step_from(key, *key_draw(key), state, self.check_action(action), params)

    def _step_from(
        self, key: jax.Array, low: jax.Array, high: jax.Array, state: EnvState, action: jax.Array, params: EnvParams
    ) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, dict[str, jax.Array]]:
        """`step_env` with draw 0 of the generator key ``(low, high)``."""
        uniforms = RNG.draws(low, high, jnp.uint32(0), (jnp.float32(0.0),) * self.num_variables)
        return self.advance(jax.random.fold_in(key, NOISE), state, action, params, uniforms)

    def advance(
        self, key: jax.Array, state: EnvState, action: jax.Array, params: EnvParams, uniforms: tuple[jax.Array, ...]
    ) -> tuple[jax.Array, EnvState, jax.Array, jax.Array, dict[str, jax.Array]]:
        """`step_env` with its ``uniforms`` given (a rollout on the NumPy envs' generator states draws them
        itself); ``key`` draws the measurement's noise (with ``measurement``). ``action`` is an int32 that
        `check_action` passed."""
        valid = (action >= 0) & (action < self._num_actions)
        effects, tables = self._inputs(state, params, action)
        old = state.variables
        new, reward, worked, risk, attack, score = MODEL.step(old, effects, uniforms, tables)
        new = tuple(jnp.where(valid, n, o) for n, o in zip(_floats(new), old))
        state = dataclasses.replace(state, variables=new, time=state.time + valid.astype(jnp.int32))
        if self.sensor is not None:
            passed = new[TIME_ELAPSED] - old[TIME_ELAPSED]
            state = self._measure(self.sensor, key, state, passed)
        info = {
            "discount": self.discount(state, params),
            "heart_attack": attack & valid,
            "heart_attack_risk": jnp.float32(risk),
            "productivity": jnp.float32(worked),
            "score": jnp.float32(score),
            "invalid_action": ~valid,
        }
        if self.population is not None:
            info |= {"person": state.person, "traits": self.person_values(state)[self.population.trait_index]}
        reward = jnp.where(valid, jnp.float32(reward), jnp.float32(0.0))
        return self.get_obs(state), state, reward, self.is_terminated(state, params), info

    def check_action(self, action: Any) -> jax.Array:
        """``action`` as an int32 array, refused where it cannot be one of the env's actions: ``TypeError``
        for a non-integer dtype (known when tracing), the NumPy envs' ``ValueError`` for a concrete value
        outside ``0 .. num_actions - 1``. A traced value is checked in the step (`advance`)."""
        array = action if isinstance(action, jax.Array) else np.asarray(action)
        if array.dtype == np.bool_ or not np.issubdtype(array.dtype, np.integer):
            raise TypeError(
                f"invalid HeartPole action {action!r} of dtype {array.dtype}: actions are integers in "
                f"0..{self._num_actions - 1} ({self._valid_actions()})"
            )
        if not isinstance(array, jax.core.Tracer):
            values = np.asarray(array)
            if values.size and (values.min() < 0 or values.max() >= self._num_actions):
                raise ValueError(f"invalid HeartPole action {action!r}; valid actions: {self._valid_actions()}")
        return jnp.asarray(array, dtype=jnp.int32)

    def _valid_actions(self) -> str:
        return ", ".join(f"{i} ({a.name})" for i, a in enumerate(self.dynamics.actions))

    def get_obs(self, state: EnvState, params: EnvParams | None = None, key: jax.Array | None = None) -> jax.Array:
        """The observation: the state variables in observation order (float32, stacked), then the person's
        traits with ``observe_traits``; with ``measurement``, the variables as measured, then their age if
        measured less often than every half-hour, then the traits."""
        obs = jnp.stack(state.variables)
        if self.sensor is not None:
            obs = self.sensor.observation(state.seen[None], state.age[None], jnp)[0]
        if self.observe_traits and self.population is not None:
            return jnp.concatenate([obs, self.person_values(state)[self.population.trait_index]])
        return obs

    @staticmethod
    def _measure(sensor: Sensor, key: jax.Array, state: EnvState, passed: jax.Array) -> EnvState:
        """``state`` with a new measurement where one is due ([`Sensor.read`][heartpole.measurement.Sensor.read],
        one standard normal per measured variable from ``key``)."""
        noise = jax.random.normal(key, (1, len(sensor.columns)), jnp.float32)
        truth = jnp.stack(state.variables)[None]
        seen, age = sensor.read(truth, state.seen[None], state.age[None], passed[None], noise, jnp)
        return dataclasses.replace(state, seen=seen[0], age=age[0])

    def observe(self, key: jax.Array, state: EnvState, action: Any, params: EnvParams) -> jax.Array:
        """gymnax 1.0's observation hook: `get_obs`."""
        return self.get_obs(state, params, key)

    def is_truncated(self, state: EnvState, params: EnvParams) -> jax.Array:
        """Whether the episode has reached its step limit."""
        return state.time >= params.max_steps_in_episode

    def is_terminated(self, state: EnvState, params: EnvParams) -> jax.Array:
        """Always ``False``: nobody dies of HeartPole's heart attacks."""
        return jnp.bool_(False)

    def is_terminal(self, state: EnvState, params: EnvParams) -> jax.Array:
        """gymnax's older name of `is_terminated` (time limits excluded)."""
        return self.is_terminated(state, params)

    def discount(self, state: EnvState, params: EnvParams) -> jax.Array:
        """Always 1.0: HeartPole's episodes end by truncation, never in an absorbing state."""
        return jnp.float32(1.0)

    def action_space(self, params: EnvParams | None = None) -> Discrete:
        """``Discrete(num_actions)``, in the variant's action order."""
        return Discrete(self._num_actions)

    def observation_space(self, params: EnvParams | None = None) -> Box:
        """The float32 box of the Gymnasium env's observation space (the same bounds)."""
        from heartpole.env import observation_space

        box = observation_space(self.dynamics)
        low, high = box.low, box.high
        if self.sensor is not None:
            low, high = self.sensor.space(low, high)
        if self.observe_traits and self.people is not None:
            trait_low, trait_high = self.people.trait_bounds()
            low, high = np.concatenate([low, trait_low]), np.concatenate([high, trait_high])
        return Box(low, high, low.shape, jnp.float32)

    def state_space(self, params: EnvParams | None = None) -> dict[str, Any]:
        """The spaces of `EnvState`'s fields."""
        params = self.default_params if params is None else params
        from heartpole.env import observation_space

        variables = observation_space(self.dynamics)
        columns = 0 if self.population is None else len(self.population.columns)
        return {
            "variables": tuple(
                Box(low, high, (), jnp.float32) for low, high in zip(variables.low.tolist(), variables.high.tolist())
            ),
            "time": Box(0, np.iinfo(np.int32).max, (), jnp.int32),
            "person": Box(-1, max(len(self.people.cohort) - 1, -1), (), jnp.int32)
            if self.people
            else Box(-1, -1, (0,), jnp.int32),
            "person_values": Box(-np.inf, np.inf, (columns if self._carries_values() else 0,), jnp.float32),
            "seen": Box(-np.inf, np.inf, (0 if self.sensor is None else self.num_variables,), jnp.float32),
            "age": Box(0, np.inf, (() if self.sensor is not None else (0,)), jnp.float32),
        }

    # -- people ----------------------------------------------------------------------------------------
    def person_values(self, state: EnvState) -> jax.Array:
        """The values of ``state``'s person, one per column of ``people.columns`` (float32): a cohort member's
        row of the cohort, a distribution's person's as drawn (``state.person_values``); empty without people."""
        cohort = None if self.population is None else self.population.cohort_values
        return state.person_values if cohort is None else cohort[state.person]

    def _carries_values(self) -> bool:
        """Whether `EnvState.person_values` holds the person's values (a distribution's person)."""
        return self.population is not None and self.population.cohort_values is None

    def person_params(self, state: EnvState, params: EnvParams) -> EnvParams:
        """The params ``state``'s episode runs on: ``params`` with the entries the person's values set (the
        rest, the task's ``heart_attack_penalty`` and ``max_steps_in_episode`` among them, as given); without
        people, ``params`` itself."""
        if self.population is None:
            return params
        mine = self.population.params_of(params.effects, params.tables, state.person, state.person_values)
        return EnvParams(*mine, params.max_steps_in_episode)

    def params_for(self, sample: Sample, params: EnvParams | None = None) -> EnvParams:
        """A batch of ``EnvParams``, one per person of ``sample`` (a [`Sample`][heartpole.people.Sample] of
        any population), to ``vmap`` over as gymnax does: ``jax.vmap(env.step, in_axes=(0, 0, 0, 0))``.

        Each is ``params`` (default: the env's) with that person's entries; every leaf gains a leading axis of
        ``len(sample)``. A cohort member's equal, bit for bit, the params of an env made with their values.

        Raises:
            TypeError: ``sample`` is not a [`Sample`][heartpole.people.Sample].
        """
        if not isinstance(sample, Sample):
            raise TypeError(f"params_for() takes a heartpole.people.Sample (People.sample(rng, n)), got {sample!r}")
        params = self.default_params if params is None else params
        n = len(sample)
        tables = Population(sample.people, self.dynamics).tables(np.asarray(sample.values, dtype=np.float64))
        effects, step = Population.merge(params.effects, params.tables, tables, n)
        return EnvParams(effects, step, jnp.broadcast_to(params.max_steps_in_episode, (n,)))

    # -- the step's inputs as [`heartpole.model`][heartpole.model] takes them ------------------------------------------
    def _inputs(self, state: EnvState, params: EnvParams, action: jax.Array) -> tuple[ActionEffects, StepTables]:
        """The effects of ``action`` and the tables ``state``'s person steps by; a cohort's read by
        ``[person, action]`` (`Population.params_of`), never through the person's whole table.

        The tables pass an optimization barrier, which XLA cannot fuse across: on a CPU a scan of steps ran a
        third faster (84 fused kernels where it made 92), on a GPU as fast (docs/jax.md, "People on a GPU")."""
        if self.population is None:
            params = jax.lax.optimization_barrier(params)
            row, tables = jax.tree_util.tree_map(lambda table: table[action], params.effects), params.tables
        else:
            person = (state.person, state.person_values)
            row, tables = self.population.params_of(params.effects, params.tables, *person, action)
        return self._as_tuples(row, EFFECTS), self._tables(tables)

    def _tables(self, tables: StepTables) -> StepTables:
        """``tables`` (an ``EnvParams``'), a ``PerVariable`` field as a tuple, the Shape fields the env's own."""
        return self._as_tuples(tables, TABLES)._replace(**self._shape)

    def _as_tuples(self, table: Any, fields: TableFields) -> Any:
        """``table`` with each ``PerVariable`` array as the tuple of its items, as the model's step reads it."""
        return table._replace(**{name: tuple(getattr(table, name)[v] for v in range(self.num_variables))
                                 for name in fields.per_variable})  # fmt: skip


def _floats(values: tuple[Any, ...]) -> tuple[jax.Array, ...]:
    """``values`` as float32 scalars (a state as `EnvState` keeps it)."""
    return tuple(jnp.asarray(value, dtype=jnp.float32) for value in values)


def make(env_id: str = "HeartPole-v0", **env_kwargs: Any) -> tuple[HeartPoleJax, EnvParams]:
    """``(env, env_params)`` for a HeartPole id, like ``gymnax.make``; ``env_kwargs`` as for ``gymnasium.make``,
    with ``people``, ``observe_traits`` and ``measurement`` (see [`HeartPoleJax`][heartpole.jax.env.HeartPoleJax])."""
    env = HeartPoleJax.from_id(env_id, **env_kwargs)
    return env, env.default_params
