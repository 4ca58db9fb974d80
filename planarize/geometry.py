"""Euclidean distances in 3-D (thesis section 3.2.2), written once, compiled, used by the engines and by you.

The thesis uses point-point (Eq 3.5) and point-segment (Eq 3.6) distances and omits point-plane
ones; `point_triangle` is the exact distance to a triangular facet that it left out. Each function
also says *where* on the segment or triangle the closest point lies, which decides which grid points
a distance belongs to.

The scalar functions (`segment`, `segment_foot_inside`, `triangle`) are the definitions: the
engines' compiled kernel (`planarize.engines.kernels`) calls them point by point. The array
functions (`point_point`, `point_segment`, `point_triangle`) broadcast their arguments (arrays whose
last axis holds ``x, y, z``) and call the same scalar code for every element.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

_TINY = float(np.finfo(float).tiny)
_INF = math.inf


@jit(inline=True)
def segment(px, py, pz, ax, ay, az, bx, by, bz):
    """Distance from point p to the segment a-b, and where its closest point lies: ``(distance, t)``.

    The closest point is ``a + t (b - a)`` with ``t`` in [0, 1]: 0 or 1 at an end point, strictly
    between when the perpendicular from p meets the segment (Eq 3.6). A degenerate segment
    (``a == b``) gives ``t = 0``.
    """
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    length2 = ux * ux + uy * uy + uz * uz
    along = wx * ux + wy * uy + wz * uz
    t = along / length2 if length2 > 0 else 0.0
    t = min(max(t, 0.0), 1.0)
    dx, dy, dz = wx - t * ux, wy - t * uy, wz - t * uz
    return math.sqrt(dx * dx + dy * dy + dz * dz), t


@jit(inline=True)
def segment_foot_inside(px, py, pz, ax, ay, az, bx, by, bz):
    """Distance from p to the segment a-b when its perpendicular foot lies strictly inside the segment, else inf.

    The engines' point-segment feature (Eq 3.6): a segment whose closest point to p is an end point
    is not a feature of its own (the end point is). For non-degenerate segments only.
    """
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    length2 = ux * ux + uy * uy + uz * uz
    along = wx * ux + wy * uy + wz * uz
    # computed whether or not the foot is inside, then chosen: a branch per pair mispredicts often
    t = along / length2
    inside = (0 < along) & (along < length2) & (0 < t) & (t < 1)
    value = math.sqrt(max(wx * wx + wy * wy + wz * wz - t * along, 0.0))
    return value if inside else _INF


@jit(inline=True)
def triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Exact distance from p to the triangle abc, and the barycentric weights of its closest point.

    Returns ``(distance, wa, wb, wc)``: the closest point is ``wa a + wb b + wc c`` with weights >= 0
    summing to 1. It is the perpendicular foot when that falls inside the triangle (every weight
    > 0), else the closest point of an edge (the weight of the opposite corner is exactly 0).
    Degenerate triangles (zero area) are their edges.
    """
    d_ab, t_ab = segment(px, py, pz, ax, ay, az, bx, by, bz)
    d_bc, t_bc = segment(px, py, pz, bx, by, bz, cx, cy, cz)
    d_ca, t_ca = segment(px, py, pz, cx, cy, cz, ax, ay, az)
    if d_ab <= d_bc and d_ab <= d_ca:
        distance, wa, wb, wc = d_ab, 1.0 - t_ab, t_ab, 0.0
    elif d_bc <= d_ca:
        distance, wa, wb, wc = d_bc, 0.0, 1.0 - t_bc, t_bc
    else:
        distance, wa, wb, wc = d_ca, t_ca, 0.0, 1.0 - t_ca
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    d00 = ux * ux + uy * uy + uz * uz
    d01 = ux * vx + uy * vy + uz * vz
    d11 = vx * vx + vy * vy + vz * vz
    d20 = wx * ux + wy * uy + wz * uz
    d21 = wx * vx + wy * vy + wz * vz
    det = d00 * d11 - d01 * d01
    if det > 1e-12 * max(d00 * d11, _TINY):
        fb = (d11 * d20 - d01 * d21) / det
        fc = (d00 * d21 - d01 * d20) / det
        fa = 1.0 - fb - fc
        if fa > 0 and fb > 0 and fc > 0:
            ex, ey, ez = wx - fb * ux - fc * vx, wy - fb * uy - fc * vy, wz - fb * uz - fc * vz
            face = math.sqrt(ex * ex + ey * ey + ez * ez)
            if face < distance:
                return face, fa, fb, fc
    return distance, wa, wb, wc


# -- on arrays ---------------------------------------------------------------------------------

def _columns(*points) -> tuple[tuple[int, ...], list[np.ndarray]]:
    """Broadcast ``(..., 3)`` point arrays; their common leading shape and their x, y, z as flat arrays."""
    arrays = np.broadcast_arrays(*(np.asarray(p, dtype=float) for p in points))
    if arrays[0].shape[-1:] != (3,):
        raise ValueError(f"points must have (x, y, z) on their last axis, got shape {arrays[0].shape}")
    return arrays[0].shape[:-1], [np.ascontiguousarray(a[..., k]).ravel() for a in arrays for k in range(3)]


@jit
def _segments(px, py, pz, ax, ay, az, bx, by, bz, distance, t):
    for k in range(len(px)):
        distance[k], t[k] = segment(px[k], py[k], pz[k], ax[k], ay[k], az[k], bx[k], by[k], bz[k])


@jit
def _triangles(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz, distance, weights):
    for k in range(len(px)):
        distance[k], weights[k, 0], weights[k, 1], weights[k, 2] = triangle(
            px[k], py[k], pz[k], ax[k], ay[k], az[k], bx[k], by[k], bz[k], cx[k], cy[k], cz[k])


def point_point(p, q) -> np.ndarray:
    """Distance between points ``p`` and ``q`` (Eq 3.5)."""
    d = np.asarray(p, dtype=float) - np.asarray(q, dtype=float)
    return np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2)


def point_segment(p, a, b) -> tuple[np.ndarray, np.ndarray]:
    """Distance from ``p`` to the segment ``a``-``b``, and where its closest point lies (see `segment`).

    Returns
    -------
    distance : ndarray
        Euclidean distance to the closest point of the segment.
    t : ndarray
        Position of that point, ``a + t (b - a)`` with ``t`` in [0, 1].
    """
    shape, columns = _columns(p, a, b)
    distance, t = np.empty(len(columns[0])), np.empty(len(columns[0]))
    _segments(*columns, distance, t)
    return distance.reshape(shape), t.reshape(shape)


def point_triangle(p, a, b, c) -> tuple[np.ndarray, np.ndarray]:
    """Exact distance from ``p`` to the triangle ``abc``, and the barycentric weights of its closest point.

    Returns
    -------
    distance : ndarray
    weights : ndarray, shape (..., 3)
        ``(wa, wb, wc)`` (see `triangle`).
    """
    shape, columns = _columns(p, a, b, c)
    distance, weights = np.empty(len(columns[0])), np.empty((len(columns[0]), 3))
    _triangles(*columns, distance, weights)
    return distance.reshape(shape), weights.reshape(*shape, 3)
