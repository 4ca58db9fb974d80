"""Structure of a board beyond the thesis: hexatic order, g(r), clusters, Voronoi coordination.

Functions take a `qdots.State` (or anything with ``positions`` (N, 2) and
``radii`` (N,) in px) and return arrays or small dataclasses. Neighbours are
those of `qdots.analysis.neighbour_edges` (the thesis text's rule by default),
so every measure here agrees with the packing figures on who touches whom.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

from labrig.validate import InputError, count

from ..geometry import pairs_with_distances
from .packing import neighbour_edges, state_arrays

#: Most bins of `radial_distribution` (8 MB an array; ``qdots analyze`` uses 80, the default is 100).
MAX_BINS = 1_000_000


@dataclass(frozen=True)
class Hexatic:
    """Bond-orientational order ``psi_6``.

    Attributes
    ----------
    psi : ndarray of complex, shape (N,)
        ``psi_6(i) = (1/n_i) sum_j exp(6 i theta_ij)`` over the ``n_i``
        neighbours ``j`` of dot ``i``, ``theta_ij`` the angle of the bond
        ``i -> j`` to the x axis; 0 for a dot without neighbours. ``|psi|`` is 1
        for a dot whose neighbours sit on a perfect hexagon (any orientation),
        0 for a square-lattice dot.
    has_neighbours : ndarray of bool, shape (N,)
    global_order : float
        ``|mean psi|`` over dots with neighbours: 1 only for a single crystal;
        grains of different orientation average out.
    local_order : float
        ``mean |psi|`` over the same dots: local hexagonality, blind to grains.
    """

    psi: np.ndarray
    has_neighbours: np.ndarray
    global_order: float
    local_order: float


def hexatic_order(state, rule: str = "text", mean_radius: float | None = None) -> Hexatic:
    """Hexatic order ``psi_6`` per dot and for the board (neighbours by `neighbour_edges`)."""
    positions, radii = state_arrays(state)
    src, dst, _ = neighbour_edges(state, rule, mean_radius)
    bond = positions[dst] - positions[src]
    phase = np.exp(6j * np.arctan2(bond[:, 1], bond[:, 0]))
    n = np.bincount(src, minlength=len(radii))
    total = np.bincount(src, phase.real, len(radii)) + 1j * np.bincount(src, phase.imag, len(radii))
    has = n > 0
    psi = np.zeros(len(radii), dtype=complex)
    psi[has] = total[has] / n[has]
    if not has.any():
        return Hexatic(psi, has, math.nan, math.nan)
    return Hexatic(psi, has, float(abs(psi[has].mean())), float(np.abs(psi[has]).mean()))


@dataclass(frozen=True)
class RadialDistribution:
    """Pair distribution function ``g(r)`` of a board.

    Attributes
    ----------
    r : ndarray, shape (B,)
        Bin centres, px.
    edges : ndarray, shape (B + 1,)
        Bin edges, px.
    g : ndarray, shape (B,)
        Pair counts over those of an ideal gas with the same number of dots in
        the same window (1 for uncorrelated dots, at every r).
    counts : ndarray of int, shape (B,)
        Pairs (each once) whose centre distance falls in each bin.
    window : (float, float)
        Width and height of the window used for the normalisation, px.
    """

    r: np.ndarray
    edges: np.ndarray
    g: np.ndarray
    counts: np.ndarray
    window: tuple[float, float]


def _ideal_pairs(edges: np.ndarray, n: int, width: float, height: float) -> np.ndarray:
    """Expected pairs per bin for ``n`` uniform points in a ``width x height`` rectangle.

    Two uniform points in a rectangle are separated by ``v`` with density
    ``(W - |v_x|)(H - |v_y|) / (W H)^2``; its angular mean at distance r is
    ``W H - 2 r (W + H) / pi + r^2 / pi`` (r <= min(W, H)); integrated over
    the annulus with weight ``2 pi r`` it gives the expected fraction of pairs
    per bin, with the window's edges accounted for exactly.
    """
    def cumulative(r):
        return 2 * math.pi * (width * height * r**2 / 2 - 2 * (width + height) * r**3 / (3 * math.pi)
                              + r**4 / (4 * math.pi))
    return 0.5 * n * (n - 1) * np.diff(cumulative(edges)) / (width * height) ** 2


def radial_distribution(state, r_max: float | None = None, bins: int = 100) -> RadialDistribution:
    """Radial distribution function ``g(r)`` with exact edge correction for a rectangular board.

    Parameters
    ----------
    state : State
        The board. The window is ``state.box`` (the board the dots were
        deposited on), or the dots' bounding box if there is none.
    r_max : float, optional
        Largest distance, px (> 0, at most the window's smaller side).
        Default: 5 mean diameters, capped by the window (the cost grows as
        ``r_max^2``: ~0.6 s for 10^5 dots at 5 diameters).
    bins : int
        Number of equal bins in ``[0, r_max]``, in [1, `MAX_BINS`].

    Raises
    ------
    labrig.validate.InputError
        On a bad argument, or an ``r_max`` that takes more than `qdots.geometry.MAX_PAIRS` pairs.

    Notes
    -----
    The normalisation is the exact pair count of an ideal gas of the same N in
    the window (see `_ideal_pairs`), so ``g`` tends to 1 at large r for a
    board that fills its window uniformly; a board of clusters with empty
    space between them has ``g < 1`` at large r, which is a real feature (the
    dots are denser than the window on average near one another).
    """
    positions, radii = state_arrays(state)
    box = getattr(state, "box", None)
    if box is not None:
        width, height = float(box[0]), float(box[1])
    elif len(positions):
        width, height = (float(v) for v in np.ptp(positions, axis=0))
    else:
        width = height = 0.0
    if not (width > 0 and height > 0):
        raise InputError("radial_distribution needs a window of positive area (state.box or spread-out dots)")
    if r_max is None:
        r_max = min(10.0 * float(radii.mean()) if len(radii) else width, width, height)
    if not (isinstance(r_max, (int, float)) and 0 < r_max <= min(width, height)):
        raise InputError(f"r_max must be in (0, {min(width, height):g}] px (the window's smaller side), got {r_max!r}")
    bins = count("bins", bins, 1, MAX_BINS)
    edges = np.linspace(0.0, float(r_max), bins + 1)
    _, _, d = pairs_with_distances(positions, float(r_max), f"r_max = {r_max:g} px")
    counts = np.histogram(d, bins=edges)[0]
    ideal = _ideal_pairs(edges, len(radii), width, height)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(ideal > 0, counts / ideal, np.nan)
    return RadialDistribution(0.5 * (edges[1:] + edges[:-1]), edges, g, counts, (width, height))


def clusters(state, rule: str = "text", mean_radius: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Clusters: connected components of the neighbour graph.

    Returns
    -------
    labels : ndarray of int, shape (N,)
        Cluster of each dot, numbered from 0 in order of decreasing size.
    sizes : ndarray of int, shape (C,)
        Dots per cluster, largest first (an isolated dot is a cluster of 1).
    """
    _, radii = state_arrays(state)
    n = len(radii)
    if n == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    src, dst, _ = neighbour_edges(state, rule, mean_radius)
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(n, n))
    _, raw = connected_components(graph, directed=True, connection="weak")
    sizes = np.bincount(raw)
    order = np.argsort(-sizes, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[raw], sizes[order]


def _circumcentres(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Circumcentres of triangles with corners a, b, c (each (T, 2))."""
    b, c = b - a, c - a
    d = 2.0 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
    bb, cc = (b * b).sum(1), (c * c).sum(1)
    return a + np.column_stack([c[:, 1] * bb - b[:, 1] * cc, b[:, 0] * cc - c[:, 0] * bb]) / d[:, None]


def voronoi_coordination(state, min_edge: float = 1e-6) -> np.ndarray:
    """Number of Voronoi neighbours of each dot (edges of its Voronoi cell).

    Computed from the Delaunay triangulation (its dual, and ~2x faster to
    build than scipy's Voronoi): two dots are Voronoi neighbours when they
    share a Delaunay edge, and the length of their common cell edge is the
    distance between the circumcentres of the two triangles on that edge.

    Parameters
    ----------
    state : State
        The board (centres only: a point Voronoi tessellation, not a radical
        one).
    min_edge : float
        Cell edges shorter than ``min_edge`` times the mean nearest-neighbour
        distance are ignored, so four co-circular points (a square lattice)
        give 4 neighbours, not 4 plus an arbitrary diagonal.

    Returns
    -------
    ndarray of int, shape (N,)
        Coordination; -1 for dots whose cell is unbounded (on the convex hull)
        and for boards of fewer than 3 dots or collinear dots.
    """
    positions, radii = state_arrays(state)
    n = len(radii)
    out = np.full(n, -1, dtype=int)
    if n < 3 or np.linalg.matrix_rank(positions - positions.mean(axis=0)) < 2:
        return out
    nearest, partner = cKDTree(positions).query(positions, k=2)
    if nearest[:, 1].min() <= 0:
        dot = int(np.argmin(nearest[:, 1]))
        other = int(partner[dot, 1] if partner[dot, 0] == dot else partner[dot, 0])
        raise InputError(f"Voronoi coordination: dots {min(dot, other)} and {max(dot, other)} share a centre")
    tri = Delaunay(positions)
    corners = tri.simplices
    centres = _circumcentres(*(positions[corners[:, k]] for k in range(3)))
    t, k = np.nonzero(tri.neighbors > np.arange(len(corners))[:, None])  # each inner edge once
    across = tri.neighbors[t, k]
    length = np.sqrt(((centres[t] - centres[across]) ** 2).sum(axis=1))
    real = length > min_edge * float(nearest[:, 1].mean())
    ends = np.concatenate([corners[t, (k + 1) % 3][real], corners[t, (k + 2) % 3][real]])
    counts = np.bincount(ends, minlength=n)
    bounded = np.ones(n, dtype=bool)
    bounded[tri.convex_hull.ravel()] = False  # in 2-D a cell is unbounded iff its dot is on the hull
    out[bounded] = counts[bounded]
    return out
