"""qdots.geometry: every pair search, overlap and clearance against a brute-force numpy oracle, and the
check that no other module of qdots has its own."""

import math
import pathlib
import re

import numpy as np
import pytest
from helpers import refused

import qdots
from labrig.validate import InputError
from qdots import geometry
from qdots.analysis import overlaps
from qdots.geometry import (
    DiscTree,
    VerletPairs,
    clashing_pairs,
    clear_of_walls,
    extent,
    moved_beyond,
    nearest_centre,
    nearest_ratio,
    nested_pairs,
    overlapping_pairs,
    pair_bound,
    pair_separation,
    pairs_closer,
    pairs_with_distances,
    pairs_within,
    relative_overlap,
    segment_distances,
    wall_clearances,
    worst_overlap,
    worst_wall_overlap,
)
from qdots.placement import hexagonal_lattice

ROOT = pathlib.Path(__file__).resolve().parents[2]


def grid(n, spacing=1.0):
    """``n`` points on a square grid, ``spacing`` px apart, from (1, 1)."""
    side = math.ceil(math.sqrt(n))
    return 1.0 + spacing * np.argwhere(np.ones((side, side)))[:n].astype(float)


# --------------------------------------------------------------------------- boards and oracles


def random_board(seed: int, n: int = 150):
    """``n`` discs on a 200 px board, on a quarter-px grid with radii in half px (every sum and half-sum
    exact), with pairs made to touch exactly (d = r_i + r_j), to overlap (d = (r_i + r_j) / 2), a disc
    nested in another and two equal discs at one centre."""
    rng = np.random.default_rng(seed)
    positions = rng.integers(40, 760, (n, 2)) / 4.0
    radii = rng.choice([1.5, 2.0, 2.5, 3.0, 4.5], n)
    for a in range(0, 12, 2):  # touching, horizontal and vertical
        axis = (a // 2) % 2
        positions[a + 1] = positions[a]
        positions[a + 1, axis] += radii[a] + radii[a + 1]
    for a in range(12, 18, 2):  # overlapping by half the contact distance
        positions[a + 1] = positions[a] + [0.5 * (radii[a] + radii[a + 1]), 0.0]
    positions[19], radii[18], radii[19] = positions[18], 4.5, 1.5  # nested
    positions[21], radii[21] = positions[20], radii[20]  # one centre
    return positions, radii


BOARDS = [random_board(seed) for seed in range(4)] + [random_board(9, n=30)]


def distances(positions):
    """Every centre distance, px (N, N)."""
    delta = positions[:, None, :] - positions[None, :, :]
    return np.sqrt((delta**2).sum(axis=2))


def upper_pairs(mask):
    """The pairs ``(i, j)``, ``i < j``, where ``mask`` holds, as a sorted list."""
    i, j = np.nonzero(np.triu(mask, 1))
    return sorted(zip(i.tolist(), j.tolist()))


def listed(i, j):
    return sorted(zip(np.asarray(i).tolist(), np.asarray(j).tolist()))


def segment_oracle(points, segments):
    """Distance from each point to each segment, by cases: the perpendicular when the foot lies on the
    segment, the nearer end otherwise."""
    out = np.empty((len(points), len(segments)))
    for k, (px, py) in enumerate(points):
        for m, (x0, y0, x1, y1) in enumerate(segments):
            ax, ay, bx, by = px - x0, py - y0, x1 - x0, y1 - y0
            length = math.hypot(bx, by)
            along = (ax * bx + ay * by) / length
            if 0.0 <= along <= length:
                out[k, m] = abs(ax * by - ay * bx) / length
            else:
                out[k, m] = min(math.hypot(ax, ay), math.hypot(px - x1, py - y1))
    return out


def walls_for(positions, radii, seed):
    """Random segments, one tangent to disc 0 (clearance exactly 0) and one through disc 2's centre."""
    rng = np.random.default_rng(seed)
    segments = rng.uniform(0, 200, (7, 4))
    x, y = positions[0]
    tangent = [x, y + radii[0], x + 8.0, y + radii[0]]
    through = [*positions[2], positions[2, 0] + 5.0, positions[2, 1] + 3.0]
    return np.vstack([segments, tangent, through])


# --------------------------------------------------------------------------- the oracles, one per function


def check_pair_separation(positions, radii):
    x, y = positions[:, 0].copy(), positions[:, 1].copy()
    for a, b in [(0, 1), (3, 2), (12, 13), (20, 21), (len(x) - 1, 0)]:
        dx, dy, d2, contact = pair_separation(x, y, radii, a, b)
        assert (dx, dy, contact) == (x[b] - x[a], y[b] - y[a], radii[a] + radii[b])
        assert d2 == pytest.approx(distances(positions)[a, b] ** 2, rel=1e-14, abs=0.0)


def check_pairs_within(positions, radii):
    x, y = positions[:, 0].copy(), positions[:, 1].copy()
    d = distances(positions)
    for cutoff in (0.0, 3.0, 2.0 * radii.max(), 17.3, 60.0):
        i, j = pairs_within(x, y, cutoff)
        assert (i < j).all()
        assert listed(i, j) == upper_pairs(d < cutoff), cutoff
    touching = float(radii[0] + radii[1])  # a pair exactly this far apart is not listed: strictly closer
    assert (0, 1) not in listed(*pairs_within(x, y, touching))


def check_pairs_with_distances(positions, radii):
    d = distances(positions)
    for reach in (0.0, 3.0, 2.0 * radii.max(), 17.3):
        i, j, dij = pairs_with_distances(positions, reach)
        assert listed(i, j) == upper_pairs(d <= reach), reach  # at most reach: a pair at reach is listed
        np.testing.assert_allclose(dij, d[i, j], rtol=1e-15, atol=0.0)


def check_pair_bound(positions, radii):
    x, y = positions[:, 0], positions[:, 1]
    d = distances(positions)
    for reach in (0.0, 3.0, 17.3, 300.0):
        assert pair_bound(x, y, reach) >= len(upper_pairs(d <= reach))


def check_pairs_closer(positions, radii):
    x, y = positions[:, 0].copy(), positions[:, 1].copy()
    d = distances(positions)
    i, j = pairs_within(x, y, 40.0)
    for extra in (0.0, 0.5, 4.0):
        ci, cj = pairs_closer(x, y, radii, i, j, extra)
        gap = d[i, j] - radii[i] - radii[j]
        assert listed(ci, cj) == listed(i[gap < extra], j[gap < extra])
        assert [p for p in zip(i.tolist(), j.tolist()) if p in set(zip(ci.tolist(), cj.tolist()))] == \
            list(zip(ci.tolist(), cj.tolist()))  # in the order of the list given


def check_verlet_pairs(positions, radii):
    x, y = positions[:, 0].copy(), positions[:, 1].copy()
    pairs = VerletPairs(2.0)
    assert pairs.update(x, y, 10.0)
    d = distances(positions)
    assert set(upper_pairs(d < 10.0)) <= set(listed(pairs.i, pairs.j))
    assert listed(pairs.i, pairs.j) == upper_pairs(d < 12.0)  # cutoff + skin when built


def check_moved_beyond(positions, radii):
    rng = np.random.default_rng(len(radii))
    x, y = positions[:, 0].copy(), positions[:, 1].copy()
    for scale in (0.01, 0.3, 1.0):
        mx, my = x + rng.normal(0, scale, x.size), y + rng.normal(0, scale, y.size)
        assert moved_beyond(mx, my, x, y, 0.5) == bool(((mx - x) ** 2 + (my - y) ** 2 > 0.25).any())
    mx = x.copy()
    mx[-1] = np.nan
    assert moved_beyond(mx, y, x, y, 1e9)


def check_extent(positions, radii):
    x, y = positions[:, 0].copy(), positions[:, 1].copy()
    assert extent(x, y) == (x.min(), y.min(), x.max(), y.max(), True)
    x[0] = np.inf
    assert extent(x, y)[4] is False


def check_relative_overlap(positions, radii):
    d = distances(positions)
    contact = radii[:, None] + radii[None, :]
    np.testing.assert_allclose(relative_overlap(d, contact), 2.0 * (contact - d) / contact, rtol=1e-13, atol=1e-13)
    assert relative_overlap(15.0, 15.0) == 0.0 and relative_overlap(14.0, 15.0) == pytest.approx(1.0 / 7.5)


def check_overlapping_pairs(positions, radii):
    d = distances(positions)
    contact = radii[:, None] + radii[None, :]
    for tolerance in (0.0, 0.02, 0.5):
        i, j, dij = overlapping_pairs(positions, radii, tolerance)
        assert listed(i, j) == upper_pairs(2.0 * (contact - d) / contact > tolerance), tolerance
        np.testing.assert_allclose(dij, d[i, j], rtol=1e-15, atol=0.0)
    assert (0, 1) not in listed(*overlapping_pairs(positions, radii)[:2])  # touching is not overlapping
    assert (12, 13) in listed(*overlapping_pairs(positions, radii)[:2])


def check_worst_overlap(positions, radii):
    d = distances(positions)
    contact = radii[:, None] + radii[None, :]
    relative = np.triu(2.0 * (contact - d) / contact, 1)
    relative[np.tril_indices(len(radii))] = -np.inf
    worst, (i, j) = worst_overlap(positions, radii)
    if relative.max() > 0:
        assert worst == pytest.approx(relative.max(), rel=1e-14) and relative[i, j] == relative.max() and i < j
    else:
        assert (worst, (i, j)) == (0.0, (-1, -1))
    for tolerance in (0.5, 1.99, 2.0):  # the discs at one centre overlap by 2
        worst, (i, j) = worst_overlap(positions, radii, tolerance)
        if relative.max() > tolerance:
            assert worst == pytest.approx(relative.max(), rel=1e-14) and relative[i, j] == relative.max()
        else:
            assert (worst, (i, j)) == (0.0, (-1, -1))


def check_nested_pairs(positions, radii):
    d = distances(positions)
    nested = d < np.abs(radii[:, None] - radii[None, :]) + 1e-9
    assert listed(*nested_pairs(positions, radii)) == upper_pairs(nested)


def check_clashing_pairs(positions, radii):
    d = distances(positions)
    contact = radii[:, None] + radii[None, :]
    for margin in (0.0, 1e-6, 2.0):
        a, b = clashing_pairs(positions, radii, margin)
        assert listed(a, b) == upper_pairs(d < contact + margin), margin
    assert (0, 1) not in listed(*clashing_pairs(positions, radii))  # touching is allowed
    assert (0, 1) in listed(*clashing_pairs(positions, radii, 1e-6))


def check_disc_tree(positions, radii):
    half = len(radii) // 2
    tree = DiscTree(positions[:half], radii[:half])
    query, query_r = positions[half:], radii[half:]
    delta = query[:, None, :] - positions[None, :half, :]
    d = np.sqrt((delta**2).sum(axis=2))
    for margin in (0.0, 1e-6, 3.0):
        clash = d < query_r[:, None] + radii[None, :half] + margin
        lowest = np.where(clash.any(axis=1), clash.argmax(axis=1), -1)
        np.testing.assert_array_equal(tree.clashing_partners(query, query_r, margin), lowest)
    everyone = DiscTree(positions, radii).clashing_partners(positions, radii)  # each disc overlaps itself at least
    np.testing.assert_array_equal(everyone, (distances(positions) < radii[:, None] + radii[None, :]).argmax(axis=1))
    assert (everyone <= np.arange(len(radii))).all()
    assert DiscTree(np.zeros((0, 2)), np.zeros(0)).clashing_partners(query, query_r).tolist() == [-1] * len(query_r)
    touching = DiscTree(positions[:1], radii[:1])
    assert touching.clashing_partners(positions[1:2], radii[1:2])[0] == -1
    assert touching.clashing_partners(positions[1:2], radii[1:2], 1e-9)[0] == 0


def check_segment_distances(positions, radii):
    segments = walls_for(positions, radii, len(radii))
    np.testing.assert_allclose(segment_distances(positions, segments), segment_oracle(positions, segments),
                               rtol=1e-12, atol=1e-9)


def check_wall_clearances(positions, radii):
    segments = walls_for(positions, radii, len(radii))
    clearance = wall_clearances(positions, radii, segments)
    np.testing.assert_allclose(clearance, segment_oracle(positions, segments) - radii[:, None], rtol=1e-12,
                               atol=1e-9)
    assert clearance[0, -2] == 0.0  # the tangent segment


def check_worst_wall_overlap(positions, radii):
    segments = walls_for(positions, radii, len(radii))
    relative = (radii[:, None] - segment_oracle(positions, segments)) / radii[:, None]
    worst, (k, m) = worst_wall_overlap(positions, radii, segments)
    assert worst == pytest.approx(relative.max(), rel=1e-12) and relative[k, m] == pytest.approx(relative.max())
    assert worst_wall_overlap(positions[:1], radii[:1], segments[-2:-1]) == (0.0, (-1, -1))  # touching is clear
    assert worst_wall_overlap(positions, radii, np.zeros((0, 4))) == (0.0, (-1, -1))


def check_clear_of_walls(positions, radii):
    segments = walls_for(positions, radii, len(radii))
    oracle = segment_oracle(positions, segments)
    for margin in (0.0, 1e-6, 2.0):
        expected = (oracle >= radii[:, None] + margin).all(axis=1)
        near = (np.abs(oracle - radii[:, None] - margin) < 1e-9).any(axis=1)  # round-off may go either way
        got = clear_of_walls(positions, radii, segments, margin)
        np.testing.assert_array_equal(got[~near], expected[~near])
    assert clear_of_walls(positions[:1], radii[:1], segments[-2:-1])[0]  # touching is clear at margin 0
    assert not clear_of_walls(positions[:1], radii[:1], segments[-2:-1], 1e-6)[0]
    assert clear_of_walls(positions, radii, np.zeros((0, 4))).all()


def check_nearest_ratio(positions, radii):
    d = distances(positions)
    np.fill_diagonal(d, np.inf)
    nearest = np.argmin(d, axis=1)
    expected = d[np.arange(len(d)), nearest] / (radii + radii[nearest])  # diameters 2 r: mean diameter r_i + r_j
    ratio = nearest_ratio(positions, 2.0 * radii)
    ties = np.sort(d, axis=1)[:, 1] == d[np.arange(len(d)), nearest]  # two neighbours at one distance: either
    np.testing.assert_allclose(ratio[~ties], expected[~ties], rtol=1e-12)
    assert nearest_ratio(positions[:1], radii[:1]).tolist() == [np.inf]


def check_nearest_centre(positions, radii):
    points, centres = positions[::2] + 0.3, positions[1::2]
    d = np.hypot(*(points[:, None, :] - centres[None, :, :]).transpose(2, 0, 1))
    distance, index = nearest_centre(points, centres)
    np.testing.assert_allclose(distance, d.min(axis=1), rtol=1e-12)
    np.testing.assert_allclose(d[np.arange(len(points)), index], d.min(axis=1), rtol=1e-12)  # ties: either
    none = nearest_centre(points, np.zeros((0, 2)))
    assert np.isinf(none[0]).all() and (none[1] == 0).all()


ORACLES = {
    "nearest_ratio": check_nearest_ratio, "nearest_centre": check_nearest_centre,
    "pair_separation": check_pair_separation, "pairs_within": check_pairs_within,
    "pairs_with_distances": check_pairs_with_distances, "pair_bound": check_pair_bound,
    "pairs_closer": check_pairs_closer, "VerletPairs": check_verlet_pairs, "moved_beyond": check_moved_beyond,
    "extent": check_extent, "relative_overlap": check_relative_overlap,
    "overlapping_pairs": check_overlapping_pairs, "worst_overlap": check_worst_overlap,
    "nested_pairs": check_nested_pairs, "clashing_pairs": check_clashing_pairs, "DiscTree": check_disc_tree,
    "segment_distances": check_segment_distances, "wall_clearances": check_wall_clearances,
    "worst_wall_overlap": check_worst_wall_overlap, "clear_of_walls": check_clear_of_walls,
}


def test_every_public_function_has_an_oracle():
    public = {name for name in geometry.__all__ if callable(getattr(geometry, name))}
    assert public == set(ORACLES)


@pytest.mark.parametrize("name", sorted(ORACLES))
@pytest.mark.parametrize("board", range(len(BOARDS)))
def test_agrees_with_the_brute_force_oracle(name, board):
    positions, radii = BOARDS[board]
    ORACLES[name](positions.copy(), radii.copy())


def test_the_random_boards_hold_the_cases_they_are_made_for():
    positions, radii = BOARDS[0]
    d = distances(positions)
    assert d[0, 1] == radii[0] + radii[1] and d[2, 3] == radii[2] + radii[3]  # exactly touching
    assert d[12, 13] == 0.5 * (radii[12] + radii[13]) and d[18, 19] == 0.0 and d[20, 21] == 0.0


# --------------------------------------------------------------------------- the engine's pair search


def test_the_verlet_list_never_misses_a_pair_and_rebuilds_only_when_needed():
    for skin in (0.0, 1.0, 3.0):
        rng = np.random.default_rng(5)
        xy = rng.uniform(0, 200, (150, 2))
        pairs, cutoff, rebuilds = VerletPairs(skin), 20.0, 0
        anchor = None
        for step in range(200):
            xy += rng.normal(0, 0.05, xy.shape)
            x, y = xy[:, 0].copy(), xy[:, 1].copy()
            rebuilt = pairs.update(x, y, cutoff)
            if rebuilt:
                anchor, rebuilds = xy.copy(), rebuilds + 1
            moved = np.hypot(*(xy - anchor).T).max()
            assert moved <= skin / 2 or skin == 0  # kept only while every dot stayed within skin / 2
            close = set(upper_pairs(distances(xy) < cutoff))
            assert close <= set(listed(pairs.i, pairs.j)), step
        assert pairs.rebuilds == rebuilds
        assert (rebuilds == 200) if skin == 0 else (1 < rebuilds < 100)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("axis", [0, 1])
def test_a_non_finite_position_forces_a_rebuild(bad, axis):
    pairs = VerletPairs(3.0)
    x, y = np.array([0.0, 10.0, 30.0]), np.array([0.0, 0.0, 5.0])
    assert pairs.update(x, y, 20.0) and not pairs.update(x, y, 20.0)
    moved = [x.copy(), y.copy()]
    moved[axis][1] = bad
    with pytest.raises(ValueError, match="not all finite"):
        pairs.update(*moved, 20.0)  # the search refuses it: the run says what happened


def test_engine_pair_search_refuses_too_many_pairs(monkeypatch):
    monkeypatch.setattr(geometry.pairs, "MAX_PAIRS", 1000)
    xy = grid(100)  # 4,950 pairs within 200 px
    refused(lambda: pairs_within(xy[:, 0], xy[:, 1], 200.0), "pair search: 4,950 pairs", "1,000")
    i, _ = pairs_within(xy[:, 0], xy[:, 1], 1.5)  # 342 pairs
    assert len(i) == 342


def test_engine_pair_search_hint_and_grid_are_bounded():
    # a huge hint allocates no more than a list may hold
    xy = grid(100)
    i, j = pairs_within(xy[:, 0], xy[:, 1], 1.5, expected=10**15)
    assert len(i) == 342
    # dots in close couples strung along 10^6 px, a cutoff far below their spacing: the grid would have
    # 6e8 cells; it gets wider cells, and the same pairs
    couples = 100_000
    x = np.repeat(10.0 * np.arange(couples), 2) + np.tile([0.0, 5e-4], couples)
    y = np.zeros_like(x)
    width, cell = x.max(), math.sqrt(1.0 / (2 * len(x)))
    assert (width / cell + 1) > geometry.MAX_GRID_CELLS
    i, j = pairs_within(x, y, 1e-3)
    assert sorted(zip(i.tolist(), j.tolist())) == [(2 * k, 2 * k + 1) for k in range(couples)]


# --------------------------------------------------------------------------- the analysis's pair search


def test_pair_bound_is_an_upper_bound():
    rng = np.random.default_rng(0)
    for trial in range(60):
        n = int(rng.integers(2, 300))
        kind = trial % 4
        if kind == 0:
            xy = rng.uniform(0, rng.uniform(1, 1000), (n, 2))
        elif kind == 1:  # on a line
            xy = np.column_stack([rng.uniform(0, 1000, n), np.full(n, 5.0)])
        elif kind == 2:  # on a grid, many at equal distances
            xy = np.round(rng.uniform(0, 50, (n, 2)))
        else:  # far from the origin
            xy = rng.normal(0, rng.uniform(0.01, 100), (n, 2)) + 1e6
        reach = float(rng.choice([0.0, rng.uniform(0, 2000), rng.uniform(0, 5)]))
        assert pair_bound(xy[:, 0], xy[:, 1], reach) >= len(upper_pairs(distances(xy) <= reach))
    xy = hexagonal_lattice(60, 15.0)
    true = len(pairs_with_distances(xy, 150.0)[0])
    assert true <= pair_bound(xy[:, 0], xy[:, 1], 150.0) <= 2.5 * true  # tight enough at large reach
    assert pair_bound(xy[:, 0], xy[:, 1], 1e9) == len(xy) * (len(xy) - 1) // 2


def test_searches_with_distances_are_refused_before_they_list_too_many_pairs(monkeypatch):
    monkeypatch.setattr(geometry.pairs, "MAX_PAIRS", 1000)  # N (N - 1) / 2 = 4,950 > 1,000: the bound is asked
    xy = grid(100)
    refused(lambda: pairs_with_distances(xy, 200.0, "r_max = 200 px"), "r_max = 200 px", "4.95e+03", "1,000 allowed")
    refused(lambda: worst_overlap(xy, np.full(100, 100.0)), "the overlap search", "100 px", "1,000 allowed")
    refused(lambda: nested_pairs(xy, np.full(100, 100.0)), "the overlap search", "1,000 allowed")
    refused(lambda: clashing_pairs(xy, np.full(100, 100.0), 1.0), "clash search", "margin 1 px", "1,000 allowed")
    assert len(pairs_with_distances(xy, 0.5)[0]) == 0  # a short reach bounds few pairs: searched


def test_fewer_than_two_discs_have_no_pairs():
    for n in (0, 1):
        xy, r = np.full((n, 2), 5.0), np.full(n, 2.0)
        assert [len(a) for a in pairs_within(xy[:, 0].copy(), xy[:, 1].copy(), 10.0)] == [0, 0]
        assert [len(a) for a in pairs_with_distances(xy, 10.0)] == [0, 0, 0]
        assert [len(a) for a in overlapping_pairs(xy, r)] == [0, 0, 0]
        assert [len(a) for a in nested_pairs(xy, r)] == [0, 0]
        assert [len(a) for a in clashing_pairs(xy, r, 1.0)] == [0, 0]
        assert worst_overlap(xy, r) == (0.0, (-1, -1)) and pair_bound(xy[:, 0], xy[:, 1], 10.0) == 0
        assert len(DiscTree(xy, r).clashing_partners(xy, r)) == n


def test_a_disc_tree_answers_in_chunks_the_same(monkeypatch):
    positions, radii = BOARDS[0]
    tree = DiscTree(positions[:70], radii[:70])
    whole = tree.clashing_partners(positions[70:], radii[70:], 1.0)
    monkeypatch.setattr(geometry.discs, "MAX_PAIRS", 140)  # two queries per chunk
    np.testing.assert_array_equal(tree.clashing_partners(positions[70:], radii[70:], 1.0), whole)
    assert (whole >= 0).any() and (whole < 0).any()


def test_a_disc_tree_keeps_its_own_copy_of_the_discs():
    centres, radii = np.array([[10.0, 10.0]]), np.array([5.0])
    tree = DiscTree(centres, radii)
    centres[0] = [100.0, 100.0]
    radii[0] = 0.1
    assert tree.clashing_partners([[12.0, 10.0]], [1.0])[0] == 0


# --------------------------------------------------------------------------- one place for the geometry


#: What a module of its own pair search or overlap test looks like (each old copy matched one of these).
OWN_GEOMETRY = {
    "a KD-tree pair search": re.compile(r"\b(cKDTree|KDTree)\b|query_pairs|query_ball_point|sparse_distance_matrix"),
    "a compiled pair search": re.compile(r"def _?(cell_)?pairs_|_cell_pairs"),
    "distances to wall segments": re.compile(r"\bsegment_distances\b"),
    "a relative overlap": re.compile(r"\b(rsum|contact)\s*-\s*(d|dist|distance)\b"),
    "a clash test": re.compile(r"(sqrt\(dx \* dx \+ dy \* dy\)|math\.dist\([^)]*\)|linalg\.norm\([^)]*\)|\bdist)"
                               r"\s*[<>]=?"),
}
#: Modules allowed a KD-tree of their own, and why: neither is a board's overlap, clash or clearance.
OWN_KD_TREES = {
    "qdots/analysis/forster.py": "the exciton network's minimum-image pairs on a periodic box (cKDTree boxsize)",
    "qdots/analysis/structure.py": "the nearest-neighbour spacing that scales Voronoi edges (cKDTree.query)",
    "qdots/micrograph/synthetic.py": "scoring a detection: the nearest true dot of each found one and back (cKDTree.query)",
    "qdots/inference/forward.py": "a film's mean gap to each dot's nearest neighbour (cKDTree.query)",
}


def own_geometry(root: pathlib.Path) -> list[str]:
    """``file:line: what`` for each line of qdots outside qdots/geometry that looks like its own geometry."""
    found = []
    for path in sorted((root / "qdots").rglob("*.py")):
        name = path.relative_to(root).as_posix()
        if name.startswith("qdots/geometry/"):
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            for what, pattern in OWN_GEOMETRY.items():
                if pattern.search(line) and not (what == "a KD-tree pair search" and name in OWN_KD_TREES):
                    found.append(f"{name}:{number}: {what}: {line.strip()}")
    return found


def test_no_module_outside_geometry_has_its_own_pair_search_or_overlap():
    assert own_geometry(ROOT) == []


def test_the_check_finds_the_copies_that_were_merged(tmp_path):
    """The patterns above find each copy `qdots.geometry` replaced (written here as they were)."""
    copies = {
        "scene.py": ["pairs = cKDTree(self.positions).query_pairs(2.0 * self.radii.max(), output_type='ndarray')",
                     "gap = segment_distances(new.positions, segments) - new.radii[:, None]",
                     "if np.linalg.norm(point - board.positions[j]) < r + board.radii[j]:"],
        "analysis/packing.py": ["relative = (rsum - d) / (0.5 * rsum)"],
        "hard_cases.py": ["return max(0.0, float(((rsum - d) / (0.5 * rsum)).max())), swallowed",
                          "if all(math.dist(p, q) > r + s + 0.5 for q, s in zip(positions, radii)):"],
        "protocols.py": ["ok &= (dist >= r[:, None] + board.radii[None, :] + GAP).all(axis=1)"],
        "placement.py": ["bad = np.sqrt(dx * dx + dy * dy) < r[a] + r[b] + margin"],
        "neighbours.py": ["def _cell_pairs(x, y, cutoff, cell, nx, ny, x0, y0, out_i, out_j):"],
    }
    for name, lines in copies.items():
        path = tmp_path / "qdots" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines) + "\n")
    found = own_geometry(tmp_path)
    assert len(found) == sum(len(lines) for lines in copies.values()), found


# --------------------------------------------------------------------------- the callers measure with it


def test_a_dot_added_on_top_of_two_names_the_lower_one():
    scene = qdots.Scene(box=(100.0, 100.0), positions=[[60.0, 50.0], [40.0, 50.0]], radii=[7.5, 7.5])
    sim = qdots.Simulation(scene, [], seed=0)
    with pytest.raises(InputError, match="new dot 0 overlaps dot 0 already on the board"):
        sim.add_dots([[50.0, 50.0]], [7.5])
    sim.add_dots([[60.0, 65.0]], [7.5])  # touching dot 0: allowed
    assert sim.n_dots == 3


def test_the_analysis_reports_the_geometry_s_worst_overlap():
    positions, radii = BOARDS[0]
    state = qdots.State(time=0.0, positions=positions, velocities=np.zeros_like(positions), radii=radii,
                        masses=np.ones(len(radii)), box=(200.0, 200.0), walls=np.zeros((0, 4)))
    assert overlaps(state) == worst_overlap(positions, radii) != (0.0, (-1, -1))
