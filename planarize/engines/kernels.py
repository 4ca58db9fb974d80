"""The compiled feature kernel: each metal point's distance to the oxide and its oxide set, pair by pair.

`closest_sets` evaluates every feature pair (`planarize.engines.features`, the slot layout) of a
list of (metal point, anchor oxide point) pairs with the geometry of `planarize.geometry`, keeps
each metal point's smallest distance and collects the oxide points of every pair within ``tie`` of
it. Everything is seen from the metal point, at the origin; every vertex is placed from its integer
grid offset and its own height, and every feature is evaluated in one fixed vertex order, so a
feature reached from any of its grid points gives the same distance, bit for bit. Both engines use
it: the reference engine over its windows, the fast engine over its ball searches.

`star_reach` (how far a point's features reach) and `search_radii` (how far a candidate search
must look) are the bounds the engines' searches rest on.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

from ..geometry import segment_foot_inside, triangle
from .features import (
    EXACT_SLOTS,
    METAL_HALF_DIAGONALS,
    METAL_SEGMENTS,
    OXIDE_HALF_DIAGONALS,
    OXIDE_SEGMENTS,
    OXIDE_TRIANGLES,
    POINT,
    THESIS_SLOTS,
    FeatureTables,
)

_INF = math.inf


@jit(inline=True)
def nearest_image(di, dj, nx, ny, periodic):
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


@jit(inline=True)
def _grid_segments(seg, z, k, di, dj, zref, dx, dy, edge_nb, step_i, step_j):
    """The 4 grid segments at point ``k`` (offset ``di, dj``, heights ``z`` less ``zref``), each from its
    -x/-y end to its +x/+y end: row ``e`` of ``seg`` holds the start, direction and squared length (or a
    negative length: no segment there, past an open edge). A metal point's own segments (``di = dj = 0``,
    ``zref`` its height) are the same for every anchor paired with it, so they are set up once per point.
    (The per-pair helpers take `FeatureTables`' arrays one by one: a tuple of arrays handed to them costs a
    reference count per array per pair, 1.5 times the kernel's time.)"""
    hx, hy, hz = di * dx, dj * dy, z[k] - zref
    for e in range(4):
        u = edge_nb[k, e]
        if u < 0:
            seg[e, 6] = -1.0
            continue
        tx, ty, tz = (di + step_i[e]) * dx, (dj + step_j[e]) * dy, z[u] - zref
        if step_i[e] + step_j[e] > 0:  # from k to u
            ax, ay, az, bx, by, bz = hx, hy, hz, tx, ty, tz
        else:
            ax, ay, az, bx, by, bz = tx, ty, tz, hx, hy, hz
        ux, uy, uz = bx - ax, by - ay, bz - az
        seg[e, 0], seg[e, 1], seg[e, 2], seg[e, 3], seg[e, 4], seg[e, 5] = ax, ay, az, ux, uy, uz
        seg[e, 6] = ux * ux + uy * uy + uz * uz


@jit(inline=True)
def _segment_feet(out, r, first, px, py, pz, seg):
    """Slots ``out[r, first .. first + 3]``: `segment_foot_inside` of point p on the 4 segments set up by
    `_grid_segments` (the same arithmetic, on the kept start and direction)."""
    for e in range(4):
        length2 = seg[e, 6]
        if length2 < 0:
            out[r, first + e] = _INF
            continue
        ux, uy, uz = seg[e, 3], seg[e, 4], seg[e, 5]
        wx, wy, wz = px - seg[e, 0], py - seg[e, 1], pz - seg[e, 2]
        along = wx * ux + wy * uy + wz * uz
        t = along / length2  # as in segment_foot_inside: computed, then chosen
        inside = (0 < along) & (along < length2) & (0 < t) & (t < 1)
        value = math.sqrt(max(wx * wx + wy * wy + wz * wz - t * along, 0.0))
        out[r, first + e] = value if inside else _INF


@jit(inline=True)
def _anchor_feet(out, r, first, z, k, di, dj, zref, dx, dy, edge_nb, step_i, step_j):
    """Slots ``out[r, first .. first + 3]``: `segment_foot_inside` of the origin (the metal point) on the 4 grid
    segments at point ``k`` (offset ``di, dj``, heights ``z`` less ``zref``), each from its -x/-y end to its
    +x/+y end, as `_grid_segments` sets them up (the same arithmetic, without the round trip through memory:
    they are used once)."""
    hx, hy, hz = di * dx, dj * dy, z[k] - zref
    for e in range(4):
        u = edge_nb[k, e]
        if u < 0:
            out[r, first + e] = _INF
            continue
        tx, ty, tz = (di + step_i[e]) * dx, (dj + step_j[e]) * dy, z[u] - zref
        if step_i[e] + step_j[e] > 0:
            out[r, first + e] = segment_foot_inside(0.0, 0.0, 0.0, hx, hy, hz, tx, ty, tz)
        else:
            out[r, first + e] = segment_foot_inside(0.0, 0.0, 0.0, tx, ty, tz, hx, hy, hz)


@jit(inline=True)
def _inside_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """The distance from p to the triangle abc when its closest point lies strictly inside it, else inf."""
    d, wa, wb, wc = triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    return d if (wa > 0 and wb > 0 and wc > 0) else _INF


@jit
def _facets(out, r, first, px, py, pz, z, k, di, dj, zref, dx, dy, quad_cell, quad_corners, cell_corners, quad_i,
            quad_j, centre_i, centre_j):
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
        out[r, first + q] = segment_foot_inside(px, py, pz, hx, hy, hz, cx, cy, cz)
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


@jit(inline=True)
def _pair_slots(out, r, zm, zo, m, v, do_oxide, do_metal, exact, nx, ny, periodic, dx, dy, edge_nb, quad_cell,
                quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j, own, mi, mj):
    """Every slot of one (metal ``m`` at row ``mi``, column ``mj``, anchor ``v``) pair, into row ``r`` of
    ``out`` (filled with inf); ``nx`` .. ``centre_j`` are `FeatureTables`' fields, ``own`` holds the metal
    point's segments (`_grid_segments`). (Rows are passed as (array, index), not as views: a view per pair
    costs more than the pair.)"""
    vi = v // ny
    di, dj = nearest_image(vi - mi, v - vi * ny - mj, nx, ny, periodic)
    zref = zm[m]
    vx, vy, vz = di * dx, dj * dy, zo[v] - zref
    if do_oxide:
        out[r, POINT] = math.sqrt(vx * vx + vy * vy + vz * vz)
        _anchor_feet(out, r, OXIDE_SEGMENTS, zo, v, di, dj, zref, dx, dy, edge_nb, step_i, step_j)
        if exact:
            _facets(out, r, OXIDE_HALF_DIAGONALS, 0.0, 0.0, 0.0, zo, v, di, dj, zref, dx, dy, quad_cell, quad_corners,
                    cell_corners, quad_i, quad_j, centre_i, centre_j)
    if do_metal:
        _segment_feet(out, r, METAL_SEGMENTS, vx, vy, vz, own)
        if exact:
            _facets(out, r, METAL_HALF_DIAGONALS, vx, vy, vz, zm, m, 0, 0, zref, dx, dy, quad_cell, quad_corners,
                    cell_corners, quad_i, quad_j, centre_i, centre_j)


@jit
def _set_of(slot, v, edge_nb, quad_corners, into, count):
    """Append the oxide points of slot ``slot`` at anchor ``v`` to ``into``: the anchor, and a segment's other
    end or a cell's other three corners; past an open edge there are none (a slot that does not apply can be
    asked for when all are inf)."""
    into[count] = v
    count += 1
    if OXIDE_SEGMENTS <= slot < METAL_SEGMENTS:
        u = edge_nb[v, slot - OXIDE_SEGMENTS]
        if u >= 0:
            into[count] = u
            count += 1
    elif OXIDE_HALF_DIAGONALS <= slot < METAL_HALF_DIAGONALS:
        q = slot - OXIDE_HALF_DIAGONALS if slot < OXIDE_TRIANGLES else (slot - OXIDE_TRIANGLES) // 2
        for c in range(3):
            u = quad_corners[v, q, c]
            if u >= 0:
                into[count] = u
                count += 1
    return count


@jit
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


@jit(inline=True)
def _closest_sets(zm, zo, m, v, tie, do_oxide, do_metal, n_slots, exact, t):
    nx, ny, periodic, dx, dy = t.nx, t.ny, t.periodic, t.dx, t.dy
    edge_nb, quad_cell, quad_corners, cell_corners = t.edge_nb, t.quad_cell, t.quad_corners, t.cell_corners
    step_i, step_j, quad_i, quad_j, centre_i, centre_j = t.step_i, t.step_j, t.quad_i, t.quad_j, t.centre_i, t.centre_j
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
        _grid_segments(own, zm, m[start], 0, 0, zm[m[start]], dx, dy, edge_nb, step_i, step_j)
        mi = m[start] // ny
        mj = m[start] - mi * ny
        low = _INF
        for r in range(start, stop):
            row = r - start
            dist[row, :] = _INF
            _pair_slots(dist, row, zm, zo, m[r], v[r], do_oxide[r], do_metal[r], exact, nx, ny, periodic, dx, dy, edge_nb,
                        quad_cell, quad_corners, cell_corners, step_i, step_j, quad_i, quad_j, centre_i, centre_j, own,
                        mi, mj)
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
@jit
def _closest_sets_thesis(zm, zo, m, v, tie, do_oxide, do_metal, t):
    return _closest_sets(zm, zo, m, v, tie, do_oxide, do_metal, THESIS_SLOTS, False, t)


@jit
def _closest_sets_exact(zm, zo, m, v, tie, do_oxide, do_metal, t):
    return _closest_sets(zm, zo, m, v, tie, do_oxide, do_metal, EXACT_SLOTS, True, t)


def _pairs(m, v, oxide, metal):
    """The (metal, anchor) pairs as int arrays sorted by metal point (stable), with their slot masks."""
    m, v = np.asarray(m, dtype=np.intp), np.asarray(v, dtype=np.intp)
    every = np.ones(len(m), dtype=bool)
    oxide = every if oxide is None else np.asarray(oxide, dtype=bool)
    metal = every if metal is None else np.asarray(metal, dtype=bool)
    if len(m) > 1 and np.any(m[1:] < m[:-1]):
        order = np.argsort(m, kind="stable")
        m, v, oxide, metal = m[order], v[order], oxide[order], metal[order]
    return m, v, oxide, metal


def closest_sets(tables: FeatureTables, zm, zo, m, v, tie: float, oxide=None, metal=None):
    """Smallest pair distance of each metal point, and the oxide points it belongs to.

    Parameters
    ----------
    tables : FeatureTables
    zm, zo : ndarray, shape (n,)
        Flat metal and oxide heights, nm.
    m, v : ndarray of int, shape (P,)
        (metal point, anchor oxide point) candidate pairs; every metal point that appears gets an
        answer from its own pairs only.
    tie : float
        Pairs within ``tie`` nm of a point's smallest distance count as equally close (their oxide
        points are all in its set).
    oxide, metal : ndarray of bool, shape (P,), optional
        Evaluate only for these pairs the slots of the oxide features at the anchor, resp. of the
        metal features at ``m``; default all pairs.

    Returns
    -------
    points : ndarray of int, shape (M,)
        The distinct metal points of ``m``, sorted.
    distance : ndarray, shape (M,)
        Their smallest distance, nm.
    owner, oxide : ndarray of int, shape (K,)
        The sets as unique (index into ``points``, oxide point) pairs, sorted.
    """
    m, v, oxide, metal = _pairs(m, v, oxide, metal)
    closest = _closest_sets_exact if tables.exact else _closest_sets_thesis
    return closest(zm, zo, m, v, float(tie), oxide, metal, tables)


@jit
def _all_slots(zm, zo, m, v, oxide, metal, t, out):
    own = np.empty((4, 7))
    for r in range(len(m)):
        _grid_segments(own, zm, m[r], 0, 0, zm[m[r]], t.dx, t.dy, t.edge_nb, t.step_i, t.step_j)
        mi = m[r] // t.ny
        _pair_slots(out, r, zm, zo, m[r], v[r], oxide[r], metal[r], t.exact, t.nx, t.ny, t.periodic, t.dx, t.dy,
                    t.edge_nb, t.quad_cell, t.quad_corners, t.cell_corners, t.step_i, t.step_j, t.quad_i, t.quad_j,
                    t.centre_i, t.centre_j, own, mi, m[r] - mi * t.ny)


def pair_slots(tables: FeatureTables, zm, zo, m, v, oxide=None, metal=None) -> np.ndarray:
    """Every slot of each (metal ``m``, anchor ``v``) pair, shape (P, n_slots), nm; inf where a slot does not
    apply (no neighbour past an open edge, the closest point is not inside the feature, or not asked for).
    What `closest_sets` takes the smallest of, for inspection and tests."""
    m, v = np.asarray(m, dtype=np.intp), np.asarray(v, dtype=np.intp)
    every = np.ones(len(m), dtype=bool)
    oxide = every if oxide is None else np.asarray(oxide, dtype=bool)
    metal = every if metal is None else np.asarray(metal, dtype=bool)
    out = np.full((len(m), tables.n_slots), np.inf)
    _all_slots(zm, zo, m, v, oxide, metal, tables, out)
    return out


@jit(inline=True)
def star(z, k, t):
    """How far the features touching grid point ``k`` reach from it, nm: the far end of its longest edge."""
    zk = z[k]
    reach2 = -_INF
    for e in range(4):
        u = t.edge_nb[k, e]
        if u >= 0:
            dz = z[u] - zk
            reach2 = max(reach2, t.edge2[e] + dz * dz)
    if t.exact:
        for q in range(4):
            cell = t.quad_cell[k, q]
            if cell >= 0:
                c = t.cell_corners[cell]
                dz = 0.25 * (((z[c[0]] + z[c[1]]) + z[c[2]]) + z[c[3]]) - zk
                reach2 = max(reach2, t.half2[q] + dz * dz)
    return math.sqrt(reach2)


@jit
def _star_reach(z, points, t):
    reach = np.empty(len(points))
    for a in range(len(points)):
        reach[a] = star(z, points[a], t)
    return reach


def star_reach(tables: FeatureTables, z, points=None) -> np.ndarray:
    """For each of ``points`` (default every grid point), the distance to the far end of its longest
    feature edge, nm: every point of a feature touching it (segment, and with exact distances
    half-diagonal or triangle) lies within this distance of it."""
    points = np.arange(tables.nx * tables.ny) if points is None else np.asarray(points, dtype=np.intp)
    return _star_reach(np.asarray(z, dtype=float), points, tables)


def max_feature_length(tables: FeatureTables, z) -> float:
    """Longest feature edge of the surface ``z`` (flat), nm."""
    return float(star_reach(tables, z).max())


@jit
def _search_radii(zm, points, bound, oxide_reach, tie, t):
    inflate = 1 + 1e-12
    r_ox = np.empty(len(points))
    r_me = np.empty(len(points))
    for a in range(len(points)):
        reach = star(zm, points[a], t)
        r_ox[a] = math.sqrt(bound[a] * bound[a] + oxide_reach * oxide_reach) * inflate + tie
        r_me[a] = math.sqrt(bound[a] * bound[a] + reach * reach) * inflate + tie
    return r_ox, r_me


def search_radii(tables: FeatureTables, zm, points, bound, oxide_reach: float, tie: float):
    """Search radii (oxide features, metal features) around metal points ``points`` for the features that can
    be closer than ``bound[i]`` to them, nm.

    An oxide feature closer than ``B`` to metal point ``m`` has a grid point within ``sqrt(B^2 + R^2)`` of
    ``m``, ``R`` = ``oxide_reach`` (`planarize.engines.features.oxide_reach`); a metal feature at ``m``
    closer than ``B`` to an oxide point lies within ``sqrt(B^2 + S^2)`` of it, ``S`` = the star reach of
    ``m``. (When the closest point ``q`` is a perpendicular foot, ``|m - a|^2 = d^2 + |q - a|^2`` for
    every grid point ``a`` of the feature.) Both are inflated by round-off and ``tie``.
    """
    return _search_radii(zm, np.asarray(points, dtype=np.intp), np.asarray(bound, dtype=float), float(oxide_reach),
                         float(tie), tables)


@jit
def _within(which, gap, r_ox, r_me):
    oxide = np.empty(len(which), dtype=np.bool_)
    metal = np.empty(len(which), dtype=np.bool_)
    for a in range(len(which)):
        oxide[a] = gap[a] <= r_ox[which[a]]
        metal[a] = gap[a] <= r_me[which[a]]
    return oxide, metal


def within(which, gap, r_ox, r_me):
    """For search results (query ``which``, distance ``gap``): within the query's oxide radius ``r_ox``,
    and within its metal radius ``r_me`` (two boolean arrays)."""
    return _within(which, gap, r_ox, r_me)
