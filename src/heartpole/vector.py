"""HeartPole as a native NumPy vector env: many people, one array operation per formula."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from heartpole import kernel
from heartpole import render as rendering
from heartpole.actions import Action
from heartpole.arrays import Recycler, new_results, placed
from heartpole.env import (
    RESET_INFO,
    build_dynamics,
    check_render_mode,
    compiled_for,
    final_infos,
    observation_space,
)
from heartpole.measurement import Measurement
from heartpole.observation import Observer, Seen, observe
from heartpole.parameters import Variable, check_integer
from heartpole.people import People, Sample
from heartpole.person_tables import PersonTables
from heartpole.time_limit import OwnTimeLimit, episode_length

INFO_KEYS = tuple(RESET_INFO)
"""The keys of a step's and a reset's ``info`` (each with its ``_key`` mask): the single env's."""
INFO_MASKS = tuple("_" + key for key in INFO_KEYS)

INFO_DTYPES = {"action_taken": kernel.ACTION_DTYPE, **{key: kernel.OUTPUTS[key] for key in INFO_KEYS[1:]}}
"""The dtypes of the ``info`` arrays, the same from ``step`` and ``reset``."""


class EpisodeEndedError(ResetNeeded, AssertionError):
    """``step`` in ``AutoresetMode.DISABLED`` while an env's episode has ended and it was not reset.

    Gymnasium's ``SyncVectorEnv`` fails there with an ``AssertionError``, so this is one too (and a
    ``gymnasium.error.ResetNeeded``, which says what to do)."""


class HeartPoleVectorEnv(OwnTimeLimit, VectorEnv):
    """``num_envs`` independent HeartPole episodes stepped together, with the single env's dynamics.

    The same compiled step as [`heartpole.HeartPole`][heartpole.env.HeartPole]
    ([`heartpole.kernel.step_envs`][heartpole.kernel.step_envs]) runs over a ``(num_variables, num_envs)`` float32
    state, in place. Each env's random numbers are keyed by one 64-bit draw from ``self.np_random`` at ``reset``, in env
    order, and counted from there on (through autoresets too): env 0 after ``reset(seed=s)`` follows
    ``HeartPole().reset(seed=s)`` bit for bit. Keyword arguments are the single env's.

    Spaces are batched: observations ``(num_envs, 6)`` float32, actions ``MultiDiscrete([4] * num_envs)``.
    Observations are copies of the state (never the state itself) in column-major (Fortran) order, as
    ``CartPoleVectorEnv``'s are: each variable is contiguous; ``np.ascontiguousarray(obs)`` gives rows.

    **The arrays a step returns** are the caller's while it holds any of them: the env never writes to one of a
    step's arrays while anything outside it holds one of them, by reference, by a view (``obs[1:]``, ``obs.T``),
    a memoryview or a tensor sharing its memory (holding one holds them all). Once nothing does, a later step may
    take them back and write its own results into them (`heartpole.arrays.Recycler`): ``obs`` (where it is the
    loop's copy of the state: no env restarted in the step, no traits or measurement observed; else it is new),
    ``reward`` and ``info``'s ``action_taken``, ``heart_attack``, ``heart_attack_risk``, ``productivity`` and
    ``score``. A weak reference does not hold them: through one alone, such an array may show a later step's
    values. Only CPython with its GIL tells by reference counts (`heartpole.arrays.COUNTED`); elsewhere (PyPy, a
    free-threaded build) every step returns new arrays. ``terminated``, ``truncated``, ``info``'s ``_key`` masks
    and ``final_obs``/``final_info`` are new at every step; ``info["person"]`` and ``info["traits"]`` are
    read-only arrays that the env replaces (never writes) when it draws new people.

    ``info`` holds the single env's keys ([`INFO_KEYS`][heartpole.vector.INFO_KEYS]: ``action_taken``, the index of the
    action taken, ``action_names`` naming it; ``heart_attack``, ``heart_attack_risk``, ``productivity``, ``score``) as
    arrays of ``num_envs`` values (dtypes [`INFO_DTYPES`][heartpole.vector.INFO_DTYPES]), with Gymnasium's ``_key``
    masks. ``step`` reports every key for every env (one mask array shared by the keys). ``reset`` gives the same keys
    with their values before any step (``action_taken`` -1, the others 0 or False, as the single env's ``reset``), for
    the envs it reset.

    ``reset(options={"reset_mask": mask})`` resets only the envs where ``mask`` (a bool array of shape
    ``(num_envs,)`` with at least one True; else ``TypeError`` or ``ValueError``, as Gymnasium's vector envs
    raise) is True; the others go on untouched. Those drawn afresh take the 64-bit keys a full
    ``reset(seed=...)`` with the same seed would give them (``num_envs`` draws from ``self.np_random``,
    env ``i`` the ``i``-th); ``seed=None`` continues the generator.

    Every episode is truncated after ``max_steps`` decisions (never terminated). Autoreset (Gymnasium's
    ``AutoresetMode``, as ``SyncVectorEnv`` runs it over [`heartpole.HeartPole`][heartpole.env.HeartPole]):

    * ``NEXT_STEP`` (default): the call to ``step`` after an env's episode ended starts a new one for that
      env, ignoring its action: its first observation, reward 0, ``truncated=False`` and ``reset``'s info
      values. The other envs step as usual.
    * ``SAME_STEP``: an env restarts within the step that ends its episode (the mode Stable-Baselines3's
      VecEnv expects). Its ``info["final_obs"]`` (an object array, ``None`` where no episode ended) holds the
      last observation, ``info["final_info"]`` the last step's info (keys with their ``_key`` masks),
      both masked by ``_final_obs`` and ``_final_info``; the top-level keys hold the new episode's
      ``reset`` values, so the last step is counted once.
    * ``DISABLED``: nothing restarts; reset the ended envs with ``reset(options={"reset_mask": truncated})``.
      ``step`` before that raises [`EpisodeEndedError`][heartpole.vector.EpisodeEndedError] (an ``AssertionError``, as
      ``SyncVectorEnv``'s) and changes nothing.

    Invalid actions (wrong shape, not integers, out of range) raise ``ValueError`` and change nothing.

    ``people``, ``observe_traits`` and ``measurement`` are the single env's (see its "People and
    measurements"): each env draws its own person at ``reset`` and at every autoreset (all drawn at once from
    one generator spawned from ``self.np_random`` at each ``reset``), ``info["person"]`` ``(num_envs,)`` int64
    and ``info["traits"]`` ``(num_envs, len(people.traits))`` float32 (read-only: copy them to change them) hold
    the current episodes' people (with ``SAME_STEP``, ``final_info`` holds the ended ones'), and
    ``self.people`` the population. The step stays one compiled loop (`heartpole.kernel`). With
    people, env 0 is still the single env bit for bit; with a measurement, its noise differs after ``reset``
    (drawn for all envs at once).

    Episode length: ``max_steps``; ``max_episode_steps`` (which ``gymnasium.make_vec`` passes along with the
    spec's ``max_steps``) is a time limit that may shorten it, as for the single env
    ([`episode_length`][heartpole.time_limit.episode_length]); ``env.spec.max_episode_steps`` reports the length the
    env truncates at.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 8, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        heart_attack_proclivity: float = 0.5,
        max_steps: int | None = None,
        render_mode: str | None = None,
        *,
        actions: Sequence[Action] | None = None,
        variables: Sequence[Variable] | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        people: People | str | None = None,
        observe_traits: bool = False,
        measurement: Measurement | None = None,
        **model_params: Any,
    ) -> None:
        check_integer("num_envs", num_envs, 1)
        check_render_mode(render_mode, self.metadata["render_modes"])
        if autoreset_mode not in list(AutoresetMode) and autoreset_mode not in [m.value for m in AutoresetMode]:
            accepted = [m.value for m in AutoresetMode]
            raise ValueError(f"autoreset_mode must be one of {accepted}, got {autoreset_mode!r}")
        max_steps = episode_length(max_steps, max_episode_steps)
        self.dynamics = build_dynamics(
            heart_attack_proclivity, max_steps, actions, variables, model_params, "HeartPoleVectorEnv.__init__"
        )
        self._observer = Observer(self.dynamics, people, observe_traits, measurement)
        self.people: People | None = self._observer.people
        """The population each episode's person is drawn from (``None``: everyone has the env's parameters)."""
        self._persons = None if self.people is None else PersonTables(self.dynamics, self.people)
        self.num_envs = int(num_envs)
        self.max_steps = int(max_steps)
        self.render_mode = render_mode
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.single_action_space = spaces.Discrete(len(self.dynamics.actions))
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._action_shape, self._num_actions = (self.num_envs,), len(self.dynamics.actions)
        self._everyone = _read_only(np.ones(self.num_envs, dtype=bool))  # copied: faster than np.ones
        self.single_observation_space = self._observer.space(observation_space(self.dynamics))
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._envs = np.zeros((len(self.dynamics.variables), self.num_envs), np.float32)  # the states
        self._rng = np.zeros((3, self.num_envs), dtype=np.uint32)
        self._started = False
        # Env i has taken `_clock - _starts[i]` steps of its episode; the earliest episode ends at `_next_end`,
        # so a step tests one number, not an array, until an episode ends.
        self._clock = 0
        self._starts = np.zeros(self.num_envs, dtype=np.int64)
        self._next_end = self.max_steps
        self._ended: np.ndarray | None = None  # NEXT_STEP and DISABLED: envs whose episode ended, not restarted
        self._last_actions = np.full(self.num_envs, -1)
        self._last_attacks = np.zeros(self.num_envs, dtype=bool)
        self._heart_attacks = np.zeros(self.num_envs, dtype=np.int64)
        # Each env's person: cohort index, traits and the kernel's numbers; the generators of people and noise.
        self._person = _read_only(np.full(self.num_envs, -1, dtype=np.int64))
        self._traits = np.zeros((self.num_envs, 0 if self.people is None else len(self.people.traits)), np.float32)
        self._traits = _read_only(self._traits)
        self._cells = None if self._persons is None else self._persons.cells(self.num_envs)
        self._place_apart()
        self._people_rng: np.random.Generator | None = None
        self._seen = None if self._observer.sensor is None else Seen(self._observer.sensor, self.num_envs)
        self._results = Recycler(functools.partial(new_results, self.num_envs, len(self.dynamics.variables)))
        self._loop: Any = None  # the compiled loop over envs, planned at the first step (`_plan_loop`)
        self._loop_arguments: tuple[Any, ...] = ()

    @property
    def action_names(self) -> tuple[str, ...]:
        """The actions' names, in action-index order: ``action_names[info["action_taken"][i]]`` names env i's."""
        return tuple(action.name for action in self.dynamics.actions)

    @property
    def state(self) -> np.ndarray:
        """The current states, ``(num_variables, num_envs)`` float32 (a copy)."""
        if not self._started:
            raise ResetNeeded("call reset() before reading the state of HeartPoleVectorEnv")
        return self._envs.copy()

    def variable(self, name: str) -> np.ndarray:
        """The state variable ``name`` of every env, ``(num_envs,)`` float32: a copy of its row of `state` alone."""
        if not self._started:
            raise ResetNeeded("call reset() before reading the state of HeartPoleVectorEnv")
        return self._envs[self.dynamics.names.index(name)].copy()

    @property
    def heart_attack_proclivity(self) -> np.ndarray:
        """Each env's heart-attack proclivity, ``(num_envs,)`` float32 (a copy): the number its step multiplies the
        sigmoid of blood pressure by, its person's with ``people``. With the blood pressure (`variable`) it gives
        a step's risk in float64 ([`exact_risk`][heartpole.rewards.exact_risk])."""
        if self._persons is None or self._cells is None:
            return np.full(self.num_envs, self.dynamics.tables.heart_attack_proclivity, dtype=np.float32)
        return self._persons.table_values(self._cells, "heart_attack_proclivity")

    @property
    def generators(self) -> np.ndarray:
        """The envs' generator states, ``(3, num_envs)`` uint32 (a copy; rows as [`heartpole.rng`][heartpole.rng]'s
        ``KEY_LOW``, ``KEY_HIGH``, ``COUNTER``): a rollout that starts from them draws this env's random numbers."""
        if not self._started:
            raise ResetNeeded("call reset() before reading the generator states of HeartPoleVectorEnv")
        return self._rng.copy()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start every env afresh (fact 0, then waking up), or those of ``options["reset_mask"]``; other
        ``options`` are accepted and unused. See the class docstring."""
        mask = self._reset_mask(options)
        if not self._started and not mask.all():
            raise ResetNeeded("call reset() without a reset_mask first: the other envs have no episode yet")
        super().reset(seed=seed)
        people_rng, sensor_rng = self._observer.generators(self.np_random)
        keys = kernel.generator_states(self.np_random, self.num_envs)
        if people_rng is not None:  # the people a full reset draws; those of the envs reset now take theirs
            self._people_rng = people_rng
            self._new_people(mask, self.num_envs)
        if self._seen is not None and sensor_rng is not None:
            self._seen.rng = sensor_rng
        if mask.all():
            self._rng[:] = keys
            self._clock, self._ended, self._started = 0, None, True
        else:
            self._rng[:, mask] = keys[:, mask]
            self._ended = self._still_ended(~mask)
        self._restart(mask, draw=False)
        if self._seen is not None:
            self._seen.reset(self._envs.T, mask)
        info: dict[str, Any] = {}
        for key, value in RESET_INFO.items():
            info[key] = np.zeros(self.num_envs, dtype=INFO_DTYPES[key])
            info[key][mask], info["_" + key] = value, mask.copy()
        self._person_info(info)
        return self._observations(), info

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its action; see the class docstring for autoreset and ``info``."""
        array = self._integers(actions)
        restart = self._ended
        if not self._started or (restart is not None and self.autoreset_mode == AutoresetMode.DISABLED):
            self._refuse(array, actions)
        n = self.num_envs
        results = self._results()  # they go out as they are: new, or the last step's if nobody holds them
        reward, action, attack = results.reward, results.actions, results.heart_attack
        stepped = restart is None or not restart.all()
        if stepped:  # the loop checks the actions and converts them into `action` before it changes anything
            loop = self._loop or self._plan_loop(results, array)
            if not loop(self._envs, results, array, self._rng, *self._loop_arguments):
                self._refuse(array, actions)
        elif not kernel.convert_actions(array, self._num_actions, action):
            self._refuse(array, actions)
        present = self._everyone.copy()  # one mask for all keys: every key is present for every env
        info: dict[str, Any] = {}
        values = (action, attack, results.heart_attack_risk, results.productivity, results.score)
        for key, mask, value in zip(INFO_KEYS, INFO_MASKS, values):
            info[key], info[mask] = value, present
        self._clock += 1
        if restart is not None:  # NEXT_STEP autoreset: these envs start afresh instead of stepping
            if stepped:  # the kernel stepped them too: their draw is given back, as if they had not stepped
                self._rng[kernel.COUNTER, restart] -= np.uint32(1)
            self._restart(restart)
            reward[restart] = 0.0
            _write_reset_values(info, restart)
        if self.render_mode is not None:  # copies: `action` and `attack` go out in info
            self._last_actions[:], self._last_attacks[:] = action, attack
            self._heart_attacks += attack
        ended = None if self._clock < self._next_end else self._clock - self._starts >= self.max_steps
        if self._seen is not None:
            self._seen.step(self._envs.T, restart)
        self._person_info(info, present)
        # the loop's copy of the states is the observation unless some env restarted or the observer adds to it
        copied = stepped and restart is None and self._observer.plain
        obs, self._ended = results.observations.T if copied else self._observations(), None
        if ended is None:
            truncated = np.zeros(n, dtype=bool)
        elif self.autoreset_mode == AutoresetMode.SAME_STEP:  # the ended envs restart now
            info.update(final_infos(info, obs, ended))
            self._restart(ended)
            if self._seen is not None:
                self._seen.reset(self._envs.T, ended)
            _write_reset_values(info, ended)
            self._person_info(info, present)
            obs, truncated = self._observations(), ended
        else:  # they restart on the next step (NEXT_STEP) or when the caller resets them (DISABLED)
            self._ended, truncated = ended, ended.copy()
        return obs, reward, np.zeros(n, dtype=bool), truncated, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        """With ``render_mode="rgb_array"``: one RGB frame per env, drawing its current state."""
        if self.render_mode is None or not self._started:
            return None
        names, action_names = self.dynamics.names, self.action_names
        frames = []
        for i in range(self.num_envs):
            last = int(self._last_actions[i])
            frames.append(
                rendering.draw_frame(
                    dict(zip(names, self._envs[:, i].tolist())),
                    action=action_names[last] if last >= 0 else None,
                    heart_attack=bool(self._last_attacks[i]),
                    heart_attacks=int(self._heart_attacks[i]),
                    step=int(self._clock - self._starts[i]),
                    max_steps=self.max_steps,
                )
            )
        return tuple(frames)

    # ----------------------------------------------------------------------------------------------------
    def _plan_loop(self, results: kernel.StepResults, action: np.ndarray) -> Any:
        """The compiled loop over envs (v0's or the people's) for the types of this env's arrays, called without
        numba's dispatch (`heartpole.env.compiled_for`), kept for every later step: the arguments after the
        actions and the generator states are in `_loop_arguments`."""
        self._loop_arguments = (self.dynamics.packed, *self._loop_spec())
        self._loop = compiled_for(kernel.step_envs, (self._envs, results, action, self._rng, *self._loop_arguments))
        return self._loop

    def _loop_spec(self) -> tuple[np.ndarray, np.ndarray]:
        """The loop's ``cells`` and ``spec`` arguments after ``packed``: the people's numbers, if any."""
        if self._persons is None:
            return kernel.NO_CELLS, self.dynamics.spec.argument
        return self._cells, self._persons.spec.argument  # type: ignore[return-value]

    def __getstate__(self) -> dict[str, Any]:
        """The env's state for ``pickle`` and ``copy``: without the compiled loop, planned again at the next step."""
        return {**self.__dict__, "_loop": None, "_loop_arguments": ()}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a pickled or copied env, its loop's arrays placed apart again."""
        self.__dict__.update(state)
        self._place_apart()

    def _place_apart(self) -> None:
        """The loop's own arrays (states, generator states, people's cells) copied to their places in the caches
        (`heartpole.arrays.placed`)."""
        self._envs, self._rng = placed(self._envs, "states"), placed(self._rng, "generators")
        if self._cells is not None:
            self._cells = placed(self._cells, "cells")

    def _observations(self) -> np.ndarray:
        """A copy of the state as ``(num_envs, num_variables)``, column-major like ``CartPoleVectorEnv``'s (as
        measured and with the traits, if so made: then row-major)."""
        if self._observer.plain:
            return self._envs.copy().T
        return observe(self._envs.T, self._seen, self._traits if self._observer.observe_traits else None)

    def _new_people(self, which: np.ndarray, count: int) -> None:
        """Draw ``count`` people (vectorized) and give them, in env order, to the envs ``which``
        (a full reset draws one per env and keeps those of ``which``; an autoreset one per env restarted)."""
        assert self.people is not None and self._persons is not None and self._people_rng is not None
        drawn = self.people.sample(self._people_rng, count)
        chosen = which if count == self.num_envs else slice(None)
        # new arrays, read-only and never written again: info hands them out as they are, with no copy per step
        person, traits = self._person.copy(), self._traits.copy()
        person[which], traits[which] = drawn.person[chosen], drawn.traits()[chosen]
        self._person, self._traits = _read_only(person), _read_only(traits)
        taken = drawn if count == int(np.count_nonzero(which)) else _rows(drawn, which)
        self._persons.assign(self._cells, which, taken)  # type: ignore[arg-type]

    def _person_info(self, info: dict[str, Any], present: np.ndarray | None = None) -> None:
        """Put each env's current person (cohort index, -1 for a distribution) and traits into ``info``, with
        ``present`` as their mask (a new one if not given)."""
        if self.people is not None:
            present = np.ones(self.num_envs, dtype=bool) if present is None else present
            info["person"], info["_person"] = self._person, present
            info["traits"], info["_traits"] = self._traits, present

    def _restart(self, which: np.ndarray, draw: bool = True) -> None:
        """Start the envs where ``which`` afresh, with new people if ``draw`` (autoreset); their random numbers
        go on from their generator states."""
        if self._persons is not None and draw:
            self._new_people(which, int(which.sum()))
        kernel.reset_envs(self._envs, self._rng, which, self.dynamics.packed, *self._loop_spec())
        self._starts[which] = self._clock
        self._next_end = int(self._starts.min()) + self.max_steps
        self._last_actions[which], self._last_attacks[which], self._heart_attacks[which] = -1, False, 0

    def _still_ended(self, kept: np.ndarray) -> np.ndarray | None:
        """The ended episodes (`_ended`) among the envs ``kept``, or None if there are none."""
        if self._ended is None:
            return None
        ended = self._ended & kept
        return ended if ended.any() else None

    def _reset_mask(self, options: dict[str, Any] | None) -> np.ndarray:
        """``options["reset_mask"]`` checked as Gymnasium's vector envs check it, or every env."""
        if options is None or "reset_mask" not in options:
            return np.ones(self.num_envs, dtype=bool)
        mask = options["reset_mask"]
        if not isinstance(mask, np.ndarray):
            raise TypeError(f"`options['reset_mask']` must be a numpy array, got {type(mask)}")
        if mask.shape != (self.num_envs,):
            raise ValueError(f"`options['reset_mask']` must have shape `({self.num_envs},)`, got {mask.shape}")
        if mask.dtype != np.bool_:
            raise TypeError(f"`options['reset_mask']` must have `dtype=np.bool_`, got {mask.dtype}")
        if not mask.any():
            raise ValueError(
                "`options['reset_mask']` must contain a boolean array with at least one True value, "
                f"got reset_mask={mask}"
            )
        return mask.copy()

    def _integers(self, actions: Any) -> np.ndarray:
        """The actions as a C-contiguous int64 array (the type the compiled loop is planned for: itself where it
        is one, else a copy), or ``ValueError`` where they are not integers of shape ``(num_envs,)``. Their values
        are checked by the loop (`_refuse` says what is wrong)."""
        array = actions if type(actions) is np.ndarray else np.asarray(actions)
        dtype = array.dtype
        if array.shape != self._action_shape or dtype.kind not in "iu":
            got = f"shape {array.shape}" if array.shape != self._action_shape else f"dtype {dtype}"
            raise ValueError(f"HeartPoleVectorEnv.step expects {self._expected_actions()}; got {got}")
        if dtype == np.int64 and array.flags.carray:  # aligned, writeable and C-contiguous: as planned
            return array
        return array.astype(np.int64, order="C")  # uint64's largest wrap around, and back in the loop's check

    def _refuse(self, array: np.ndarray, actions: Any) -> None:
        """Raise what ``step`` raises before it steps, with nothing changed: ``ValueError`` where ``array`` (the
        ``actions`` given, as `_integers` made them) holds values that are not actions, else ``ResetNeeded``
        before the first reset, else `EpisodeEndedError` (see ``step``)."""
        if not kernel.convert_actions(array, self._num_actions, np.empty(self.num_envs, kernel.ACTION_DTYPE)):
            given = np.asarray(actions)
            raise ValueError(
                f"HeartPoleVectorEnv.step expects {self._expected_actions()}; got values from {given.min()} to "
                f"{given.max()}"
            )
        if not self._started:
            raise ResetNeeded("call reset() before step() in HeartPoleVectorEnv")
        assert self._ended is not None
        raise EpisodeEndedError(
            f"the episodes of envs {np.flatnonzero(self._ended).tolist()} have ended and autoreset_mode is "
            'DISABLED: reset them first, with reset(options={"reset_mask": mask})'
        )

    def _expected_actions(self) -> str:
        """What ``step`` accepts, in words."""
        return f"an integer array of shape ({self.num_envs},) with values in 0..{self._num_actions - 1}"


def _rows(sample: Sample, which: np.ndarray) -> Sample:
    """The people of ``sample`` at the envs ``which`` (a full reset's draw, of which some envs take theirs)."""
    return Sample(sample.people, sample.person[which], sample.values[which])


def _read_only(array: np.ndarray) -> np.ndarray:
    """``array``, made read-only (its owner replaces it rather than writes it: see ``_new_people``)."""
    array.flags.writeable = False
    return array


def _write_reset_values(info: dict[str, Any], which: np.ndarray) -> None:
    """Put ``reset``'s info values into ``info``'s arrays for the envs ``which`` (restarted in the step)."""
    for key, value in RESET_INFO.items():
        info[key][which] = value
