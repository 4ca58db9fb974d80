"""Pluggable forces. Each is optional; a simulation pays only for those it has.

All act as velocity changes applied once per time step (see `Force`).
"""

import inspect

from labrig.params import Param
from labrig.validate import InputError

from .base import Force, StepContext
from .fields import CentreGravity, Drag, Gravity
from .thermal import Langevin, ThermalKicks
from .vdw import VanDerWaals, hamaker_force, thesis_offset

#: The built-in forces by name, for files (checkpoints, experiment files).
FORCE_TYPES = {cls.__name__: cls for cls in (VanDerWaals, ThermalKicks, Langevin, Drag, Gravity, CentreGravity)}
#: Declaration of a force table's ``type`` key (`labrig.params`); each force declares its parameters (``PARAMS``).
FORCE_TYPE = Param("str", choices=tuple(sorted(FORCE_TYPES)), doc="the force")


def force_from_dict(spec: dict) -> Force:
    """Rebuild a force from ``Force.to_dict()`` output.

    Raises
    ------
    labrig.validate.InputError
        On an unknown ``type`` or a parameter the force does not take.
    """
    if not isinstance(spec, dict) or "type" not in spec:
        raise InputError(f"a force must be a table with a 'type' key, got {spec!r}")
    params = dict(spec)
    name = params.pop("type")
    if not isinstance(name, str) or name not in FORCE_TYPE.choices:
        raise InputError(f"unknown force type {name!r} (known: {', '.join(FORCE_TYPE.choices)})")
    cls = FORCE_TYPES[name]
    allowed = [n for n in inspect.signature(cls.__init__).parameters if n != "self"]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        raise InputError(f"{name} has no parameter {unknown[0]!r} (allowed: {', '.join(allowed)})")
    return cls(**params)


__all__ = [
    "FORCE_TYPES",
    "FORCE_TYPE",
    "force_from_dict",
    "Force",
    "StepContext",
    "VanDerWaals",
    "ThermalKicks",
    "Langevin",
    "Drag",
    "Gravity",
    "CentreGravity",
    "hamaker_force",
    "thesis_offset",
]
