"""The two spaces HeartPole needs, with gymnax's interface: [`Discrete`][heartpole.jax.spaces.Discrete] and
[`Box`][heartpole.jax.spaces.Box].

gymnax's wrappers and PureJaxRL-style code read ``n``, ``shape``, ``dtype``, ``low`` / ``high`` and call
``sample(key)`` and ``contains(x)``; these classes provide exactly that, so HeartPole's JAX env needs no
dependency on gymnax (whose releases pin old Gymnasium and JAX versions).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np


class Discrete:
    """The integers ``0 .. n - 1`` (int32)."""

    def __init__(self, num_categories: int) -> None:
        if num_categories < 1:
            raise ValueError(f"a Discrete space needs at least one value, got {num_categories!r}")
        self.n = int(num_categories)
        self.shape: tuple[int, ...] = ()
        self.dtype = jnp.int32

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

    def __init__(self, low: Any, high: Any, shape: tuple[int, ...], dtype: Any = jnp.float32) -> None:
        self.low = np.broadcast_to(np.asarray(low, dtype=dtype), shape)
        self.high = np.broadcast_to(np.asarray(high, dtype=dtype), shape)
        self.shape, self.dtype = tuple(shape), dtype

    def sample(self, key: jax.Array) -> jax.Array:
        """A uniform random array within the bounds (unbounded sides are the largest finite float32)."""
        return jax.random.uniform(key, self.shape, self.dtype, self.low, self.high)

    def contains(self, x: Any) -> jax.Array:
        """Whether ``x`` lies within the bounds (traceable)."""
        return jnp.all(jnp.logical_and(x >= self.low, x <= self.high))

    def __repr__(self) -> str:
        return f"Box(shape={self.shape}, dtype={jnp.dtype(self.dtype).name})"
