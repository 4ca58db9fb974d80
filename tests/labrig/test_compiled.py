"""labrig.compiled: the fast-math kernels keep NaN's meaning (pixels left out are NaN) and compute the same sums."""

import math

import numpy as np

from labrig.compiled import FAST_MATH, jit


@jit(fastmath=True)
def finite_sum(values):
    """The sum of the values that are not NaN, and how many there were (a NaN test as the micrograph kernels make)."""
    total = 0.0
    n = 0
    for v in values:
        if not (v == v):
            continue
        total += v
        n += 1
    return total, n


@jit(fastmath=True)
def below(values, limit):
    """How many values lie below ``limit`` (a NaN compares false)."""
    n = 0
    for v in values:
        if v < limit:
            n += 1
    return n


def test_fast_math_leaves_nan_and_infinity_alone():
    assert "nnan" not in FAST_MATH and "ninf" not in FAST_MATH and "fast" not in FAST_MATH


def test_a_fast_math_kernel_still_skips_nan():
    values = np.array([1.0, math.nan, 2.5, math.nan, -0.5])
    total, n = finite_sum(values)
    assert n == 3 and total == 3.0
    assert below(values, 2.0) == 2
    assert below(np.array([math.nan, math.inf, -math.inf]), 0.0) == 1


def test_a_fast_math_sum_differs_from_numpy_by_rounding_only():
    values = np.random.default_rng(3).normal(size=10_001)
    total, n = finite_sum(values)
    assert n == values.size
    assert abs(total - math.fsum(values)) <= 1e-9 * np.abs(values).sum()
