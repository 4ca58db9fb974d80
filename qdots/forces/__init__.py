"""Pluggable forces. Each is optional; a simulation pays only for those it has.

All act as velocity changes applied once per time step (see `Force`).
"""

from .base import Force, StepContext
from .fields import CenterGravity, Drag, Gravity
from .thermal import Langevin, ThermalKicks
from .vdw import VanDerWaals, hamaker_force, thesis_offset

__all__ = [
    "Force",
    "StepContext",
    "VanDerWaals",
    "ThermalKicks",
    "Langevin",
    "Drag",
    "Gravity",
    "CenterGravity",
    "hamaker_force",
    "thesis_offset",
]
