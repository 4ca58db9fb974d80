"""Validation of scalar parameters, with messages that name the parameter."""

from __future__ import annotations

import math


def nonnegative(name: str, value: float) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite and >= 0."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return float(value)


def positive(name: str, value: float) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite and > 0."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return float(value)
