"""Is the board still inside what the engine integrates? Speed checks between chunks of a run."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np

from labrig.validate import InputError

#: Largest travel per sub-step, in radii, that a run accepts without a warning. Chipmunk sees a
#: contact only once two discs overlap, so a dot can overlap by what it travels in a sub-step; at
#: ~0.75 r it passes through walls, while up to ~0.35 r the hard cases stay within their overlap
#: tolerances (measured: `benchmarks.qdots_hard_cases`).
SAFE_TRAVEL = 0.5


class RunawayError(InputError, FloatingPointError):
    """The dots left the model's range: speeds that cross the board in one sub-step, or non-finite values.

    The parameters (forces, time step) are outside what the model can integrate; the message says
    what was measured and lists them.
    """


def check_motion(positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray, sub_dt: float,
                 box: tuple[float, float], describe: Callable[[], tuple[str, str]]) -> float:
    """The largest travel of a dot in one sub-step, in its radii; raise when the board ran away.

    Parameters
    ----------
    positions, velocities : ndarray, shape (N, 2)
        px and px/s.
    radii : ndarray, shape (N,)
        px.
    sub_dt : float
        Chipmunk's sub-step, s.
    box : (float, float)
        Board size, px.
    describe : callable
        Returns ``(where, causes)``: when it happened and what acts on the dots, for the message
        (called only to raise: describing the forces costs more than the check).

    Raises
    ------
    RunawayError
        A non-finite value, or a speed that crosses the board's diagonal in one sub-step.
    """
    speed = np.hypot(velocities[:, 0], velocities[:, 1])
    fastest = float(speed.max()) if np.isfinite(speed).all() else math.inf
    if not (np.isfinite(positions).all() and fastest * sub_dt < math.hypot(*box)):
        where, causes = describe()
        raise RunawayError(
            f"the dots left the model's range {where}: speeds of {fastest:.3g} px/s cross the {box[0]:g} x "
            f"{box[1]:g} px board in one sub-step of {sub_dt:g} s; {causes} are outside what the model integrates")
    return float((speed / radii).max()) * sub_dt


def describe_forces(forces) -> str:
    """The forces with their parameters, for messages (a force that cannot say them by its class name)."""
    def describe(force) -> str:
        try:
            return repr(force)
        except (AttributeError, TypeError, ValueError):
            return type(force).__name__

    return ", ".join(map(describe, forces)) or "none"


def warn_travel(travel: float, when: str) -> None:
    """Warn that a dot moves ``travel`` radii per sub-step, more than `SAFE_TRAVEL`."""
    warnings.warn(f"{when} a dot moves {travel:.2f} radii per sub-step (> {SAFE_TRAVEL}): contacts are found "
                  "only once discs overlap, so overlaps of that size and dots passing through walls become "
                  "possible; use a smaller dt, more substeps or a larger max_substeps", RuntimeWarning, stacklevel=4)
