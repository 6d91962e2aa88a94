"""Imperfect measurements: noisy observations, taken every few half-hours, the last value carried forward.

A [`Measurement`][heartpole.measurement.Measurement] names the measured variables with the standard
deviation of each one's Gaussian noise, and how often they are measured. The state itself is unchanged:
only what the agent observes is. Variables not named are observed exactly at every step (the clock and
the work done, say). The measured ones are measured together: at reset, and then at the first step at
least ``every`` half-hours after the last measurement (a sleep passes many half-hours at once); in between
the agent sees the last measured values, and the observation gains one column, the measurement's **age**
in half-hours (``0 <= age < every``; no column when ``every == 1``, where the age is always 0).

Bound to an env's variables, a [`Sensor`][heartpole.measurement.Sensor] steps a batch of envs at once,
purely: NumPy arrays in, arrays out, the noise from the ``numpy.random.Generator`` it is given (one
standard normal per env and measured variable at every step, used or not, so the draws do not depend on
the schedule). Off by default: an env's ``measurement=None`` observes the state itself.

>>> import numpy as np
>>> sensor = Measurement({"alertness": 0.1}, every=4).sensor(("alertness", "time_elapsed"))
>>> rng = np.random.default_rng(0)
>>> seen, age = sensor.reset(np.array([[1.0, 0.0]]), rng)
>>> seen, age = sensor.step(np.array([[0.9, 1.0]]), seen, age, np.array([1.0]), rng)
>>> age.tolist(), float(seen[0, 1])  # not measured yet: one half-hour old; the clock is exact
([1.0], 1.0)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from heartpole.parameters import check_integer, check_number


@dataclass(frozen=True, init=False)
class Measurement:
    """What is measured, how noisily, how often.

    ``Measurement({"alertness": 0.2, "hypertension": 0.5}, every=4)``: alertness and hypertension read with
    Gaussian noise of standard deviation 0.2 and 0.5, every 4 half-hours (2 hours), the last reading carried
    forward in between. A standard deviation of 0 measures a variable exactly, but only on schedule.

    Attributes:
        noise: ``(variable, sd)`` pairs, in the order given.
        every: half-hours between measurements (1: every step).

    Raises:
        ValueError: no variable, a name that is not a string, an sd that is not a finite number >= 0, or
            ``every`` not an integer >= 1.
    """

    noise: tuple[tuple[str, float], ...]
    every: int

    def __init__(self, noise: Mapping[str, float], every: int = 1) -> None:
        if not isinstance(noise, Mapping) or not noise:
            raise ValueError(f"noise must map at least one variable name to its noise sd, got {noise!r}")
        for name, sd in noise.items():
            if not isinstance(name, str):
                raise ValueError(f"noise's keys must be variable names, got {name!r}")
            check_number(f"noise[{name!r}] (a standard deviation)", sd, 0.0)
        object.__setattr__(self, "noise", tuple((name, float(sd)) for name, sd in noise.items()))
        object.__setattr__(self, "every", check_integer("every", every, 1))

    def sensor(self, variables: Sequence[str]) -> Sensor:
        """This measurement of an env whose observation columns are ``variables`` (in order).

        Raises:
            ValueError: a measured variable the env does not have (the message lists those it has).
        """
        names = list(variables)
        unknown = [name for name, _ in self.noise if name not in names]
        if unknown:
            raise ValueError(f"measurement of unknown variables {unknown}; the env observes {names}")
        columns = np.array([names.index(name) for name, _ in self.noise], dtype=np.int64)
        sd = np.array([sd for _, sd in self.noise], dtype=np.float64)
        return Sensor(len(names), columns, sd, self.every)

    def to_dict(self) -> dict[str, object]:
        """JSON-safe description (for reports and datasets' metadata)."""
        return {"noise": dict(self.noise), "every": self.every}

    @classmethod
    def resolve(cls, value: object) -> Measurement | None:
        """An env's ``measurement`` keyword: ``None``, a ``Measurement``, or its JSON description
        (``{"noise": {"alertness": 0.2}, "every": 4}``, as [`to_dict`][heartpole.measurement.Measurement.to_dict]
        writes it and a preset's or ``--env-kwargs``' JSON holds it).

        Raises:
            TypeError: anything else, or a description with other keys.
            ValueError: a description's bad values (see the class).
        """
        if value is None or isinstance(value, Measurement):
            return value
        if not isinstance(value, Mapping) or "noise" not in value or set(value) - {"noise", "every"}:
            raise TypeError(
                "measurement must be a heartpole.measurement.Measurement, its JSON description such as "
                f'{{"noise": {{"alertness": 0.2}}, "every": 4}}, or None; got {value!r}'
            )
        return cls(**value)


@dataclass(frozen=True, eq=False)
class Sensor:
    """A [`Measurement`][heartpole.measurement.Measurement] bound to an env's observation columns.

    Attributes:
        size: the env's observation columns (before the age).
        columns: the measured columns, ``(m,)`` int64.
        sd: their noise's standard deviations, ``(m,)`` float64.
        every: half-hours between measurements.
    """

    size: int
    columns: np.ndarray
    sd: np.ndarray
    every: int

    @property
    def has_age(self) -> bool:
        """Whether the observation gains the age column (``every > 1``)."""
        return self.every > 1

    def reset(self, true: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Measure every env now: ``(seen, age)`` for true observations ``true`` of shape ``(n, size)``."""
        return self.step(true, true, np.zeros(len(true)), np.full(len(true), np.inf), rng)

    def step(
        self,
        true: np.ndarray,
        seen: np.ndarray,
        age: np.ndarray,
        passed: np.ndarray,
        rng: np.random.Generator,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``n`` envs: what is seen now, and how old its measurement is.

        Args:
            true: ``(n, size)`` the true observations now.
            seen: ``(n, size)`` what was seen at the previous step (its measured columns are carried forward).
            age: ``(n,)`` half-hours between the previous step's measurement and the previous step.
            passed: ``(n,)`` half-hours since the previous step (``inf`` measures now: an env that reset).
            rng: the noise's generator: one ``standard_normal((n, m))`` draw per call.

        Returns:
            ``(seen, age)``: ``(n, size)`` float64, the true values with the measured columns replaced by a
            fresh noisy reading where ``age + passed >= every`` and by the carried one elsewhere; ``(n,)``
            float64 ages, 0 where measured now, ``age + passed`` elsewhere.
        """
        true = np.asarray(true, dtype=np.float64)
        if true.ndim != 2 or true.shape[1] != self.size:
            raise ValueError(f"true observations must have shape (n, {self.size}), got {true.shape}")
        noise = rng.standard_normal((len(true), len(self.columns)))
        seen, age, passed = (np.asarray(x, dtype=np.float64) for x in (seen, age, passed))
        return self.read(true, seen, age, passed, noise, np)

    def read(self, true: Any, seen: Any, age: Any, passed: Any, noise: Any, xp: Any) -> tuple[Any, Any]:
        """`step` with the noise given, on any array namespace ``xp`` (``numpy``, ``jax.numpy``): the one
        definition of a reading, which `step` runs on NumPy and ``heartpole.jax`` traces.

        ``noise`` is ``(n, m)`` standard normals, one per env and measured variable (in ``columns``' order);
        the other arguments and the result are `step`'s, in ``xp``'s arrays and float type.
        """
        measured = np.zeros(self.size, dtype=bool)
        measured[self.columns] = True
        sd = np.zeros(self.size)
        sd[self.columns] = self.sd
        position = np.zeros(self.size, dtype=np.int64)  # each column's noise (an unmeasured one's is unused)
        position[self.columns] = np.arange(len(self.columns))
        older = age + passed
        now = older >= self.every
        reading = true + xp.asarray(sd, dtype=true.dtype) * noise[:, position]
        carried = xp.where(now[:, None], reading, seen)
        return xp.where(measured, carried, true), xp.where(now, xp.zeros_like(older), older)

    def observation(self, seen: Any, age: Any, xp: Any = np) -> Any:
        """The observation: ``seen``, then the age column if [`has_age`][heartpole.measurement.Sensor.has_age]
        (float32, as the env's), on the array namespace ``xp`` (``numpy`` or ``jax.numpy``)."""
        if not self.has_age:
            return xp.asarray(seen, dtype=xp.float32)
        return xp.concatenate([seen, xp.asarray(age)[:, None]], axis=1).astype(xp.float32)

    def space(self, low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The observation space's bounds: the env's ``(low, high)`` (one per column), a noisy column's
        finite bounds opened to infinity (noise may read below a floor), then ``[0, every]`` for the age."""
        low, high = np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)
        noisy = self.columns[self.sd > 0]
        low[noisy], high[noisy] = -np.inf, np.inf
        if self.has_age:
            low, high = np.append(low, np.float32(0)), np.append(high, np.float32(self.every))
        return low, high
