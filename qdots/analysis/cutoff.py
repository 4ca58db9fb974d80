"""The pair cutoff of the exciton network and rigorous bounds on the LQE error it makes.

Pair cutoff and its error
-------------------------
Only pairs closer than a cutoff ``R_c`` get a rate. Dropping the others changes
the LQE by at most (`truncation_bound`)::

    |LQE - LQE_cut| <= eta tau max_i sum_{R_ij > R_c} W_ij <= eta R_F^6 / (2 h^2 (R_c - h)^4),

where ``h`` is half the smallest centre distance on the board. First
inequality: run both chains on the same random clocks; they differ only if a
dropped hop fires before the exciton dies, and the expected number of such
firings is the dropped rate times the expected lifetime, at most ``eta tau``
(the Boltzmann factor is at most 1). Second: discs of radius ``h`` around the
dots do not overlap, and ``|y|^-6`` is subharmonic in the plane, so each
dot's ``R^-6`` is at most its mean over its disc; the discs beyond ``R_c``
lie outside radius ``R_c - h``, where ``|y|^-6`` integrates to
``pi / (2 (R_c - h)^4)``. With the default tolerance 1e-3 and the thesis's
``R_F = 2 h`` this gives ``R_c = 7.2`` diameters (about 170 partners per dot
in a close-packed film).

That bound rests on the board's one closest pair. On a measured film, where
two detections can sit a few px apart, it sends the cutoff far out (16 R_F on
a 2048 px film, 680 partners per dot). A second rigorous bound uses where the
dots are (`far_field_bound`): counted on a grid of cells of side ``s``, a dot
in cell ``a`` is at least ``d_min(a, b)`` from every dot in cell ``b``, and a
pair beyond ``R_c`` is dropped only if the cells' farthest points are beyond it
too, so ``sum_{R_ij > R_c} R_ij^-6 <= sum_b n_b max(d_min(a, b), R_c)^-6`` over
the cells ``b`` whose farthest point from ``a`` is beyond ``R_c``: one FFT
convolution of the counts. The network states the smaller of the two bounds,
and the default cutoff is the smallest (within 1 %) where it meets the
tolerance: 115 px instead of 231 px on that film. Both are rigorous but loose:
the far hops that they count mostly land on dots of similar yield (tests
measure the true change, ~20x smaller).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

#: Default bound on the LQE error from the pair cutoff (absolute).
CUTOFF_TOLERANCE = 1e-3
#: Cells per side of `far_field_bound`'s count grid, at most (its FFTs are 2x that: 30 ms for a default cutoff).
FAR_FIELD_CELLS = 128
#: `smallest_cutoff` seeks the default cutoff (`qdots.analysis.forster.exciton_network`) within this factor.
CUTOFF_SEARCH_RATIO = 1.01


def truncation_bound(forster_radius: float, cutoff: float, spacing: float, efficiency: float = 1.0) -> float:
    """Bound on the LQE error from dropping hops longer than ``cutoff`` (see the module docstring).

    Parameters
    ----------
    forster_radius, cutoff : float
        ``R_F`` and ``R_c``, px.
    spacing : float
        Smallest centre distance on the board, px (``2 h``).
    efficiency : float
        Intrinsic efficiency ``eta`` of a radiative dot (the lifetime is ``eta tau``).

    Returns
    -------
    float
        ``eta R_F^6 / (2 h^2 (R_c - h)^4)`` (inf if ``cutoff <= h``).
    """
    h = 0.5 * spacing
    if cutoff <= h:
        return math.inf
    try:
        return efficiency * forster_radius**6 / (2.0 * h * h * (cutoff - h) ** 4)
    except (OverflowError, ZeroDivisionError):  # beyond a float: no bound
        return math.inf


def cutoff_for(forster_radius: float, spacing: float, tolerance: float, efficiency: float = 1.0) -> float:
    """Smallest cutoff, px, whose `truncation_bound` is at most ``tolerance``."""
    h = 0.5 * spacing
    try:
        return h + (efficiency * forster_radius**6 / (2.0 * h * h * tolerance)) ** 0.25
    except (OverflowError, ZeroDivisionError):  # beyond a float: every pair is within the cutoff
        return math.inf


def far_field_grid(positions: np.ndarray, cell: float, box: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The dots counted on a grid for `far_field_bound`.

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        px (in ``[0, box)`` when ``box`` is given).
    cell : float
        Side of a cell, px (> 0); at least the span over `FAR_FIELD_CELLS` is taken.
    box : ndarray, shape (2,), optional
        Periodic box, px: the grid covers it exactly, and offsets wrap.

    Returns
    -------
    counts : ndarray, shape (M, K)
        Dots per cell; an open board's grid is padded to twice its cells, so that circular offsets are plain ones.
    size : ndarray, shape (2,)
        The cells' sides, px.
    """
    if box is None:
        low, span = positions.min(axis=0), np.ptp(positions, axis=0)
        cell = max(cell, float(span.max()) / FAR_FIELD_CELLS)
        cells = (span // cell).astype(int) + 1
        index = np.minimum(((positions - low) // cell).astype(int), cells - 1)
        shape, size = 2 * cells, np.array([cell, cell])
    else:
        cell = max(cell, float(box.max()) / FAR_FIELD_CELLS)
        shape = np.maximum(np.ceil(box / cell).astype(int), 1)
        size = box / shape
        index = np.minimum((positions // size).astype(int), shape - 1)
    counts = np.zeros(tuple(shape))
    np.add.at(counts, (index[:, 0], index[:, 1]), 1.0)
    return counts, size


def far_field_bound(counts: np.ndarray, size: np.ndarray, forster_radius: float, cutoff: float,
                    efficiency: float = 1.0) -> float:
    """Bound on the LQE error from dropping hops longer than ``cutoff``, from where the dots are.

    ``eta R_F^6 max_a sum_b n_b max(d_min(a, b), R_c)^-6`` over the cells ``b`` whose farthest point from
    cell ``a`` is beyond ``R_c``, ``a`` a cell holding a dot (see the module docstring).

    Parameters
    ----------
    counts, size
        From `far_field_grid`.
    forster_radius, cutoff : float
        ``R_F`` and ``R_c``, px.
    efficiency : float
        Intrinsic efficiency ``eta`` of a radiative dot.
    """
    offsets = [np.minimum(np.arange(m), m - np.arange(m)) for m in counts.shape]  # cells apart, either way round
    near = [np.maximum(k - 1, 0) * side for k, side in zip(offsets, size)]
    far = [(k + 1) * side for k, side in zip(offsets, size)]
    nearest = np.maximum(near[0][:, None] ** 2 + near[1][None, :] ** 2, cutoff * cutoff)
    reach = far[0][:, None] ** 2 + far[1][None, :] ** 2 > cutoff * cutoff
    kernel = np.where(reach, nearest ** -3.0, 0.0)
    sums = np.fft.irfft2(np.fft.rfft2(counts) * np.fft.rfft2(kernel), s=counts.shape)
    try:
        return efficiency * forster_radius**6 * float(sums[counts > 0].max()) * (1.0 + 1e-9)  # FFT round-off
    except OverflowError:
        return math.inf


def smallest_cutoff(bound: Callable[[float], float], low: float, high: float, tolerance: float) -> float:
    """The smallest cutoff in (``low``, ``high``], px, within `CUTOFF_SEARCH_RATIO`, whose ``bound`` is at most
    ``tolerance``, by bisection on a log scale (the bounds fall as the cutoff grows); ``high``'s must meet it."""
    while high > low * CUTOFF_SEARCH_RATIO:
        middle = math.sqrt(low * high)
        low, high = (low, middle) if bound(middle) <= tolerance else (middle, high)
    return high
