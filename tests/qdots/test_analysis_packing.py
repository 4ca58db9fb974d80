"""Packing figures (separation, fill within radius, size-separation correlation) against exact answers."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from qdots.analysis import (
    fill_within_radius,
    neighbour_counts,
    neighbour_edges,
    packing_summary,
    separation,
    size_separation_correlation,
)
from qdots.placement import hexagonal_lattice

R = 7.5


def board(positions, radii, box=(600.0, 600.0)):
    positions = np.asarray(positions, dtype=float)
    return SimpleNamespace(positions=positions, radii=np.broadcast_to(np.asarray(radii, float), (len(positions),)).copy(),
                           box=box)


def hexagon(rings, pitch=2 * R, centre=(300.0, 300.0)):
    """A hexagonal flake: a centre dot and ``rings`` hexagonal rings, 3 s (s + 1) + 1 dots."""
    return hexagonal_lattice(rings, pitch, "flake", centre)


@pytest.mark.parametrize("rings", [1, 2, 5, 9])
def test_hexagonal_flake_interior_fraction_is_analytic(rings):
    flake = board(hexagon(rings), R)
    n = 3 * rings * (rings + 1) + 1
    assert len(flake.positions) == n
    summary = packing_summary(flake)
    # Only the outer ring (6 s dots: corners with 3 neighbours, edges with 4) is not interior.
    assert summary["interior_fraction"] == pytest.approx((n - 6 * rings) / n, abs=1e-15)
    assert summary["mean_neighbours_interior"] == 6.0
    # Every bond is counted from both ends: 3 s (3 s + 1) bonds in a flake of s rings.
    assert summary["mean_neighbours"] == pytest.approx(2 * 3 * rings * (3 * rings + 1) / n, abs=1e-12)
    assert abs(summary["rms_excess_separation"]) < 1e-9 and abs(summary["mean_spacing"]) < 1e-9


@pytest.mark.parametrize("rule", ["text", "code"])
def test_separation_of_a_dilated_lattice(rule):
    gap = 2.0  # px between surfaces, below one mean radius: still neighbours by both rules
    flake = board(hexagon(4, pitch=2 * R + gap), R)
    for interior_only in (True, False):
        s = separation(flake, rule=rule, interior_only=interior_only)
        assert s.rms_excess == pytest.approx(gap, rel=1e-12)
        assert s.mean_gap == pytest.approx(gap, rel=1e-12)
    assert separation(flake, rule=rule).mean_neighbours == 6.0


def java_determine_packing(positions, radii, interior_only, factor):
    """The Java loops of determinePacking (factor 2) / determinePackingInterior (factor 1.5), transcribed."""
    excess = space = neighbours_total = balls = 0.0
    for i in range(len(radii)):
        count, ex, sp = 0, 0.0, 0.0
        for j in range(len(radii)):
            if i == j:
                continue
            d = float(np.hypot(*(positions[i] - positions[j])))
            if d > radii[i] + factor * radii[j]:
                continue
            count += 1
            ex += (d - radii[i] - radii[j]) ** 2
            sp += d - radii[i] - radii[j]
        if interior_only and count <= 4:
            continue
        balls += 1
        neighbours_total += count
        excess += ex
        space += sp
    return math.sqrt(excess / neighbours_total), space / neighbours_total, neighbours_total / balls, balls


def test_separation_matches_the_java_loops(rng):
    positions = rng.uniform(0, 150, (400, 2))
    radii = rng.normal(7.5, 0.8, 400)
    keep = [0]
    for k in range(1, 400):  # thin to non-overlapping dots
        d = np.hypot(*(positions[keep] - positions[k]).T)
        if np.all(d > radii[keep] + radii[k]):
            keep.append(k)
    b = board(positions[keep], radii[keep])
    s = separation(b, rule="code", interior_only=False)
    rms, mean, neighbours, balls = java_determine_packing(b.positions, b.radii, False, 2.0)
    assert (s.rms_excess, s.mean_gap, s.mean_neighbours, s.n_dots) == pytest.approx((rms, mean, neighbours, balls))
    assert len(keep) > 40


def test_fill_within_radius_one_dot_matches_the_java_self_test():
    # The Java's testDetermineFillWithinRadius: one dot of radius 7.5 at the centre.
    curve = fill_within_radius(board([[300.0, 300.0]], R), [3, 7.5, 15, 30])
    np.testing.assert_allclose(curve.fill, [1, 1, 0.25, 1 / 16], rtol=1e-14)
    assert curve.centre == (300.0, 300.0)
    np.testing.assert_array_equal(curve.overlap_bound, 0.0)


def test_fill_within_radius_lens_against_a_fine_grid():
    b = board([[300.0, 300.0], [318.0, 305.0], [280.0, 290.0], [250.0, 350.0]], [7.5, 6.0, 9.0, 8.0])
    radii = np.array([5.0, 12.0, 20.0, 40.0, 70.0])
    curve = fill_within_radius(b, radii)
    h = 0.05
    x, y = np.meshgrid(np.arange(200, 400, h) + h / 2, np.arange(200, 400, h) + h / 2)
    covered = np.zeros(x.shape, dtype=bool)
    for (cx, cy), r in zip(b.positions, b.radii):
        covered |= (x - cx) ** 2 + (y - cy) ** 2 < r * r
    rho2 = (x - 300) ** 2 + (y - 300) ** 2
    grid = [covered[rho2 < rr * rr].sum() * h * h / (math.pi * rr * rr) for rr in radii]
    np.testing.assert_allclose(curve.fill, grid, atol=2e-3)


def test_fill_overlap_bound_brackets_the_union():
    # Two dots of radius 10 at distance 10 around the centre: lens area known in closed form.
    b = board([[295.0, 300.0], [305.0, 300.0]], 10.0)
    curve = fill_within_radius(b, [40.0])
    lens = 2 * 100 * math.acos(0.5) - 0.5 * 10 * math.sqrt(400 - 100)
    union = 2 * math.pi * 100 - lens
    assert curve.fill[0] == pytest.approx(2 * math.pi * 100 / (math.pi * 1600), rel=1e-12)
    assert curve.overlap_bound[0] == pytest.approx(lens / (math.pi * 1600), rel=1e-12)
    assert curve.fill[0] - curve.overlap_bound[0] == pytest.approx(union / (math.pi * 1600), rel=1e-12)


def test_size_separation_correlation_against_numpy(rng):
    positions = rng.uniform(0, 200, (120, 2))
    radii = rng.uniform(2, 6, 120)
    b = board(positions, radii)
    i, j = np.triu_indices(120, 1)
    gap = np.hypot(*(positions[i] - positions[j]).T) - radii[i] - radii[j]
    expected = np.corrcoef(gap, np.abs(radii[i] - radii[j]))[0, 1]
    assert size_separation_correlation(b, pairs="all") == pytest.approx(expected, rel=1e-10)
    src, dst, d = neighbour_edges(b)
    once = src < dst
    gap = d[once] - radii[src[once]] - radii[dst[once]]
    expected = np.corrcoef(gap, np.abs(radii[src[once]] - radii[dst[once]]))[0, 1]
    assert size_separation_correlation(b) == pytest.approx(expected, rel=1e-10)


def test_size_separation_correlation_sign_and_degenerate_cases():
    # Pairs of unequal dots sit farther apart than pairs of equal ones: r > 0.
    pos = [[0, 0], [16, 0], [100, 0], [121, 0], [200, 0], [216, 0], [300, 0], [322, 0]]
    b = board(pos, [7.5, 7.5, 7.5, 11.0, 7.5, 7.5, 7.5, 11.5])
    assert size_separation_correlation(b) > 0.9
    assert math.isnan(size_separation_correlation(board(hexagon(2), R)))  # equal sizes: no variance
    assert math.isnan(size_separation_correlation(board([[0, 0]], R), pairs="all"))
    with pytest.raises(ValueError, match="pairs must be"):
        size_separation_correlation(b, pairs="some")


def test_bad_fill_arguments():
    b = board(hexagon(1), R)
    with pytest.raises(ValueError, match="radius must be"):
        fill_within_radius(b, [-1.0])
    with pytest.raises(ValueError, match="centre must be"):
        fill_within_radius(b, [5.0], centre=(1.0, float("nan")))


def test_neighbour_counts_unchanged_by_edges_refactor():
    # The text rule lists each pair in both directions, the code rule per viewer.
    b = board([[100, 100], [122, 100]], [10.0, 5.0])
    src, dst, d = neighbour_edges(b, rule="code")
    assert list(zip(src, dst)) == [(1, 0)] and d[0] == 22.0
    np.testing.assert_array_equal(neighbour_counts(b, rule="text"), [1, 1])
