"""Deprecated name of `qdots.inference.calibration` (since 0.3; goes in 0.4)."""

from labrig.lazy import moved_module

__getattr__, __dir__ = moved_module(__name__, "qdots.inference.calibration", since="0.3", goes_in="0.4")
