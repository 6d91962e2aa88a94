"""heartpole.lanes: the operations the compiled loops vectorise, against their definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from heartpole import lanes


def test_exp32_is_within_its_stated_error() -> None:
    exp32 = njit(lambda x: lanes.exp32(x))
    for x in np.linspace(-87, 87, 20_001, dtype=np.float32):
        assert exp32(x) == pytest.approx(math.exp(float(x)), rel=3e-7)
    assert exp32(np.float32(-1000.0)) == pytest.approx(math.exp(-87.0), rel=3e-7)
    assert math.isfinite(exp32(np.float32(1000.0)))


@pytest.mark.parametrize(("name", "expected"), [("mul32", 0x9E3779B9 * 7), ("add32", 0x9E3779B9 + 7)])
def test_the_32_bit_operations_wrap_around_in_compiled_code(name: str, expected: int) -> None:
    operation = getattr(lanes, name)
    compiled = njit(lambda a, b: operation(a, b))
    assert compiled(np.uint32(0x9E3779B9), np.uint32(7)) == expected % 2**32
