"""HeartPole's model and its random numbers traced by JAX: [`heartpole.model`][heartpole.model]'s step and
[`heartpole.rng`][heartpole.rng]'s generator with their own code objects, bound to ``jax.numpy``, and how a gymnax
step turns its key into the generator's draws."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from heartpole import model, rng

MODEL = model.rebind({"exp": jnp.exp, "where": jnp.where, "replace": model.replace})
"""[`heartpole.model`][heartpole.model]'s functions with their own code objects, run on ``jax.numpy``."""


def _u32(value: Any) -> jax.Array:
    return jnp.asarray(value, dtype=jnp.uint32)


RNG = rng.rebind(
    {
        "u32": _u32,
        "mul32": jnp.multiply,
        "add32": jnp.add,
        "xor32": jnp.bitwise_xor,
        "shr32": jax.lax.shift_right_logical,
        "to_float": lambda bits: bits.astype(jnp.float32),
        "where": jnp.where,
        "replace": model.replace,
        "kept_by_the_step": model.kept_by_the_step,
    }
)
"""[`heartpole.rng`][heartpole.rng]'s generator with its own code objects, on ``jax.numpy``'s 32-bit unsigned
integers (which wrap around as the generator needs): the NumPy envs' uniforms, bit for bit."""


RESET_DRAW = 1
"""The draw of a step's generator key (`key_draw`) that the autoreset's next episode takes; the step takes 0."""
NOISE = 1
"""A step's measurement noise comes from its key folded with this; a reset from draw ``d`` folds the key with
``2 + 2 * d`` for its noise and ``3 + 2 * d`` for a distribution's person (`HeartPoleJax._reset_from`)."""


def key_draw(key: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The generator key (two uint32 halves) whose draws a gymnax step (or reset) uses: ``key``'s own 64 bits.

    A threefry key (JAX's default, typed or a raw ``uint32[2]``) is already the output of the hash that
    ``split`` or ``fold_in`` made it with, and the generator hashes its key three times more, so the step
    takes the key's data as it is: a threefry call of its own was most of a step's arithmetic (measured: 1.4x
    the steps per CPU-second without it, at 16,384 envs). Keys of other implementations are drawn from, one
    64-bit `jax.random.bits` draw."""
    data = jax.random.key_data(key) if jnp.issubdtype(key.dtype, jax.dtypes.prng_key) else key
    if data.shape != (2,) or data.dtype != jnp.uint32:
        data = jax.random.bits(key, (2,), jnp.uint32)
    return data[0], data[1]
