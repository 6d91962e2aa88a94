"""What an env's agent observes when people differ or measurements are imperfect: shared by both envs.

Without people or measurement an observation is the state itself. [`Observer`][heartpole.observation.Observer]
adds, for envs made with ``people=``, ``observe_traits=`` or ``measurement=``: the measured state
([`Sensor`][heartpole.measurement.Sensor]: noisy, carried forward, with the measurement's age as one more
column when ``every > 1``), then the person's traits when ``observe_traits=True`` (in
[`People.traits`][heartpole.people.People.traits]' order). Its generators are spawned from the env's own at each
``reset``, so that a seed reproduces everything, env 0 of a vector env draws the person a single env draws, and
the states are those of the env without people or measurement.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from heartpole.dynamics import Dynamics
from heartpole.measurement import Measurement, Sensor
from heartpole.model import TIME_ELAPSED
from heartpole.people import People, check_observe_traits

LARGEST = float(np.finfo(np.float32).max)


class Observer:
    """An env's people and measurement, checked, and how they shape its observations.

    Args:
        dynamics: the env's variant.
        people: a [`People`][heartpole.people.People], a population's name (``"default"``) or ``None``.
        observe_traits: append the person's traits to the observation (needs ``people``).
        measurement: a [`Measurement`][heartpole.measurement.Measurement] or ``None`` (the state itself).

    Raises:
        TypeError: ``people``, ``observe_traits`` or ``measurement`` of the wrong type.
        ValueError: an unknown population name, ``observe_traits=True`` without people, a measurement of a
            variable the env does not have.
    """

    def __init__(self, dynamics: Dynamics, people: Any, observe_traits: Any, measurement: Any) -> None:
        self.people = People.resolve(people)
        self.observe_traits = check_observe_traits(observe_traits, self.people)
        self.measurement = measurement = Measurement.resolve(measurement)
        self.sensor: Sensor | None = None if measurement is None else measurement.sensor(dynamics.names)
        self.plain = self.sensor is None and not self.observe_traits
        """Whether the observation is the state itself."""

    def space(self, state_space: spaces.Box) -> spaces.Box:
        """The observation space of one env, given the state's."""
        low, high = state_space.low, state_space.high
        if self.sensor is not None:
            low, high = self.sensor.space(low, high)
        if self.observe_traits:
            assert self.people is not None  # checked in __init__
            trait_low, trait_high = self.people.trait_bounds()
            low, high = np.concatenate([low, trait_low]), np.concatenate([high, trait_high])
        low = np.maximum(low, -LARGEST).astype(np.float32)  # float32 bounds: no precision warning, whatever
        high = np.minimum(high, LARGEST).astype(np.float32)  # NumPy's promotion rules (1.x promotes to float64)
        return spaces.Box(low, high, dtype=np.float32)

    def generators(self, rng: np.random.Generator) -> tuple[np.random.Generator | None, np.random.Generator | None]:
        """The people's and the measurement's generators of a ``reset``: children spawned from the seed sequence
        of the env's ``rng`` (``rng.bit_generator.seed_seq.spawn``), which draw nothing from ``rng`` itself,
        so the env's keys and hence its states are those of the same env without people or measurement. A
        generator without a seed sequence gives two 64-bit draws instead. Without people and measurement there
        is nothing to spawn (a spawn changes only the seed sequence's count of children, which only this reads),
        but the two draws of a generator without a seed sequence stay: they advance ``rng``."""
        seeds: list[Any]
        sequence = getattr(rng.bit_generator, "seed_seq", None)
        if isinstance(sequence, np.random.SeedSequence) and self.people is None and self.sensor is None:
            return None, None  # nothing to seed, and spawning would change nothing a result reads: 0.1 ms saved
        if isinstance(sequence, np.random.SeedSequence):
            seeds = list(sequence.spawn(2))
        else:
            seeds = [int(x) for x in rng.integers(0, 2**64, size=2, dtype=np.uint64)]
        people = None if self.people is None else np.random.default_rng(seeds[0])
        sensor = None if self.sensor is None else np.random.default_rng(seeds[1])
        return people, sensor


class Seen:
    """The measured observations of ``n`` envs: what was last seen and how old it is (with a sensor)."""

    def __init__(self, sensor: Sensor, n: int) -> None:
        self.sensor = sensor
        self.seen = np.zeros((n, sensor.size))
        self.age = np.zeros(n)
        self.clock = np.zeros(n)  # each env's time_elapsed at its previous observation
        self.rng = np.random.default_rng(0)  # replaced at the first reset

    def reset(self, true: np.ndarray, which: np.ndarray) -> None:
        """Measure the envs ``which`` afresh (their episodes start): ``true`` is every env's state, ``(n, size)``."""
        seen, age = self.sensor.reset(true[which], self.rng)
        self.seen[which], self.age[which], self.clock[which] = seen, age, true[which, TIME_ELAPSED]

    def step(self, true: np.ndarray, restarted: np.ndarray | None) -> None:
        """One step of every env; those ``restarted`` (their state is a new episode's) are measured afresh."""
        passed = true[:, TIME_ELAPSED] - self.clock
        if restarted is not None:
            passed[restarted] = np.inf
        self.seen, self.age = self.sensor.step(true, self.seen, self.age, passed, self.rng)
        self.clock = true[:, TIME_ELAPSED].astype(np.float64)

    def observation(self) -> np.ndarray:
        """``(n, size [+ 1])`` float32: the seen values, then the age column if the sensor has one."""
        return self.sensor.observation(self.seen, self.age)


def observe(states: np.ndarray, seen: Seen | None, traits: np.ndarray | None) -> np.ndarray:
    """``(n, columns)`` float32 observations of ``n`` envs: their states ``(n, num_variables)`` as ``seen``
    measures them (or as they are), then their people's ``traits`` (when observed)."""
    parts = [states if seen is None else seen.observation()]
    if traits is not None:
        parts.append(traits)
    return np.concatenate(parts, axis=1).astype(np.float32)
