"""Euclidean distances in 3-D, vectorized over any leading shape (thesis section 3.2.2).

Points are arrays whose last axis holds ``(x, y, z)``; all arguments broadcast
against each other. The thesis uses point-point (Eq 3.5) and point-segment
(Eq 3.6) distances and omits point-plane ones; `point_triangle` is the exact
distance to a triangular facet that it left out. Each function also returns
*where* on the segment or triangle the closest point lies, which the engines
use to decide which grid points a distance belongs to.

The engines call the ``*_xyz`` forms, which take the three coordinates as
separate arrays (a structure of arrays is several times faster in numpy than
reducing over a length-3 axis).
"""

from __future__ import annotations

import numpy as np


def _xyz(v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = np.asarray(v, dtype=float)
    return v[..., 0], v[..., 1], v[..., 2]


def point_point(p, q) -> np.ndarray:
    """Distance between points ``p`` and ``q`` (Eq 3.5)."""
    d = np.asarray(p, dtype=float) - np.asarray(q, dtype=float)
    return np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + d[..., 2] ** 2)


def point_segment(p, a, b) -> tuple[np.ndarray, np.ndarray]:
    """Distance from ``p`` to the segment ``a``-``b``, and where its closest point lies.

    Returns
    -------
    distance : ndarray
        Euclidean distance to the closest point of the segment.
    t : ndarray
        Position of that point, ``a + t (b - a)`` with ``t`` in [0, 1]: 0 or
        1 when it is an end point, strictly between when the perpendicular
        from ``p`` meets the segment (the case of Eq 3.6). A degenerate
        segment (``a == b``) gives ``t = 0``.
    """
    return point_segment_xyz(*_xyz(p), *_xyz(a), *_xyz(b))


def point_segment_xyz(px, py, pz, ax, ay, az, bx, by, bz):
    """`point_segment` on coordinate arrays: returns ``(distance, t)``."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    length2 = ux * ux + uy * uy + uz * uz
    along = wx * ux + wy * uy + wz * uz
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(length2 > 0, along / length2, 0.0)
    t = np.clip(t, 0.0, 1.0)
    dx, dy, dz = wx - t * ux, wy - t * uy, wz - t * uz
    return np.sqrt(dx * dx + dy * dy + dz * dz), t


def segment_foot_xyz(px, py, pz, ax, ay, az, bx, by, bz):
    """Perpendicular distance from ``p`` to the line through ``a``, ``b`` and where its foot lies.

    Returns ``(distance, t)`` with the foot at ``a + t (b - a)``; the distance
    is that of the segment only when ``0 < t < 1``. For non-degenerate
    segments (``a != b``) and callers that only use feet strictly inside: the
    engines' grid segments, which always have a lateral extent.
    """
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    length2 = ux * ux + uy * uy + uz * uz
    along = wx * ux + wy * uy + wz * uz
    t = along / length2
    # Pythagoras: the foot is at distance along / |u| from a along the segment
    d2 = wx * wx + wy * wy + wz * wz - t * along
    return np.sqrt(np.maximum(d2, 0.0)), t


def point_triangle(p, a, b, c) -> tuple[np.ndarray, np.ndarray]:
    """Exact distance from ``p`` to the triangle ``abc``, and the barycentric weights of its closest point.

    The closest point is the perpendicular foot when that falls inside the
    triangle, else the closest point of one of the three edges. Degenerate
    triangles (zero area: coincident or collinear corners) are handled as
    their edges.

    Returns
    -------
    distance : ndarray
    weights : ndarray, shape (..., 3)
        ``(wa, wb, wc)``, >= 0, summing to 1: the closest point is
        ``wa a + wb b + wc c``. A weight is exactly 0 when the closest point
        lies on the opposite edge (or at a corner).
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (p, a, b, c)))
    distance, wa, wb, wc = point_triangle_xyz(*_xyz(p), *_xyz(a), *_xyz(b), *_xyz(c))
    return distance, np.stack([wa, wb, wc], axis=-1)


def triangle_frame(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Edge vectors ``u = b - a``, ``v = c - a``, ``w = p - a``, their dot products ``u.u, u.v, v.v,
    w.u, w.v`` and the Gram determinant, as a flat tuple.

    Written with arithmetic operators only, so that the same code runs on
    arrays here and on scalars in `planarize.engines.kernels` (same results bit for bit).
    """
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    d00 = ux * ux + uy * uy + uz * uz
    d01 = ux * vx + uy * vy + uz * vz
    d11 = vx * vx + vy * vy + vz * vz
    d20 = wx * ux + wy * uy + wz * uz
    d21 = wx * vx + wy * vy + wz * vz
    return ux, uy, uz, vx, vy, vz, wx, wy, wz, d00, d01, d11, d20, d21, d00 * d11 - d01 * d01


def point_triangle_xyz(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """`point_triangle` on coordinate arrays: returns ``(distance, wa, wb, wc)``."""
    px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz = np.broadcast_arrays(
        px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    # closest point on each edge: ab, bc, ca
    d_ab, t_ab = point_segment_xyz(px, py, pz, ax, ay, az, bx, by, bz)
    d_bc, t_bc = point_segment_xyz(px, py, pz, bx, by, bz, cx, cy, cz)
    d_ca, t_ca = point_segment_xyz(px, py, pz, cx, cy, cz, ax, ay, az)
    on_ab = (d_ab <= d_bc) & (d_ab <= d_ca)
    on_bc = ~on_ab & (d_bc <= d_ca)
    distance = np.where(on_ab, d_ab, np.where(on_bc, d_bc, d_ca))
    zero = np.zeros_like(distance)
    wa = np.where(on_ab, 1.0 - t_ab, np.where(on_bc, zero, t_ca))
    wb = np.where(on_ab, t_ab, np.where(on_bc, 1.0 - t_bc, zero))
    wc = np.where(on_ab, zero, np.where(on_bc, t_bc, 1.0 - t_ca))
    # the perpendicular foot, where the triangle has area and the foot is inside
    ux, uy, uz, vx, vy, vz, wx, wy, wz, d00, d01, d11, d20, d21, det = triangle_frame(
        px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    area_ok = det > 1e-12 * np.maximum(d00 * d11, np.finfo(float).tiny)
    with np.errstate(invalid="ignore", divide="ignore"):
        fb = np.where(area_ok, (d11 * d20 - d01 * d21) / det, -1.0)
        fc = np.where(area_ok, (d00 * d21 - d01 * d20) / det, -1.0)
    fa = 1.0 - fb - fc
    inside = area_ok & (fa > 0) & (fb > 0) & (fc > 0)
    if np.any(inside):
        ex, ey, ez = wx - fb * ux - fc * vx, wy - fb * uy - fc * vy, wz - fb * uz - fc * vz
        face = np.sqrt(ex * ex + ey * ey + ez * ez)
        use = inside & (face < distance)
        distance = np.where(use, face, distance)
        wa, wb, wc = np.where(use, fa, wa), np.where(use, fb, wb), np.where(use, fc, wc)
    return distance, wa, wb, wc
