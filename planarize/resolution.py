"""Moved to `planarize.engines.resolution` (the continuum engine's driver, beside its engine); this name keeps
working for the 0.x releases (docs/stability.md)."""

from .engines.resolution import FLOOR, converge, error_columns, observed_orders, relative_error, volume_error

__all__ = ["converge", "error_columns", "observed_orders", "relative_error", "volume_error", "FLOOR"]
