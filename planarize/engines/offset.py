"""The oxide over a metal height field: its conformal coat, and the roughness of both (compiled).

The oxide of the continuum limit (`planarize.engines.flow`) is, at thickness ``t``, the highest of
the metal's conformal coats so far: at a point ``y``, ``max over s <= t`` of the metal dilated by a
ball of radius ``s``::

    D_s[M](y) = max over x of  M(x) + sqrt(s^2 - |x - y|^2)

(an oxide point rises only while it is some metal point's nearest, and then it lies at exactly the
oxide thickness above that point; docs/planarize_continuum.md). `coat` evaluates ``D_t[M]`` on the
grid: the best grid point ``x`` in a window around each point's previous foot (and its neighbours'
feet), then a Newton step on the metal's local quadratic model for the sub-grid maximum. Open grids
are mirrored about their edge points, as in the flow.

`surface_moments` integrates the piecewise-linear surface of the thesis (four triangles per cell
meeting at the cell centre) exactly: its mean height and its RMS, the limit of Eq 3.8 as the grid
refines.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit


@jit(inline=True)
def _index(a, n, periodic):
    """Grid index ``a`` (any integer) folded into [0, n): periodic image or mirror about the edges."""
    if periodic:
        return a % n
    if n == 1:
        return 0
    period = 2 * (n - 1)
    a = a % period
    return a if a < n else period - a


@jit(inline=True)
def _value(z, a, b, periodic):
    nx, ny = z.shape
    return z[_index(a, nx, periodic), _index(b, ny, periodic)]


@jit
def _window(z, i, j, ci, cj, w, t, dx, dy, periodic, best, bi, bj):
    """The best grid point (largest ``z + sqrt(t^2 - r^2)``) of the window of half-width ``w`` around
    (ci, cj) (unfolded indices), as (value, i, j), starting from (best, bi, bj)."""
    nx, ny = z.shape
    t2 = t * t
    inside = ci - w >= 0 and cj - w >= 0 and ci + w < nx and cj + w < ny
    for a in range(ci - w, ci + w + 1):
        rx = (a - i) * dx
        rx2 = rx * rx
        if rx2 > t2:
            continue
        for b in range(cj - w, cj + w + 1):
            ry = (b - j) * dy
            r2 = rx2 + ry * ry
            if r2 <= t2:
                height = z[a, b] if inside else _value(z, a, b, periodic)
                if height + t < best:  # (the ball adds at most t)
                    continue
                v = height + math.sqrt(t2 - r2)
                if v > best:
                    best, bi, bj = v, a, b
    return best, bi, bj


@jit
def _refine(z, i, j, a, b, t, dx, dy, periodic, best):
    """The sub-grid maximum of ``M(x) + sqrt(t^2 - |x - y|^2)`` near grid point (a, b), for oxide point
    (i, j): Newton steps on the metal's quadratic model there, kept within a cell."""
    c = _value(z, a, b, periodic)
    gx = (_value(z, a + 1, b, periodic) - _value(z, a - 1, b, periodic)) / (2.0 * dx)
    gy = (_value(z, a, b + 1, periodic) - _value(z, a, b - 1, periodic)) / (2.0 * dy)
    hxx = (_value(z, a + 1, b, periodic) - 2.0 * c + _value(z, a - 1, b, periodic)) / (dx * dx)
    hyy = (_value(z, a, b + 1, periodic) - 2.0 * c + _value(z, a, b - 1, periodic)) / (dy * dy)
    hxy = (_value(z, a + 1, b + 1, periodic) - _value(z, a + 1, b - 1, periodic)
           - _value(z, a - 1, b + 1, periodic) + _value(z, a - 1, b - 1, periodic)) / (4.0 * dx * dy)
    cx = (a - i) * dx
    cy = (b - j) * dy
    ux = 0.0
    uy = 0.0
    t2 = t * t
    found = best
    for _ in range(4):
        rx = cx + ux
        ry = cy + uy
        s2 = t2 - rx * rx - ry * ry
        if s2 <= 0.0:
            break
        s = math.sqrt(s2)
        # gradient and Hessian of q(u) = M(u) + sqrt(t^2 - |c + u|^2)
        fx = gx + hxx * ux + hxy * uy - rx / s
        fy = gy + hxy * ux + hyy * uy - ry / s
        s3 = s2 * s
        axx = hxx - 1.0 / s - rx * rx / s3
        ayy = hyy - 1.0 / s - ry * ry / s3
        axy = hxy - rx * ry / s3
        det = axx * ayy - axy * axy
        if axx >= 0.0 or det <= 0.0:  # not concave here: keep the grid point
            break
        nx_ = ux - (ayy * fx - axy * fy) / det
        ny_ = uy - (axx * fy - axy * fx) / det
        if abs(nx_) > dx or abs(ny_) > dy:
            break
        ux, uy = nx_, ny_
        rx = cx + ux
        ry = cy + uy
        s2 = t2 - rx * rx - ry * ry
        if s2 <= 0.0:
            break
        v = c + gx * ux + gy * uy + 0.5 * (hxx * ux * ux + 2.0 * hxy * ux * uy + hyy * uy * uy) + math.sqrt(s2)
        if v > found:
            found = v
    return found


@jit
def coat(z, t, dx, dy, periodic, window, fi0, fj0, previous, out, foot_i, foot_j, start, stop):
    """``out = max(previous, D_t[z])`` on rows [start, stop): the metal ``z`` (nx, ny) dilated by a ball of
    radius ``t`` (nm), no lower than ``previous`` (the oxide so far).

    ``fi0``, ``fj0`` (nx, ny) hold each point's foot (the metal grid point, unfolded index, that gave its
    height last time); the search covers a window of half-width ``window`` around it and one of
    half-width 1 around each neighbour's foot. The feet found go to ``foot_i``, ``foot_j``.
    """
    nx, ny = z.shape
    for i in range(start, stop):
        for j in range(ny):
            best = -np.inf
            bi = i
            bj = j
            best, bi, bj = _window(z, i, j, fi0[i, j], fj0[i, j], window, t, dx, dy, periodic, best, bi, bj)
            for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                ni = i + di
                nj = j + dj
                if periodic:
                    si = fi0[ni % nx, nj % ny] + (ni - ni % nx)
                    sj = fj0[ni % nx, nj % ny] + (nj - nj % ny)
                elif 0 <= ni < nx and 0 <= nj < ny:
                    si = fi0[ni, nj]
                    sj = fj0[ni, nj]
                else:
                    continue
                # the neighbour's foot seen from here: shifted back by the neighbour's offset
                if abs(si - di - fi0[i, j]) > window or abs(sj - dj - fj0[i, j]) > window:
                    best, bi, bj = _window(z, i, j, si - di, sj - dj, 1, t, dx, dy, periodic, best, bi, bj)
            value = _refine(z, i, j, bi, bj, t, dx, dy, periodic, best) if t > 0.0 else best
            out[i, j] = max(value, previous[i, j])
            foot_i[i, j] = bi
            foot_j[i, j] = bj


@jit
def surface_moments(z, periodic):
    """Mean height and RMS of the piecewise-linear surface over its area (exact integrals), nm.

    Each cell is four triangles meeting at its centre, whose height is the mean of the corners
    (`planarize.heightfield`); the integrals of ``z`` and ``z^2`` over a triangle with corner heights
    ``a, b, c`` are ``A (a + b + c) / 3`` and ``A (a^2 + b^2 + c^2 + ab + bc + ca) / 6``.
    """
    nx, ny = z.shape
    ref = 0.0
    for i in range(nx):
        for j in range(ny):
            ref += z[i, j]
    ref /= nx * ny
    cx = nx if periodic else nx - 1
    cy = ny if periodic else ny - 1
    s1 = 0.0
    s2 = 0.0
    for i in range(cx):
        i1 = (i + 1) % nx
        for j in range(cy):
            j1 = (j + 1) % ny
            a = z[i, j] - ref
            b = z[i1, j] - ref
            c = z[i1, j1] - ref
            d = z[i, j1] - ref
            m = 0.25 * (a + b + c + d)
            s1 += (4.0 * m + 2.0 * (a + b + c + d)) / 3.0
            s2 += (4.0 * m * m + 2.0 * (a * a + b * b + c * c + d * d)
                   + 2.0 * m * (a + b + c + d) + (a * b + b * c + c * d + d * a)) / 6.0
    cells = 4.0 * cx * cy
    mean = s1 / cells
    return ref + mean, math.sqrt(max(s2 / cells - mean * mean, 0.0))


@jit(inline=True)
def _vertex(zm, z0, zp):
    """The correction to ``z0`` that puts the parabola through (-1, zm), (0, z0), (1, zp) at its vertex
    (0 if that parabola has no extremum there)."""
    curve = zm - 2.0 * z0 + zp
    if curve == 0.0:
        return 0.0
    shift = -0.5 * (zp - zm) / curve
    if abs(shift) > 0.5:
        return 0.0
    return -0.125 * (zp - zm) ** 2 / curve


@jit
def extremes(z, periodic):
    """Highest and lowest heights of the surface the grid values sample, nm: the extreme grid points,
    moved to the vertex of the parabola through each and its neighbours along x and along y (open grids
    mirrored about their edges), so that the z-range of a smooth surface does not jump with where the
    grid happens to sample its peak."""
    nx, ny = z.shape
    hi = 0
    lo = 0
    flat = z.ravel()
    for k in range(flat.size):
        if flat[k] > flat[hi]:
            hi = k
        if flat[k] < flat[lo]:
            lo = k
    out = np.empty(2)
    for slot, k in ((0, hi), (1, lo)):
        i = k // ny
        j = k % ny
        c = z[i, j]
        if nx >= 3 or periodic:
            c += _vertex(_value(z, i - 1, j, periodic), z[i, j], _value(z, i + 1, j, periodic))
        if ny >= 3 or periodic:
            c += _vertex(_value(z, i, j - 1, periodic), z[i, j], _value(z, i, j + 1, periodic))
        out[slot] = c
    return out[0], out[1]
