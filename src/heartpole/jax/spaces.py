"""The two spaces HeartPole needs, with gymnax's interface: [`Discrete`][heartpole.jax.spaces.Discrete] and
[`Box`][heartpole.jax.spaces.Box]; gymnax's own classes wherever gymnax is in use.

gymnax's wrappers check a space's class, not only its attributes: PureJaxRL's
``FlattenObservationWrapper`` asserts ``isinstance(space, gymnax.environments.spaces.Box)``, and
``GymnaxToGymWrapper`` converts only gymnax's ``Discrete`` and ``Box``. gymnax itself is no dependency of
HeartPole (its releases pin old Gymnasium and JAX versions) and takes seconds to import (it loads flax,
matplotlib and seaborn), so ``import heartpole.jax`` never imports it. Instead a space made while gymnax's spaces
module is loaded (``import gymnax``, or any of its wrappers, does it) is also an instance of gymnax's class: a
subclass of both, with HeartPole's behaviour ([`gymnax_class`][heartpole.jax.spaces.gymnax_class]). Envs make
their spaces when asked (``env.observation_space(params)``), so a program that uses gymnax's wrappers gets
spaces they accept, and one that does not never pays for gymnax.

>>> space = Discrete(4)
>>> space.n, space.shape, isinstance(space, Discrete)
(4, (), True)
"""

from __future__ import annotations

import sys
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

GYMNAX_SPACES = "gymnax.environments.spaces"
"""The module of gymnax's space classes; a space made while it is loaded is also an instance of its class."""

_flavours: dict[tuple[type, type], type] = {}


def gymnax_class(cls: type) -> type:
    """The class a space of ``cls`` is made as: ``cls`` itself, or while gymnax's spaces are loaded (see the module),
    a subclass of ``cls`` and gymnax's class of the same name, made once and kept."""
    module = sys.modules.get(GYMNAX_SPACES)
    theirs = getattr(module, cls.__name__, None) if module is not None else None
    if not isinstance(theirs, type) or issubclass(cls, theirs):
        return cls
    key = (cls, theirs)
    if key not in _flavours:  # HeartPole's methods first: gymnax's class lends its identity, not its behaviour
        _flavours[key] = type(cls.__name__, (cls, theirs), {"__module__": __name__, "__doc__": cls.__doc__})
    return _flavours[key]


class Discrete:
    """The integers ``0 .. n - 1`` (int32)."""

    def __new__(cls, *args: Any, **kwargs: Any) -> Discrete:
        return super().__new__(gymnax_class(cls))

    def __init__(self, num_categories: int) -> None:
        if num_categories < 1:
            raise ValueError(f"a Discrete space needs at least one value, got {num_categories!r}")
        self.n = int(num_categories)
        self.shape: tuple[int, ...] = ()
        self.dtype = jnp.int32

    def __reduce__(self) -> tuple[Any, ...]:
        return Discrete, (self.n,)

    def sample(self, key: jax.Array) -> jax.Array:
        """A uniform random value."""
        return jax.random.randint(key, self.shape, 0, self.n, dtype=self.dtype)

    def contains(self, x: Any) -> jax.Array:
        """Whether ``x`` is one of the values (traceable)."""
        return jnp.logical_and(x >= 0, x < self.n)

    def __repr__(self) -> str:
        return f"Discrete({self.n})"


class Box:
    """Arrays of ``shape`` between ``low`` and ``high`` (float32 unless told)."""

    def __new__(cls, *args: Any, **kwargs: Any) -> Box:
        return super().__new__(gymnax_class(cls))

    def __init__(self, low: Any, high: Any, shape: tuple[int, ...], dtype: Any = jnp.float32) -> None:
        self.low = np.broadcast_to(np.asarray(low, dtype=dtype), shape)
        self.high = np.broadcast_to(np.asarray(high, dtype=dtype), shape)
        self.shape, self.dtype = tuple(shape), dtype

    def __reduce__(self) -> tuple[Any, ...]:
        return Box, (self.low, self.high, self.shape, self.dtype)

    def sample(self, key: jax.Array) -> jax.Array:
        """A uniform random array within the bounds (unbounded sides are the largest finite float32), weighted
        so that ``high - low`` never overflows."""
        share = jax.random.uniform(key, self.shape, self.dtype)
        low, high = jnp.asarray(self.low), jnp.asarray(self.high)
        return jnp.clip(low * (1 - share) + high * share, low, high)

    def contains(self, x: Any) -> jax.Array:
        """Whether ``x`` lies within the bounds (traceable)."""
        return jnp.all(jnp.logical_and(x >= self.low, x <= self.high))

    def __repr__(self) -> str:
        return f"Box(shape={self.shape}, dtype={jnp.dtype(self.dtype).name})"


__all__ = ["GYMNAX_SPACES", "Box", "Discrete", "gymnax_class"]
