"""Which parts of the metal and oxide surfaces are compared, whom a distance belongs to: the slot layout.

The distance of a metal point ``m`` to the oxide (thesis section 3.3) is the smallest distance
between a *feature* of the metal at ``m`` and a feature of the oxide, over these pairs:

``distance="thesis"`` (the Matlab's ``updatemetalpoint3``):
    * the point ``m`` and an oxide point (Eq 3.5);
    * the point ``m`` and an oxide grid segment, when the perpendicular meets
      the segment strictly inside (Eq 3.6);
    * a metal grid segment that ends at ``m`` and an oxide point, likewise.
``distance="exact"`` adds the facets the thesis omitted (its weakness 1):
    * the point ``m`` and the inside of an oxide triangle or of a half-diagonal
      (the triangle edges from a cell corner to the cell centre);
    * a metal triangle or half-diagonal at ``m`` and an oxide point.

    Together with the thesis pairs this is the exact distance from ``m`` to
    the oxide surface, plus the exact distance from oxide points to the
    part of the metal surface around ``m``.

Each pair names the oxide points that get raised when ``m`` is oxidized (the thesis's "oxide point
set"): an oxide point is its own set, a segment its two ends, and anything touching a cell centre
the cell's four corners (the centre height is their mean).

Every pair is generated from a (metal point, *anchor* oxide point) pair: the anchor's own point,
the oxide features touching it, and the metal features at ``m`` against the anchor point. The
kernel (`planarize.engines.kernels`) evaluates them into *slots*, one per feature pair, laid out
here and nowhere else:

====================  ======================  ========================================================
slots                 constant                feature pair
====================  ======================  ========================================================
0                     `POINT`                 the anchor oxide point
1-4                   `OXIDE_SEGMENTS`        oxide segments from the anchor, one per `EDGE_DIRECTIONS`
5-8                   `METAL_SEGMENTS`        metal segments from ``m``, against the anchor point
9-12 (exact)          `OXIDE_HALF_DIAGONALS`  oxide half-diagonals at the anchor, one per `QUADRANTS`
13-20 (exact)         `OXIDE_TRIANGLES`       two oxide triangles per quadrant at the anchor
21-24 (exact)         `METAL_HALF_DIAGONALS`  metal half-diagonals at ``m``, against the anchor point
25-32 (exact)         `METAL_TRIANGLES`       two metal triangles per quadrant at ``m``, likewise
====================  ======================  ========================================================
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from labrig.validate import choice

from ..grid import EDGE_DIRECTIONS, QUADRANTS, Grid
from ..model import DISTANCES

#: First slot of each feature group (see the module docstring).
POINT = 0
OXIDE_SEGMENTS = 1
METAL_SEGMENTS = 5
OXIDE_HALF_DIAGONALS = 9
OXIDE_TRIANGLES = 13
METAL_HALF_DIAGONALS = 21
METAL_TRIANGLES = 25
#: Slots per pair of each distance kind.
THESIS_SLOTS = 9
EXACT_SLOTS = 33


class FeatureTables(NamedTuple):
    """The grid as the compiled kernels see it: sizes, neighbour tables and feature offsets (one argument).

    Attributes
    ----------
    nx, ny, periodic, dx, dy
        The grid (`planarize.grid.Grid`).
    edge_nb, quad_cell, quad_corners, cell_corners : ndarray of int
        `Grid.edge_neighbours`, `Grid.quadrant_cell`, `Grid.quadrant_corners`, `Grid.cell_corners`.
    step_i, step_j : ndarray of int, shape (4,)
        Grid offsets of `EDGE_DIRECTIONS`.
    quad_i, quad_j : ndarray of int, shape (4,)
        Signs of `QUADRANTS`.
    centre_i, centre_j : ndarray, shape (4,)
        Offsets of the cell centre of each quadrant from its point, in grid steps.
    edge2, half2 : ndarray, shape (4,)
        Squared lateral lengths of the segments and half-diagonals, nm^2.
    exact : bool
        Exact distances (facets too), else the thesis's points and segments.
    """

    nx: int
    ny: int
    periodic: bool
    dx: float
    dy: float
    edge_nb: np.ndarray
    quad_cell: np.ndarray
    quad_corners: np.ndarray
    cell_corners: np.ndarray
    step_i: np.ndarray
    step_j: np.ndarray
    quad_i: np.ndarray
    quad_j: np.ndarray
    centre_i: np.ndarray
    centre_j: np.ndarray
    edge2: np.ndarray
    half2: np.ndarray
    exact: bool

    @property
    def n_slots(self) -> int:
        return EXACT_SLOTS if self.exact else THESIS_SLOTS


def feature_tables(grid: Grid, distance: str = "thesis") -> FeatureTables:
    """The `FeatureTables` of ``grid`` for the distance kind ``distance``."""
    choice("distance", distance, DISTANCES)
    step_i = np.array([di for di, _ in EDGE_DIRECTIONS], dtype=np.intp)
    step_j = np.array([dj for _, dj in EDGE_DIRECTIONS], dtype=np.intp)
    quad_i = np.array([sx for sx, _ in QUADRANTS], dtype=np.intp)
    quad_j = np.array([sy for _, sy in QUADRANTS], dtype=np.intp)
    quad_x, quad_y = quad_i * grid.dx, quad_j * grid.dy
    return FeatureTables(
        nx=grid.nx, ny=grid.ny, periodic=grid.periodic, dx=grid.dx, dy=grid.dy,
        edge_nb=grid.edge_neighbours, quad_cell=grid.quadrant_cell, quad_corners=grid.quadrant_corners,
        cell_corners=grid.cell_corners, step_i=step_i, step_j=step_j, quad_i=quad_i, quad_j=quad_j,
        centre_i=np.minimum(quad_i, 0) + 0.5, centre_j=np.minimum(quad_j, 0) + 0.5,
        edge2=(step_i * grid.dx) ** 2 + (step_j * grid.dy) ** 2,
        half2=(0.5 * quad_x) ** 2 + (0.5 * quad_y) ** 2,
        exact=distance == "exact")


def oxide_reach(longest: float, distance: str) -> float:
    """How far (nm) the closest point of an oxide feature can lie from the nearest of its grid points,
    given the oxide's longest feature edge ``longest`` (`planarize.engines.kernels.max_feature_length`).

    A segment's closest point is within half its length of one end; a half-diagonal or a triangle
    (exact distances) has only one or two real grid points (the centre is derived), so its whole
    length counts.
    """
    return 0.5 * longest if distance == "thesis" else longest
