"""The compiled kernel's slots against explicit features built point by point with `planarize.geometry`."""

import numpy as np
import pytest

from planarize.engines.features import feature_tables
from planarize.engines.kernels import pair_slots
from planarize.geometry import point_point, point_segment, point_triangle
from planarize.grid import EDGE_DIRECTIONS, QUADRANTS, Grid


def explicit_slots(grid, zm, zo, m, v, distance):
    """Every slot of the pair (m, v), built from absolute coordinates (open grid); inf where not inside."""
    def vertex(z, k, di, dj):
        i, j = divmod(k, grid.ny)
        i, j = i + di, j + dj
        if not (0 <= i < grid.nx and 0 <= j < grid.ny):
            return None
        return np.array([i * grid.dx, j * grid.dy, z[i * grid.ny + j]])

    def centre(z, k, sx, sy):
        corners = [vertex(z, k, a, b) for a, b in ((0, 0), (sx, 0), (sx, sy), (0, sy))]
        if any(c is None for c in corners):
            return None
        return np.mean(corners, axis=0)

    out = []
    pm, pv = vertex(zm, m, 0, 0), vertex(zo, v, 0, 0)
    out.append(point_point(pm, pv))
    for surface, base, query in ((zo, v, pm), (zm, m, pv)):  # slots 1-4, then 5-8
        for di, dj in EDGE_DIRECTIONS:
            b = vertex(surface, base, di, dj)
            if b is None:
                out.append(np.inf)
                continue
            d, t = point_segment(query, vertex(surface, base, 0, 0), b)
            out.append(float(d) if 0 < t < 1 else np.inf)
    if distance == "exact":
        for surface, base, query in ((zo, v, pm), (zm, m, pv)):
            a = vertex(surface, base, 0, 0)
            for sx, sy in QUADRANTS:
                c = centre(surface, base, sx, sy)
                if c is None:
                    out.append(np.inf)
                    continue
                d, t = point_segment(query, a, c)
                out.append(float(d) if 0 < t < 1 else np.inf)
            for sx, sy in QUADRANTS:
                c = centre(surface, base, sx, sy)
                for b in (vertex(surface, base, sx, 0), vertex(surface, base, 0, sy)):
                    if c is None:
                        out.append(np.inf)
                        continue
                    d, w = point_triangle(query, a, b, c)
                    out.append(float(d) if np.all(w > 0) else np.inf)
    return np.array(out)


@pytest.mark.parametrize("distance", ["thesis", "exact"])
def test_kernel_slots_are_the_explicit_features(distance, rng):
    grid = Grid((6, 7), (0.3, 0.45), periodic=False)
    zm = rng.uniform(0, 1, grid.n)
    zo = zm + rng.uniform(0, 0.6, grid.n)
    tables = feature_tables(grid, distance)
    m = rng.integers(0, grid.n, 300)
    v = rng.integers(0, grid.n, 300)
    got = pair_slots(tables, zm, zo, m, v)
    for row, (a, b) in enumerate(zip(m, v)):
        want = explicit_slots(grid, zm, zo, a, b, distance)
        finite = np.isfinite(want)
        np.testing.assert_array_equal(np.isfinite(got[row]), finite)
        np.testing.assert_allclose(got[row][finite], want[finite], rtol=1e-12, atol=1e-12)


def test_periodic_kernel_uses_the_nearest_image(rng):
    """A periodic grid's features seen across the seam equal those of an open grid shifted so they do not wrap."""
    nx, ny = 6, 5
    zm = rng.uniform(0, 1, (nx, ny))
    zo = zm + rng.uniform(0, 0.5, (nx, ny))
    tables = feature_tables(Grid((nx, ny), (0.3, 0.3), True), "exact")
    # metal point at the last row, anchor at row 0: across the seam, one dx apart
    m = np.array([(nx - 1) * ny + 2])
    v = np.array([0 * ny + 2])
    got = pair_slots(tables, zm.ravel(), zo.ravel(), m, v)
    # the same neighbourhood, rolled so that both sit inside an open grid
    shift = 3
    want = pair_slots(tables, np.roll(zm, shift, 0).ravel(), np.roll(zo, shift, 0).ravel(),
                      m - (nx - shift) * ny, v + shift * ny)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert got[0, 0] == pytest.approx(np.sqrt(0.3**2 + (zo[0, 2] - zm[-1, 2]) ** 2))
