"""The statistics of HeartPole's results, in one place: Student-t intervals for means over episodes, and the
interquartile mean with a percentile-bootstrap interval across seeds (rliable's recommendation for few runs).

Written here on NumPy alone (the t quantile from a table and a Cornish-Fisher expansion, the IQM as
``scipy.stats.trim_mean(x, 0.25)``), so ``import heartpole`` needs neither SciPy nor rliable; the tests check
them against known values.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np


class Statistic(Protocol):
    """A statistic of values along an axis, as NumPy's reductions are: ``statistic(array, axis=1)``."""

    def __call__(self, values: np.ndarray, /, *, axis: int) -> float | np.ndarray: ...


_Z975 = 1.959963984540054
_T975_SMALL = {1: 12.7062, 2: 4.3027, 3: 3.1824, 4: 2.7764, 5: 2.5706, 6: 2.4469, 7: 2.3646, 8: 2.3060, 9: 2.2622}


def t_quantile_975(dof: int) -> float:
    """The 97.5% quantile of Student's t with ``dof`` degrees of freedom (NaN for ``dof < 1``).

    Exact to four decimals for ``dof < 10`` (a table), a Cornish-Fisher expansion beyond (error < 1e-5).
    """
    if dof < 1:
        return math.nan
    if dof in _T975_SMALL:
        return _T975_SMALL[dof]
    z = _Z975
    terms = (
        (z**3 + z) / 4,
        (5 * z**5 + 16 * z**3 + 3 * z) / 96,
        (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384,
        (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160,
    )
    quantile: float = z + sum(term / dof ** (k + 1) for k, term in enumerate(terms))  # int ** int is Any
    return quantile


def standard_error(values: np.ndarray) -> float:
    """The standard error of the mean of ``values`` (NaN for fewer than two)."""
    values = np.asarray(values, dtype=np.float64)
    if len(values) < 2:
        return math.nan
    return float(values.std(ddof=1) / math.sqrt(len(values)))


def confidence_interval(values: np.ndarray) -> tuple[float, float]:
    """The 95% Student-t interval for the mean of ``values``: ``mean -+ t * sd / sqrt(n)``.

    ``(nan, nan)`` for fewer than two values.

    >>> low, high = confidence_interval([1.0, 2.0, 3.0])  # 2 -+ 4.3027 / sqrt(3)
    >>> round(low, 4), round(high, 4)
    (-0.4842, 4.4842)
    """
    values = np.asarray(values, dtype=np.float64)
    mean = float(values.mean()) if len(values) else math.nan
    half = t_quantile_975(len(values) - 1) * standard_error(values)
    return (mean - half, mean + half)


def interquartile_mean(values: Sequence[float] | np.ndarray, axis: int = -1) -> float | np.ndarray:
    """The mean of the middle half: ``floor(n / 4)`` values cut from each end (``scipy.stats.trim_mean(x,
    0.25)``, which rliable uses); with fewer than 4 values, the plain mean.

    >>> float(interquartile_mean([1, 2, 3, 4, 5, 6, 7, 100]))  # 1, 2, 7 and 100 cut
    4.5
    """
    array = np.sort(np.asarray(values, dtype=np.float64), axis=axis)
    n = array.shape[axis]
    if n == 0:
        raise ValueError("the interquartile mean of no values is undefined")
    cut = n // 4
    return np.take(array, np.arange(cut, n - cut), axis=axis).mean(axis=axis)


def bootstrap_interval(
    values: Sequence[float],
    statistic: Statistic = interquartile_mean,
    *,
    resamples: int = 10_000,
    confidence: float = 0.95,
    seed: int = 0,
) -> tuple[float, float]:
    """A percentile-bootstrap interval of ``statistic`` over ``values`` (resampled with replacement).

    ``statistic`` is called on a ``(resamples, n)`` array with ``axis=1``. Deterministic for a given ``seed``.

    >>> values = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    >>> low, high = bootstrap_interval(values, seed=0)
    >>> low < float(interquartile_mean(values)) < high, bootstrap_interval(values, seed=0) == (low, high)
    (True, True)
    """  # fmt: skip
    array = np.asarray(values, dtype=np.float64)
    if array.size == 0:
        raise ValueError("a bootstrap interval needs at least one value")
    rng = np.random.default_rng(seed)
    samples = array[rng.integers(0, array.size, size=(resamples, array.size))]
    stats = statistic(samples, axis=1)
    tail = (1.0 - confidence) / 2.0 * 100.0
    low, high = np.percentile(stats, [tail, 100.0 - tail])
    return float(low), float(high)


def json_number(value: float) -> float | None:
    """``value`` for JSON: ``None`` (``null``) for NaN and infinities, which JSON does not have."""
    return float(value) if math.isfinite(value) else None


def json_interval(interval: Sequence[float]) -> list[float | None]:
    """An interval for JSON: its ends, ``null`` where there is none (fewer than two episodes)."""
    return [json_number(end) for end in interval]


def fixed(value: float, digits: int, *, sign: bool = False) -> str:
    """``value`` with ``digits`` decimals (and a ``+`` before positive ones with ``sign``), never a negative zero:
    a difference that rounds to zero reads ``0.0000``, not ``-0.0000``.

    >>> fixed(-1e-9, 5), fixed(-0.0, 2, sign=True), fixed(-0.25, 2), fixed(0.25, 2, sign=True)
    ('0.00000', '+0.00', '-0.25', '+0.25')
    """
    text = f"{value:+.{digits}f}" if sign else f"{value:.{digits}f}"
    if text.startswith("-") and not any(c in "123456789" for c in text):
        text = ("+" if sign else "") + text[1:]
    return text
