"""Length units of height-map files: what a file states, what the user gives, and nm per unit."""

from __future__ import annotations

import math

import numpy as np

from labrig.validate import InputError

#: Length units, nm per unit. "A" is the ångström here (the user's word); see `FILE_UNITS`.
LENGTH_UNITS = {"nm": 1.0, "um": 1e3, "µm": 1e3, "μm": 1e3, "mm": 1e6, "m": 1e9, "pm": 1e-3, "A": 0.1, "Å": 0.1}
#: Length units as Gwyddion writes them (SI: "A" is the ampere, so it is not here).
FILE_UNITS = {k: v for k, v in LENGTH_UNITS.items() if k != "A"}
#: Largest coordinate or size stated in a file, in its own unit.
MAX_COORDINATE = 1e15


def unit_scale(unit: str, name: str = "unit") -> float:
    """nm per ``unit`` (a key of `LENGTH_UNITS`), or a ValueError naming the allowed units."""
    if unit not in LENGTH_UNITS:
        raise InputError(f"{name} must be a length unit, one of {', '.join(LENGTH_UNITS)}; got {unit!r}")
    return LENGTH_UNITS[unit]


def file_unit(unit, what: str) -> str:
    """A length unit stated in a file (SI spelling), or a ValueError saying what it is instead."""
    unit = "" if unit is None else str(unit).strip()
    if unit not in FILE_UNITS:
        raise InputError(f"{what} are in {unit or 'no unit'!r}, not a length "
                         f"(supported: {', '.join(FILE_UNITS)})")
    return unit


def agree(stated: str | None, given: str | None, name: str, what: str) -> float:
    """nm per unit: the file's (``stated``) if it states one, else the user's (``given``); the two must agree."""
    if given is not None:
        scale = unit_scale(given, name)
        if stated is not None and not math.isclose(scale, FILE_UNITS[stated], rel_tol=1e-12):
            raise InputError(f"{name}={given!r} contradicts the file, whose {what} are in {stated!r}; "
                             f"leave {name} out")
        return scale
    if stated is None:
        raise InputError(f"the file does not state the unit of its {what}: pass {name} "
                         f"({', '.join(LENGTH_UNITS)})")
    return FILE_UNITS[stated]


def spacing_pair(spacing, name: str = "spacing") -> tuple[float, float]:
    """``spacing`` (a number or a pair) as ``(dx, dy)``, both finite and > 0."""
    pair = (spacing, spacing) if np.ndim(spacing) == 0 else tuple(spacing)
    try:
        dx, dy = (float(v) for v in pair)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number or a pair (dx, dy), got {spacing!r}") from None
    if not all(math.isfinite(v) and v > 0 for v in (dx, dy)):
        raise InputError(f"{name} must be finite and > 0, got {spacing!r}")
    return dx, dy


def unit_scales(stated_xy, stated_z, unit, z_unit) -> tuple[float, float]:
    """nm per unit of the lateral coordinates and of the heights: the file's, else the user's."""
    xy = agree(stated_xy, unit, "unit", "lateral coordinates")
    if z_unit is not None:
        return xy, agree(stated_z, z_unit, "z_unit", "heights")
    return xy, agree(stated_z, None if stated_z else unit, "unit", "heights")


def given_spacing(spacing, stated: bool):
    """The user's grid spacing as ``(dx, dy)`` when the file does not state one (None when it does); an
    InputError when both or neither give it."""
    if spacing is not None and stated:
        raise InputError("the file states its grid spacing: leave spacing out")
    if spacing is None and not stated:
        raise InputError("the file does not state its grid spacing: pass spacing (in unit)")
    return None if spacing is None else spacing_pair(spacing)
