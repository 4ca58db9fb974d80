"""Hexatic order, g(r), clusters and Voronoi coordination: exact lattices and freud as an oracle."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from qdots.analysis import neighbour_counts, neighbour_edges
from qdots.analysis.structure import clusters, hexatic_order, radial_distribution, voronoi_coordination
from qdots.placement import hexagonal_lattice, random_sequential

freud = pytest.importorskip("freud")

R = 7.5


def board(positions, radii=R, box=(600.0, 600.0)):
    positions = np.asarray(positions, dtype=float)
    return SimpleNamespace(positions=positions, radii=np.full(len(positions), float(radii)), box=box)


def hex_lattice(m, pitch=2 * R, angle=0.0, origin=(60.0, 60.0)):
    xy = hexagonal_lattice(m, pitch)
    c, s = math.cos(angle), math.sin(angle)
    return xy @ np.array([[c, s], [-s, c]]) + origin


def square_lattice(m, pitch, origin=(60.0, 60.0)):
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    return np.column_stack([pitch * i.ravel(), pitch * j.ravel()]) + origin


def settled_like_board(seed=3, n=400):
    """Equal dots at random (RSA, area fraction 0.44): irregular, many near-contacts."""
    positions, radii = random_sequential(n, (400.0, 400.0), sigma=0.0, rng=seed)
    return SimpleNamespace(positions=positions, radii=radii, box=(400.0, 400.0))


def freud_system(b, pad=400.0):
    """The board in a freud box large enough that no pair wraps around."""
    pts = np.zeros((len(b.positions), 3))
    pts[:, :2] = b.positions - np.asarray(b.box) / 2
    return freud.box.Box.square(max(b.box) + 2 * pad), pts


# --------------------------------------------------------------------------- exact lattices


@pytest.mark.parametrize("angle", [0.0, 0.3, 1.1])
def test_hexagonal_lattice_psi6_is_one(angle):
    b = board(hex_lattice(10, angle=angle, origin=(300, 150)))
    h = hexatic_order(b)
    assert h.has_neighbours.all()
    np.testing.assert_allclose(np.abs(h.psi), 1.0, atol=1e-12)  # edge dots too: all bonds on the hexagon
    np.testing.assert_allclose(h.psi, np.exp(6j * angle), atol=1e-12)
    assert h.global_order == pytest.approx(1.0, abs=1e-12) and h.local_order == pytest.approx(1.0, abs=1e-12)


def test_hexagonal_lattice_counts_and_voronoi():
    m = 10
    b = board(hex_lattice(m))
    counts = neighbour_counts(b)
    inner = np.zeros((m, m), dtype=bool)
    inner[1:-1, 1:-1] = True
    assert np.all(counts[inner.ravel()] == 6)
    vor = voronoi_coordination(b)
    assert np.all(vor[inner.ravel()] == 6)
    assert np.all(vor[~inner.ravel()] != 6)  # hull dots: -1; others on the rim see fewer or more


@pytest.mark.parametrize("pitch, n_neighbours, edge_psi", [(2.5 * R, 4, -1 / 3), (2.0 * R, 8, -1 / 5)])
def test_square_lattice_psi6_is_zero_inside(pitch, n_neighbours, edge_psi):
    # pitch 2.5 R: only the 4 axial neighbours are within one mean radius of surface;
    # pitch 2 R: the diagonals too (gap 0.83 R). Either way sum exp(6i theta) = 0.
    m = 7
    b = board(square_lattice(m, pitch))
    counts = neighbour_counts(b).reshape(m, m)
    assert np.all(counts[1:-1, 1:-1] == n_neighbours)
    psi = hexatic_order(b).psi.reshape(m, m)
    np.testing.assert_allclose(psi[1:-1, 1:-1], 0.0, atol=1e-12)
    # An edge dot (not a corner): bonds at 0, 90, 270 deg give (1 - 1 - 1) / 3; with the
    # diagonals (45, 315 deg: -i and +i) the sum is still -1, over 5 neighbours.
    assert psi[0, 3] == pytest.approx(edge_psi, abs=1e-12)
    vor = voronoi_coordination(b).reshape(m, m)
    assert np.all(vor[1:-1, 1:-1] == 4)  # co-circular points: the zero-length diagonal edges are dropped
    assert np.all(vor[0, :] == -1)


def test_voronoi_coordination_matches_scipy_voronoi(rng):
    from scipy.spatial import Voronoi

    positions = rng.uniform(0, 300, (500, 2))
    vor = Voronoi(positions)
    ridges = np.asarray(vor.ridge_vertices)
    finite = (ridges >= 0).all(axis=1)
    expected = np.bincount(np.asarray(vor.ridge_points)[finite].ravel(), minlength=500)
    unbounded = np.zeros(500, dtype=bool)
    unbounded[np.asarray(vor.ridge_points)[~finite].ravel()] = True
    ours = voronoi_coordination(board(positions))
    np.testing.assert_array_equal(ours[~unbounded], expected[~unbounded])
    assert np.all(ours[unbounded] == -1)
    assert ours[~unbounded].mean() == pytest.approx(6.0, abs=0.1)  # Euler: 6 on average in the plane


def test_two_isolated_dots_and_empty_boards():
    b = board([[100.0, 100.0], [300.0, 100.0]])
    h = hexatic_order(b)
    assert not h.has_neighbours.any() and math.isnan(h.global_order)
    labels, sizes = clusters(b)
    assert sorted(labels) == [0, 1] and list(sizes) == [1, 1]
    np.testing.assert_array_equal(voronoi_coordination(b), [-1, -1])
    empty = board(np.zeros((0, 2)))
    assert clusters(empty)[1].size == 0 and voronoi_coordination(empty).size == 0


def test_clusters_of_separate_patches():
    patch_a = hex_lattice(4, origin=(50, 50))    # 16 dots
    patch_b = hex_lattice(3, origin=(300, 300))  # 9 dots
    lone = [[500.0, 80.0]]
    b = board(np.vstack([patch_b, lone, patch_a]))
    labels, sizes = clusters(b)
    np.testing.assert_array_equal(sizes, [16, 9, 1])
    assert np.all(labels[10:] == 0) and np.all(labels[:9] == 1) and labels[9] == 2


# --------------------------------------------------------------------------- g(r)


def test_rdf_of_uniform_points_is_one_with_edge_correction(rng):
    box = (400.0, 250.0)
    b = SimpleNamespace(positions=rng.uniform(0, 1, (4000, 2)) * box, radii=np.full(4000, 1.0), box=box)
    rdf = radial_distribution(b, r_max=240.0, bins=24)
    # Expected counts per bin are > 2e4 here: Poisson noise < 1 %; without the edge term the
    # last bins would be ~45 % low.
    np.testing.assert_allclose(rdf.g, 1.0, atol=0.03)
    assert rdf.counts.sum() == pytest.approx(rdf.counts.sum())  # counts are integers
    assert rdf.window == box


def test_rdf_counts_match_freud():
    b = settled_like_board()
    rdf = radial_distribution(b, r_max=60.0, bins=40)
    box, pts = freud_system(b)
    ref = freud.density.RDF(bins=40, r_max=60.0)
    ref.compute((box, pts), reset=True)
    np.testing.assert_allclose(rdf.edges, ref.bin_edges, rtol=1e-6, atol=1e-9)
    np.testing.assert_array_equal(2 * rdf.counts, ref.bin_counts)  # freud counts ordered pairs
    # Hard discs: nothing inside one diameter, a contact peak just outside it.
    assert rdf.counts[rdf.r < 2 * R - 1].sum() == 0
    assert rdf.g[np.argmax(rdf.g)] > 1.5 and 2 * R <= rdf.r[np.argmax(rdf.g)] < 2 * R + 3


# --------------------------------------------------------------------------- freud cross-checks


def test_neighbour_counts_and_psi6_match_freud():
    b = settled_like_board()
    box, pts = freud_system(b)
    # Equal radii: the text rule is "centre distance < 3 R".
    nlist = freud.locality.AABBQuery(box, pts).query(pts, dict(r_max=3 * R, exclude_ii=True)).toNeighborList()
    np.testing.assert_array_equal(neighbour_counts(b), nlist.neighbor_counts)
    hexatic = freud.order.Hexatic(k=6)
    hexatic.compute((box, pts), neighbors=nlist)
    ours = hexatic_order(b)
    has = ours.has_neighbours
    np.testing.assert_allclose(ours.psi[has], hexatic.particle_order[has], atol=2e-4)  # freud works in single precision


def test_psi6_with_our_neighbour_list_matches_freud_polydisperse(rng):
    positions, radii = random_sequential(400, (400.0, 400.0), sigma=0.15, rng=8)
    b = SimpleNamespace(positions=positions, radii=radii, box=(400.0, 400.0))
    src, dst, _ = neighbour_edges(b, rule="code")  # asymmetric rule: give freud the same bonds
    box, pts = freud_system(b)
    order = np.lexsort((dst, src))
    src, dst = src[order], dst[order]
    nlist = freud.locality.NeighborList.from_arrays(len(pts), len(pts), src, dst, box.wrap(pts[dst] - pts[src]))
    hexatic = freud.order.Hexatic(k=6)
    hexatic.compute((box, pts), neighbors=nlist)
    ours = hexatic_order(b, rule="code")
    np.testing.assert_allclose(ours.psi[ours.has_neighbours], hexatic.particle_order[ours.has_neighbours], atol=2e-4)


def test_structure_rejects_bad_input():
    b = board(hex_lattice(3))
    with pytest.raises(ValueError, match="r_max must be"):
        radial_distribution(b, r_max=1e4)
    with pytest.raises(ValueError, match="bins must be"):
        radial_distribution(b, r_max=50.0, bins=0)
    with pytest.raises(ValueError, match="rule must be"):
        hexatic_order(b, rule="java")
    with pytest.raises(ValueError, match="dots 0 and 1 share a centre"):
        voronoi_coordination(board([[0.0, 0.0], [0.0, 0.0], [1.0, 5.0], [7.0, 1.0]]))
