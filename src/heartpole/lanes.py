"""Operations for HeartPole's compiled loops that LLVM vectorises: float32 ``exp``, a branch-free ``where``, and
wrapping 32-bit unsigned arithmetic.

[`heartpole.kernel`][heartpole.kernel] compiles [`heartpole.model`][heartpole.model]'s step and
[`heartpole.rng`][heartpole.rng]'s generator with these bindings. Each is written so that a loop over envs stays one
straight stretch of vector instructions: no calls, no branches, no widening to 64 bits. With
``NUMBA_DISABLE_JIT=1`` plain Python stands in for the intrinsics.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numba import njit
from numba.core import types as nbtypes
from numba.extending import intrinsic

from heartpole.jit import INLINE, JIT

F32, U32, U64 = np.float32, np.uint32, np.uint64
LOG2E, LN2_HIGH, LN2_LOW = F32(1.4426950408889634), F32(0.693359375), F32(-2.12194440e-4)
EXP_LOW, EXP_HIGH = F32(-87.0), F32(87.0)


@intrinsic
def _int32_as_float32_intrinsic(typingctx: Any, bits: Any) -> Any:
    """The float32 whose IEEE-754 bits are the int32 ``bits`` (a bit cast, no conversion)."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.bitcast(args[0], context.get_value_type(nbtypes.float32))

    return nbtypes.float32(nbtypes.int32), codegen


_int32_as_float32: Any = _int32_as_float32_intrinsic


@njit(**JIT, **INLINE)
def exp32(x: Any) -> Any:
    """``e ** x`` in float32 without branches or calls, so that LLVM vectorises it.

    ``x`` is clamped to [-87, 87], where float32 ``exp`` and ``1 / (1 + exp)`` are finite and normal (the
    formulas need nothing beyond: their sigmoids are 0 or 1 there to float32 precision; past 87, ``1 / (1 +
    exp)`` would be a subnormal, which CPUs compute many times slower). Then ``e ** x = 2 ** n * e ** r`` with
    ``|r| <= ln(2) / 2``; ``e ** r`` is its Taylor polynomial to degree 6 (relative error below 2e-7).
    """
    x = min(max(F32(x), EXP_LOW), EXP_HIGH)
    n = np.floor(x * LOG2E + F32(0.5))
    r = x - n * LN2_HIGH - n * LN2_LOW
    p = F32(1.0 / 720.0)
    p = p * r + F32(1.0 / 120.0)
    p = p * r + F32(1.0 / 24.0)
    p = p * r + F32(1.0 / 6.0)
    p = p * r + F32(0.5)
    p = p * r + F32(1.0)
    p = p * r + F32(1.0)
    return p * _int32_as_float32((np.int32(n) + np.int32(127)) << np.int32(23))


@njit(**JIT, **INLINE)
def where(condition: Any, a: Any, b: Any) -> Any:
    """``a if condition else b``; LLVM turns it into a select, not a branch."""
    return a if condition else b


# The random numbers (heartpole.rng) are compiled with these four 32-bit operations: LLVM's own, since numba
# would widen uint32 arithmetic to 64 bits (half the vector lanes).
def _uint32_operation(name: str) -> Any:
    @intrinsic
    def operation(typingctx: Any, a: Any, b: Any) -> Any:
        def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
            return getattr(builder, name)(args[0], args[1])

        return nbtypes.uint32(nbtypes.uint32, nbtypes.uint32), codegen

    operation.__doc__ = f"``a {name} b`` on 32-bit unsigned integers, wrapping around."
    return operation


mul32, add32, xor32, shr32 = (_uint32_operation(name) for name in ("mul", "add", "xor", "lshr"))

# Intrinsics run only in compiled code: plain Python stands in for them (numba.config has no static type).
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    _int32_as_float32 = lambda bits: np.int32(bits).view(np.float32)  # noqa: E731
    mul32 = lambda a, b: np.uint32((int(a) * int(b)) & 0xFFFFFFFF)  # noqa: E731
    add32 = lambda a, b: np.uint32((int(a) + int(b)) & 0xFFFFFFFF)  # noqa: E731
    xor32 = lambda a, b: np.uint32(int(a) ^ int(b))  # noqa: E731
    shr32 = lambda a, b: np.uint32(int(a) >> int(b))  # noqa: E731
