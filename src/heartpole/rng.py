"""HeartPole's random numbers: one counter-based generator, written once and run by every backend.

The ``j``-th uniform of an env's ``c``-th draw is a keyed hash of ``(key, c, j)``: an env's generator state is
its 64-bit key (two 32-bit halves) and its draw counter, so copies and pickles continue exactly, and two envs
(or two policies evaluated alike, or two backends) with the same generator state see the same numbers. A step
takes one draw, ``len(state) + 2`` uniforms ([`draws`][heartpole.rng.draws]: the ``uniforms`` of
[`heartpole.model.step`][heartpole.model.step]); a reset takes one too, of which it uses the wake-up uniform.

Like the step, this is plain arithmetic with a few operations bound per backend (`BACKEND_BOUND`): 32-bit
unsigned integers that wrap around (``u32``, ``mul32``, ``add32``, ``xor32``, ``shr32``), ``to_float`` (an
integer below ``2 ** 24`` as a float32, exactly) and the step's ``where`` and ``replace``. NumPy's are bound
here, so these functions run on NumPy numbers and arrays as written; [`heartpole.kernel`][heartpole.kernel]
compiles them with numba and [`heartpole.jax`][heartpole.jax] traces them with ``jax.numpy``
([`rebind`][heartpole.rng.rebind]). Every backend therefore draws the very same uniforms, bit for bit.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy import where

from heartpole.backend import called_by, rebind_functions
from heartpole.model import Number, State, kept_by_the_step, replace

MIX_1, MIX_2 = 0x21F0AAAD, 0x735A2D97
"""The multipliers of [`mix32`][heartpole.rng.mix32] (C. Wellons' ``lowbias32``)."""
GOLDEN = 0x9E3779B9
"""``2 ** 32`` over the golden ratio: spreads a draw's uniforms ``j`` apart before the last round."""


def u32(value: Any) -> Any:
    """``value`` as a 32-bit unsigned integer (NumPy)."""
    return np.uint32(value)


def mul32(a: Any, b: Any) -> Any:
    """``a * b`` modulo ``2 ** 32``."""
    return np.multiply(np.uint32(a), np.uint32(b), dtype=np.uint32)


def add32(a: Any, b: Any) -> Any:
    """``a + b`` modulo ``2 ** 32``."""
    return np.add(np.uint32(a), np.uint32(b), dtype=np.uint32)


def xor32(a: Any, b: Any) -> Any:
    """``a ^ b`` on 32-bit unsigned integers."""
    return np.bitwise_xor(np.uint32(a), np.uint32(b), dtype=np.uint32)


def shr32(a: Any, b: Any) -> Any:
    """``a >> b`` on 32-bit unsigned integers (a logical shift)."""
    return np.right_shift(np.uint32(a), np.uint32(b), dtype=np.uint32)


def to_float(bits: Any) -> Any:
    """``bits`` (below ``2 ** 24``) as a float32: exact."""
    return np.float32(bits)


def mix32(x: Any) -> Any:
    """A bijective hash of 32-bit values with strong avalanche (C. Wellons' ``lowbias32``, bias ~0.1)."""
    x = xor32(x, shr32(x, u32(16)))
    x = mul32(x, u32(MIX_1))
    x = xor32(x, shr32(x, u32(15)))
    x = mul32(x, u32(MIX_2))
    return xor32(x, shr32(x, u32(15)))


def uniform(key_low: Any, key_high: Any, counter: Any, draw: Any) -> Number:
    """The ``draw``-th uniform of an env's draw number ``counter``: a float32 in [0, 1).

    Three rounds of `mix32`, keyed by the two halves of the env's 64-bit key; the top 24 bits of the last
    hash make the uniform, so every value is a multiple of ``2 ** -24`` (a float32 holds them exactly). A
    draw's first two rounds are shared by its uniforms. An env's counter wraps around after ``2 ** 32`` draws.
    """
    h = mix32(xor32(u32(counter), u32(key_low)))
    h = mix32(add32(h, u32(key_high)))
    h = mix32(xor32(h, mul32(add32(u32(draw), u32(1)), u32(GOLDEN))))
    return to_float(shr32(h, u32(8))) * 2.0**-24  # a literal: each backend makes it its float (float32)


def draws(key_low: Any, key_high: Any, counter: Any, zeros: State) -> State:
    """The ``len(zeros) + 2`` uniforms of one step ([`heartpole.model.step`][heartpole.model.step]'s
    ``uniforms``), as a tuple: one per variable, then waking up, then the heart-attack coin.

    The variables the step keeps itself ([`kept_by_the_step`][heartpole.model.kept_by_the_step]) take no
    effects, so their uniforms are 0 and cost nothing: the backends drop their hashes.
    """
    none = 0.0  # a literal, not a tuple of them: each backend makes it its float
    u = zeros + (none, none)
    for j in range(len(u)):
        u = replace(u, j, where(kept_by_the_step(j), none, uniform(key_low, key_high, counter, j)))
    return u


def wake_uniform(key_low: Any, key_high: Any, counter: Any, num_variables: int) -> Number:
    """The uniform a reset wakes up with: the wake-up uniform (number ``num_variables``) of its draw."""
    return uniform(key_low, key_high, counter, num_variables)


BACKEND_BOUND = ("u32", "mul32", "add32", "xor32", "shr32", "to_float", "where", "replace", "kept_by_the_step")
"""The operations every backend binds its own way (NumPy's here), and the model's function the draws read."""
FUNCTIONS = called_by(("draws", "wake_uniform"), globals(), BACKEND_BOUND)
"""The generator's functions, callees first: found from `draws`' and `wake_uniform`'s own code."""


def rebind(
    bindings: dict[str, Any],
    constant: Callable[[Any], Any] = lambda value: value,
    wrap: Callable[[Callable[..., Any]], Any] = lambda function: function,
) -> types.SimpleNamespace:
    """[`FUNCTIONS`][heartpole.rng.FUNCTIONS] with this module's very code objects against a backend's
    ``bindings`` of `BACKEND_BOUND`; ``constant`` and ``wrap`` as
    [`heartpole.model.rebind`][heartpole.model.rebind]'s."""
    return rebind_functions(globals(), FUNCTIONS, BACKEND_BOUND, bindings, constant, wrap)


def generator_states(rng: np.random.Generator, count: int) -> np.ndarray:
    """The generator states of ``count`` envs, ``(3, count)`` uint32 (rows `KEY_LOW`, `KEY_HIGH`, `COUNTER`):
    each a fresh 64-bit key drawn from ``rng`` (in env order, one 64-bit draw each) and a counter at 0."""
    keys = rng.integers(0, 2**64, size=count, dtype=np.uint64)
    return np.stack([keys & np.uint64(0xFFFFFFFF), keys >> np.uint64(32), np.zeros_like(keys)]).astype(np.uint32)


KEY_LOW, KEY_HIGH, COUNTER = 0, 1, 2
"""The rows of envs' generator states (``rng[:, i]``, uint32): the 64-bit key's halves and the draw counter."""
