"""The feature kernel compiled with numba: `closest_sets` without numpy's per-call overhead.

`planarize.engines.features.closest_sets` evaluates every feature pair with some
thirty numpy calls on temporary arrays; here one compiled loop does the same
arithmetic pair by pair, in the same order of operations, so the distances
are the same to the last bit (tests/test_planarize_compiled.py checks this
against the numpy kernel on random surfaces, open and periodic, with both
distance kinds). The fast engine uses it when numba is installed (the
``fast`` extra); the reference engine always uses the numpy kernel, so that
it stays the thesis algorithm in plain numpy.

numba is optional: without it `AVAILABLE` is False and the fast engine runs
on the numpy kernel, with the same results, several times slower.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..geometry import triangle_frame

try:
    import numba
except ImportError:  # pragma: no cover - exercised only where numba is absent
    numba = None

#: True when numba is installed and the compiled kernel can be used.
AVAILABLE = numba is not None

_TINY = float(np.finfo(float).tiny)
_INF = math.inf


def _jit(function=None, *, inline: bool = False):
    # error_model="numpy": a division by zero gives inf/nan as in numpy, not an exception; inline: for small
    # helpers called per pair with many array arguments, where a call costs more than the work
    if function is None:
        return functools.partial(_jit, inline=inline)
    if numba is None:  # pragma: no cover
        return function
    return numba.njit(cache=True, nogil=True, error_model="numpy", inline="always" if inline else "never")(function)


_triangle_frame = _jit(triangle_frame)


@_jit
def _foot(px, py, pz, ax, ay, az, bx, by, bz):
    """`planarize.geometry.segment_foot_xyz` for one point, as the features use it: the distance when
    the foot is strictly inside the segment, else inf."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    length2 = ux * ux + uy * uy + uz * uz
    along = wx * ux + wy * uy + wz * uz
    # computed whether or not the foot is inside, then chosen: a branch per pair mispredicts often
    t = along / length2
    inside = (0 < along) & (along < length2) & (0 < t) & (t < 1)
    value = math.sqrt(max(wx * wx + wy * wy + wz * wz - t * along, 0.0))
    return value if inside else _INF


@_jit(inline=True)
def _nearest_image(di, dj, nx, ny, periodic):
    """Grid offsets ``di, dj`` (each within the grid's size) of the nearest periodic image:
    ``di - nx * floor((di + nx // 2) / nx)`` as `Grid.offsets` has it, without a division."""
    if periodic:
        if di + nx // 2 >= nx:
            di -= nx
        elif di + nx // 2 < 0:
            di += nx
        if dj + ny // 2 >= ny:
            dj -= ny
        elif dj + ny // 2 < 0:
            dj += ny
    return di, dj


@_jit(inline=True)
def _own_segments(seg, zm, m, dx, dy, edge_nb, step_i, step_j):
    """The 4 grid segments at metal point ``m``, relative to it, as `_segments` orients them: row ``e`` of
    ``seg`` holds the start, direction and squared length (or a negative length: no segment there). They are
    the same for every anchor paired with ``m``, so they are set up once per metal point."""
    zref = zm[m]
    for e in range(4):
        u = edge_nb[m, e]
        if u < 0:
            seg[e, 6] = -1.0
            continue
        tx, ty, tz = step_i[e] * dx, step_j[e] * dy, zm[u] - zref
        if step_i[e] + step_j[e] > 0:  # from m to u
            ax, ay, az, bx, by, bz = 0.0, 0.0, 0.0, tx, ty, tz
        else:
            ax, ay, az, bx, by, bz = tx, ty, tz, 0.0, 0.0, 0.0
        ux, uy, uz = bx - ax, by - ay, bz - az
        seg[e, 0], seg[e, 1], seg[e, 2], seg[e, 3], seg[e, 4], seg[e, 5] = ax, ay, az, ux, uy, uz
        seg[e, 6] = ux * ux + uy * uy + uz * uz


@_jit(inline=True)
def _own_feet(out, r, first, px, py, pz, seg):
    """Slots ``out[r, first .. first + 3]``: `_foot` of point p on the 4 segments set up by `_own_segments`."""
    for e in range(4):
        length2 = seg[e, 6]
        if length2 < 0:
            out[r, first + e] = _INF
            continue
        ux, uy, uz = seg[e, 3], seg[e, 4], seg[e, 5]
        wx, wy, wz = px - seg[e, 0], py - seg[e, 1], pz - seg[e, 2]
        along = wx * ux + wy * uy + wz * uz
        t = along / length2  # as in `_foot`: computed, then chosen
        inside = (0 < along) & (along < length2) & (0 < t) & (t < 1)
        value = math.sqrt(max(wx * wx + wy * wy + wz * wz - t * along, 0.0))
        out[r, first + e] = value if inside else _INF


@_jit
def _segment(px, py, pz, ax, ay, az, bx, by, bz):
    """`planarize.geometry.point_segment_xyz` for one point: (distance, t)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    length2 = ux * ux + uy * uy + uz * uz
    along = wx * ux + wy * uy + wz * uz
    t = along / length2 if length2 > 0 else 0.0
    t = min(max(t, 0.0), 1.0)
    dx, dy, dz = wx - t * ux, wy - t * uy, wz - t * uz
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@_jit
def _inside_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """`planarize.geometry.point_triangle_xyz` for one point, as the features use it: the distance
    when the closest point is strictly inside the triangle, else inf."""
    d_ab = _segment(px, py, pz, ax, ay, az, bx, by, bz)
    d_bc = _segment(px, py, pz, bx, by, bz, cx, cy, cz)
    d_ca = _segment(px, py, pz, cx, cy, cz, ax, ay, az)
    distance = min(d_ab, d_bc, d_ca)  # the closest point is on an edge: a weight is 0
    ux, uy, uz, vx, vy, vz, wx, wy, wz, d00, d01, d11, d20, d21, det = _triangle_frame(
        px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    if not det > 1e-12 * max(d00 * d11, _TINY):
        return _INF
    fb = (d11 * d20 - d01 * d21) / det
    fc = (d00 * d21 - d01 * d20) / det
    fa = 1.0 - fb - fc
    if not (fa > 0 and fb > 0 and fc > 0):
        return _INF
    ex, ey, ez = wx - fb * ux - fc * vx, wy - fb * uy - fc * vy, wz - fb * uz - fc * vz
    face = math.sqrt(ex * ex + ey * ey + ez * ez)
    return face if face < distance else _INF


@_jit(inline=True)
def _segments(out, r, first, px, py, pz, z, k, di, dj, zref, dx, dy, edge_nb, step_i, step_j):
    """Slots ``out[r, first .. first + 3]``: the 4 grid segments at point ``k`` (offset ``di, dj``), seen from p."""
    hx, hy, hz = di * dx, dj * dy, z[k] - zref
    for e in range(4):
        u = edge_nb[k, e]
        if u < 0:
            out[r, first + e] = _INF
            continue
        tx, ty, tz = (di + step_i[e]) * dx, (dj + step_j[e]) * dy, z[u] - zref
        if step_i[e] + step_j[e] > 0:  # always from the -x/-y end to the +x/+y end
            out[r, first + e] = _foot(px, py, pz, hx, hy, hz, tx, ty, tz)
        else:
            out[r, first + e] = _foot(px, py, pz, tx, ty, tz, hx, hy, hz)


@_jit
def _facets(out, r, first, px, py, pz, z, k, di, dj, zref, dx, dy, quad_cell, quad_corners, cell_corners,
            quad_i, quad_j, centre_i, centre_j):
    """Slots ``out[r, first .. first + 11]``: half-diagonals, then two triangles per quadrant, at point ``k``."""
    hx, hy, hz = di * dx, dj * dy, z[k] - zref
    for q in range(4):
        cell = quad_cell[k, q]
        if cell < 0:
            out[r, first + q] = _INF
            out[r, first + 4 + 2 * q] = _INF
            out[r, first + 5 + 2 * q] = _INF
            continue
        c = cell_corners[cell]
        zc = 0.25 * (((z[c[0]] + z[c[1]]) + z[c[2]]) + z[c[3]])
        cx, cy, cz = (di + centre_i[q]) * dx, (dj + centre_j[q]) * dy, zc - zref
        out[r, first + q] = _foot(px, py, pz, hx, hy, hz, cx, cy, cz)
        for side in range(2):
            si = quad_i[q] if side == 0 else 0
            sj = 0 if side == 0 else quad_j[q]
            w = quad_corners[k, q, 0 if side == 0 else 2]
            tx, ty, tz = (di + si) * dx, (dj + sj) * dy, z[w] - zref
            if si + sj > 0:
                d = _inside_triangle(px, py, pz, hx, hy, hz, tx, ty, tz, cx, cy, cz)
            else:
                d = _inside_triangle(px, py, pz, tx, ty, tz, hx, hy, hz, cx, cy, cz)
            out[r, first + 4 + side + 2 * q] = d


@_jit(inline=True)
def _pair_slots(out, r, zm, zo, m, v, do_oxide, do_metal, exact, nx, ny, periodic, dx, dy, edge_nb, quad_cell,
                quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j, own, mi, mj):
    """`FeatureKernel.distances` of one (metal ``m`` at row ``mi``, column ``mj``, anchor ``v``) pair, into row
    ``r`` of ``out`` (filled with inf). (Rows are passed as (array, index), not as views: a view per pair costs
    more than the pair.)"""
    vi = v // ny
    di, dj = _nearest_image(vi - mi, v - vi * ny - mj, nx, ny, periodic)
    zref = zm[m]
    vx, vy, vz = di * dx, dj * dy, zo[v] - zref
    if do_oxide:
        out[r, 0] = math.sqrt(vx * vx + vy * vy + vz * vz)
        _segments(out, r, 1, 0.0, 0.0, 0.0, zo, v, di, dj, zref, dx, dy, edge_nb, step_i, step_j)
        if exact:
            _facets(out, r, 9, 0.0, 0.0, 0.0, zo, v, di, dj, zref, dx, dy, quad_cell, quad_corners, cell_corners,
                    quad_i, quad_j, centre_i, centre_j)
    if do_metal:
        _own_feet(out, r, 5, vx, vy, vz, own)  # = _segments(out, r, 5, vx, vy, vz, zm, m, 0, 0, zref, ...)
        if exact:
            _facets(out, r, 21, vx, vy, vz, zm, m, 0, 0, zref, dx, dy, quad_cell, quad_corners, cell_corners,
                    quad_i, quad_j, centre_i, centre_j)


@_jit
def _set_of(slot, v, edge_nb, quad_corners, into, count):
    """Append the oxide points of slot ``slot`` at anchor ``v`` (`FeatureKernel.oxide_sets`) to ``into``;
    past an open edge there are none (a slot that does not apply can be asked for when all are inf)."""
    into[count] = v
    count += 1
    if 1 <= slot <= 4:
        u = edge_nb[v, slot - 1]
        if u >= 0:
            into[count] = u
            count += 1
    elif 9 <= slot <= 20:
        q = slot - 9 if slot < 13 else (slot - 13) // 2
        for c in range(3):
            u = quad_corners[v, q, c]
            if u >= 0:
                into[count] = u
                count += 1
    return count


@_jit
def _sort_unique(values, count):
    """Sort ``values[:count]`` in place (insertion sort: a set has a few points) and drop repeats;
    return the new count."""
    for a in range(1, count):
        x = values[a]
        b = a - 1
        while b >= 0 and values[b] > x:
            values[b + 1] = values[b]
            b -= 1
        values[b + 1] = x
    kept = min(count, 1)
    for a in range(1, count):
        if values[a] != values[kept - 1]:
            values[kept] = values[a]
            kept += 1
    return kept


@_jit(inline=True)
def _closest_sets(zm, zo, m, v, tie, do_oxide, do_metal, n_slots, exact, nx, ny, periodic, dx, dy, edge_nb, quad_cell,
                  quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j):
    n_pairs = len(m)
    n_groups = 0
    for r in range(n_pairs):
        if r == 0 or m[r] != m[r - 1]:
            n_groups += 1
    points = np.empty(n_groups, dtype=np.intp)
    best = np.empty(n_groups)
    owner = np.empty(4 * n_groups, dtype=np.intp)
    oxide = np.empty(4 * n_groups, dtype=np.intp)
    found = np.empty(64, dtype=np.intp)
    dist = np.empty((16, n_slots))  # one group's pairs at a time: stays in cache
    own = np.empty((4, 7))
    n_out = 0
    start = 0
    for g in range(n_groups):
        stop = start + 1
        while stop < n_pairs and m[stop] == m[start]:
            stop += 1
        if stop - start > len(dist):
            dist = np.empty((2 * (stop - start), n_slots))
        _own_segments(own, zm, m[start], dx, dy, edge_nb, step_i, step_j)
        mi = m[start] // ny
        mj = m[start] - mi * ny
        low = _INF
        for r in range(start, stop):
            row = r - start
            dist[row, :] = _INF
            _pair_slots(dist, row, zm, zo, m[r], v[r], do_oxide[r], do_metal[r], exact, nx, ny, periodic, dx, dy,
                        edge_nb, quad_cell, quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i,
                        centre_j, own, mi, mj)
            for s in range(n_slots):
                low = min(low, dist[row, s])
        points[g] = m[start]
        best[g] = low
        count = 0
        for r in range(start, stop):
            for s in range(n_slots):
                if dist[r - start, s] <= low + tie:
                    if count + 4 > len(found):
                        found = np.concatenate((found, np.empty_like(found)))
                    count = _set_of(s, v[r], edge_nb, quad_corners, found, count)
        count = _sort_unique(found, count)
        if n_out + count > len(owner):
            grow = max(len(owner), count)
            owner = np.concatenate((owner, np.empty(grow, dtype=np.intp)))
            oxide = np.concatenate((oxide, np.empty(grow, dtype=np.intp)))
        for c in range(count):
            owner[n_out] = g
            oxide[n_out] = found[c]
            n_out += 1
        start = stop
    return points, best, owner[:n_out], oxide[:n_out]


# one compiled kernel per distance kind: with ``exact`` a constant, the thesis kind carries no facet code
@_jit
def _closest_sets_thesis(zm, zo, m, v, tie, do_oxide, do_metal, nx, ny, periodic, dx, dy, edge_nb, quad_cell,
                         quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j):
    return _closest_sets(zm, zo, m, v, tie, do_oxide, do_metal, 9, False, nx, ny, periodic, dx, dy, edge_nb,
                         quad_cell, quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j)


@_jit
def _closest_sets_exact(zm, zo, m, v, tie, do_oxide, do_metal, nx, ny, periodic, dx, dy, edge_nb, quad_cell,
                        quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j):
    return _closest_sets(zm, zo, m, v, tie, do_oxide, do_metal, 33, True, nx, ny, periodic, dx, dy, edge_nb,
                         quad_cell, quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j)


def closest_sets(kernel, zm, zo, m, v, tie: float, oxide=None, metal=None):
    """`planarize.engines.features.closest_sets`, compiled: same arguments, same results bit for bit."""
    m, v = np.asarray(m, dtype=np.intp), np.asarray(v, dtype=np.intp)
    every = np.ones(len(m), dtype=bool)
    oxide = every if oxide is None else np.asarray(oxide, dtype=bool)
    metal = every if metal is None else np.asarray(metal, dtype=bool)
    if len(m) > 1 and np.any(m[1:] < m[:-1]):
        order = np.argsort(m, kind="stable")
        m, v, oxide, metal = m[order], v[order], oxide[order], metal[order]
    g = kernel.grid
    closest = _closest_sets_exact if kernel.n_slots > 9 else _closest_sets_thesis
    return closest(zm, zo, m, v, float(tie), oxide, metal, g.nx, g.ny, g.periodic, g.dx,
                         g.dy, g.edge_neighbours, g.quadrant_cell, g.quadrant_corners, g.cell_corners,
                         kernel._step_i, kernel._step_j, kernel._quad_i, kernel._quad_j, kernel._centre_i,
                         kernel._centre_j)


@_jit
def _star(z, k, exact, edge_nb, edge2, quad_cell, cell_corners, half2):
    zk = z[k]
    reach2 = -_INF
    for e in range(4):
        u = edge_nb[k, e]
        if u >= 0:
            dz = z[u] - zk
            reach2 = max(reach2, edge2[e] + dz * dz)
    if exact:
        for q in range(4):
            cell = quad_cell[k, q]
            if cell >= 0:
                c = cell_corners[cell]
                dz = 0.25 * (((z[c[0]] + z[c[1]]) + z[c[2]]) + z[c[3]]) - zk
                reach2 = max(reach2, half2[q] + dz * dz)
    return math.sqrt(reach2)


@_jit
def _star_reach(z, points, exact, edge_nb, edge2, quad_cell, cell_corners, half2):
    reach = np.empty(len(points))
    for a in range(len(points)):
        reach[a] = _star(z, points[a], exact, edge_nb, edge2, quad_cell, cell_corners, half2)
    return reach


def star_reach(kernel, z, points) -> np.ndarray:
    """`FeatureKernel.star_reach` of the surface ``z`` at ``points``, compiled: same values bit for bit."""
    g = kernel.grid
    return _star_reach(z, np.asarray(points, dtype=np.intp), kernel.distance == "exact", g.edge_neighbours,
                       kernel._edge_x ** 2 + kernel._edge_y ** 2, g.quadrant_cell, g.cell_corners,
                       kernel._half_x ** 2 + kernel._half_y ** 2)
