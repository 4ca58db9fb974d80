"""Neighbour counts, overlaps and random sequential placement, against exact answers."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import worst_overlap

import qdots
from qdots import placement
from qdots.analysis import neighbour_counts, overlaps, packing_summary
from qdots.placement import hexagonal_lattice, random_sequential

R = 7.5  # thesis mean radius, px


def board(positions, radii, velocities=None, masses=None, box=(600.0, 600.0)):
    positions = np.asarray(positions, dtype=float)
    n = len(positions)
    return qdots.State(
        time=0.0,
        positions=positions,
        velocities=np.zeros((n, 2)) if velocities is None else np.asarray(velocities, dtype=float),
        radii=np.broadcast_to(np.asarray(radii, dtype=float), (n,)).copy(),
        masses=np.ones(n) if masses is None else np.asarray(masses, dtype=float),
        box=box,
        walls=np.zeros((0, 4)),
    )


def hex_patch(m, r=R, origin=(100.0, 100.0)):
    """m x m parallelogram of a hexagonal lattice with spacing 2r (every bond in exact contact)."""
    return hexagonal_lattice(m, 2 * r, "parallelogram", origin)


def flower(r=R):
    """A centre dot and its six touching neighbours."""
    angles = np.arange(6) * np.pi / 3
    ring = 300 + 2 * r * np.column_stack([np.cos(angles), np.sin(angles)])
    return np.vstack([[300.0, 300.0], ring])


# --------------------------------------------------------------------------- analysis


def test_two_isolated_dots():
    state = board([[100, 100], [200, 100]], R)
    assert overlaps(state) == (0.0, (-1, -1))
    for rule in ("text", "code"):
        np.testing.assert_array_equal(neighbour_counts(state, rule=rule), [0, 0])


@pytest.mark.parametrize("rule", ["text", "code"])
def test_flower_exact_counts(rule):
    state = board(flower(), R)
    np.testing.assert_array_equal(neighbour_counts(state, rule=rule), [6, 3, 3, 3, 3, 3, 3])
    worst, _ = overlaps(state)
    assert worst <= 1e-12


@pytest.mark.parametrize("rule", ["text", "code"])
def test_hex_patch_bond_count(rule):
    m = 9
    state = board(hex_patch(m), R)
    counts = neighbour_counts(state, rule=rule)
    # A parallelogram of m x m hexagonal sites has (m - 1)(3m - 1) nearest-neighbour bonds.
    assert counts.sum() == 2 * (m - 1) * (3 * m - 1)
    centre = (m // 2) * m + m // 2
    assert counts[centre] == 6
    assert counts.max() == 6
    assert overlaps(state)[0] <= 1e-12


def test_text_rule_threshold_is_one_mean_radius():
    inside = board([[100, 100], [100 + 2 * R + 0.99 * R, 100]], R)
    outside = board([[100, 100], [100 + 2 * R + 1.01 * R, 100]], R)
    np.testing.assert_array_equal(neighbour_counts(inside), [1, 1])
    np.testing.assert_array_equal(neighbour_counts(outside), [0, 0])
    # An explicit mean radius overrides the mean of the radii.
    np.testing.assert_array_equal(neighbour_counts(inside, mean_radius=0.5 * R), [0, 0])
    # With a large dot far away the KD-tree reach grows; the gap test alone must decide.
    far_big = [[500, 500]]
    inside3 = board(np.vstack([inside.positions, far_big]), [R, R, 3 * R])
    outside3 = board(np.vstack([outside.positions, far_big]), [R, R, 3 * R])
    np.testing.assert_array_equal(neighbour_counts(inside3, mean_radius=R), [1, 1, 0])
    np.testing.assert_array_equal(neighbour_counts(outside3, mean_radius=R), [0, 0, 0])


def test_code_rule_is_asymmetric():
    # Big r=10 and small r=5 at centre distance 22: the big dot's reach is
    # r_big + 2 r_small = 20 (< 22), the small dot's is r_small + 2 r_big = 25.
    state = board([[100, 100], [122, 100]], [10.0, 5.0])
    np.testing.assert_array_equal(neighbour_counts(state, rule="code"), [0, 1])
    # The text rule is symmetric: gap 7 px < mean radius 7.5 px.
    np.testing.assert_array_equal(neighbour_counts(state, rule="text"), [1, 1])


def test_known_overlap_and_pair():
    # Dots 1 and 2 overlap by 1 px at radii 5 and 10: (15 - 14) / 7.5.
    # Dots 3 and 4 overlap less: (15 - 14.5) / 7.5.
    positions = [[50, 50], [200, 200], [214, 200], [400, 400], [414.5, 400]]
    state = board(positions, [7.5, 5.0, 10.0, 7.5, 7.5])
    worst, pair = overlaps(state)
    assert worst == pytest.approx(1 / 7.5, rel=1e-12)
    assert pair == (1, 2)
    assert worst == pytest.approx(worst_overlap(state.positions, state.radii), rel=1e-12)


def test_packing_summary_flower():
    velocities = np.zeros((7, 2))
    velocities[0] = [3.0, 4.0]
    masses = np.array([2.0, 1, 1, 1, 1, 1, 1])
    summary = packing_summary(board(flower(), R, velocities=velocities, masses=masses))
    assert summary["n_dots"] == 7
    assert summary["interior_fraction"] == pytest.approx(1 / 7)
    assert summary["mean_neighbours_interior"] == 6.0
    assert summary["max_overlap"] <= 1e-12
    assert summary["kinetic_energy"] == pytest.approx(0.5 * 2.0 * 25.0)


def test_summary_accepts_duck_typed_boards_and_no_interior():
    summary = packing_summary(SimpleNamespace(positions=np.array([[0.0, 0.0], [50.0, 0.0]]), radii=np.array([R, R])))
    assert summary["interior_fraction"] == 0.0
    assert math.isnan(summary["mean_neighbours_interior"])
    assert math.isnan(summary["kinetic_energy"])


def test_analysis_rejects_bad_arguments():
    state = board(flower(), R)
    with pytest.raises(ValueError, match="rule must be one of"):
        neighbour_counts(state, rule="java")
    with pytest.raises(ValueError, match="mean_radius must be > 0"):
        neighbour_counts(state, mean_radius=-1.0)
    with pytest.raises(ValueError, match="positions and radii"):
        overlaps(object())
    with pytest.raises(ValueError, match=r"state.radii must have shape \(7,\)"):
        overlaps(SimpleNamespace(positions=state.positions, radii=np.ones(3)))


# --------------------------------------------------------------------------- placement


@pytest.mark.parametrize("sigma", [0.0, 0.05, 0.15])
def test_random_sequential_valid_board(sigma):
    box = (300.0, 200.0)
    positions, radii = random_sequential(150, box, sigma=sigma, rng=3)  # area fraction 0.44
    assert positions.shape == (150, 2) and radii.shape == (150,)
    assert worst_overlap(positions, radii) <= 0.0
    assert np.all(positions - radii[:, None] >= 0)
    assert np.all(positions + radii[:, None] <= box)
    qdots.Scene(box=box, positions=positions, radii=radii)  # validates again
    if sigma == 0:
        np.testing.assert_array_equal(radii, 7.5)


def test_random_sequential_reproducible_and_prefix_stable():
    a = random_sequential(120, (300, 300), sigma=0.1, rng=7)
    b = random_sequential(120, (300, 300), sigma=0.1, rng=np.random.default_rng(7))
    c = random_sequential(40, (300, 300), sigma=0.1, rng=7)
    d = random_sequential(120, (300, 300), sigma=0.1, rng=8)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_array_equal(a[0][:40], c[0])
    assert not np.array_equal(a[0], d[0])


def test_random_sequential_matches_one_at_a_time_reference():
    """Batched acceptance must equal the plain sequential loop on the same candidate stream."""
    # Area fraction ~0.52 asked: near jamming, so many batches and many clashes within a batch.
    n, box, sigma, margin = 65, (150.0, 150.0), 0.15, 0.5
    try:
        fast = random_sequential(n, box, sigma=sigma, rng=11, margin=margin)
    except ValueError:
        pytest.fail("reference board should fit")
    gen = np.random.default_rng(11)
    pos, rad = np.zeros((0, 2)), np.zeros(0)
    while len(rad) < n:
        cand, r, ok = placement.draw_candidates(gen, placement.BATCH, (0.0, 0.0, *box), 15.0, sigma, margin)
        for p, ri, good in zip(cand, r, ok):
            if len(rad) == n:
                break
            d = np.sqrt(((pos - p) ** 2).sum(axis=1))
            if good and not np.any(d < rad + ri + margin):
                pos, rad = np.vstack([pos, p]), np.append(rad, ri)
    np.testing.assert_array_equal(fast[0], pos)
    np.testing.assert_array_equal(fast[1], rad)
    gaps = np.sqrt(((pos[:, None] - pos[None]) ** 2).sum(-1)) - rad[:, None] - rad[None]
    assert gaps[~np.eye(n, dtype=bool)].min() >= margin
    assert np.all(pos - rad[:, None] >= margin) and np.all(pos + rad[:, None] <= np.array(box) - margin)


def test_random_sequential_diameter_distribution():
    _, radii = random_sequential(2000, (3000, 3000), mean_diameter=15.0, sigma=0.1, rng=5)
    d = 2 * radii
    assert d.mean() == pytest.approx(15.0, abs=0.15)
    assert d.std() == pytest.approx(1.5, rel=0.08)


def test_random_sequential_fast_for_3000_dots():
    import time

    start = time.perf_counter()
    positions, radii = random_sequential(3000, (1200, 1200), sigma=0.05, rng=1)
    assert time.perf_counter() - start < 1.0
    assert worst_overlap(positions, radii) <= 0.0


def test_random_sequential_too_full():
    with pytest.raises(ValueError, match=r"board too full: placed \d+ of 500 dots .* 100 x 100 px box"):
        random_sequential(500, (100, 100), rng=1)


def test_random_sequential_zero_dots():
    positions, radii = random_sequential(0, (100, 100))
    assert positions.shape == (0, 2) and radii.shape == (0,)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(n=-1), r"n must be an integer in \[0, 1,000,000\]"),
        (dict(n=2.5), r"n must be an integer in \[0, 1,000,000\]"),
        (dict(n=True), r"n must be an integer in \[0, 1,000,000\]"),
        (dict(box=(0, 100)), "box must be two sizes > 0"),
        (dict(box=(100,)), "box must be"),
        (dict(box="big"), "box must be"),
        (dict(mean_diameter=0.0), r"mean_diameter must be in \[0.01, 1e6\] px"),
        (dict(mean_diameter=200.0), "does not fit in the box"),
        (dict(sigma=1.0), r"sigma must be in \[0, 1\)"),
        (dict(sigma=-0.1), r"sigma must be in \[0, 1\)"),
        (dict(sigma=float("nan")), r"sigma must be in \[0, 1\)"),
        (dict(rng="seed"), "rng must be a numpy Generator"),
        (dict(max_tries=0), r"max_tries must be an integer in \[1, "),
        (dict(margin=-1.0), r"margin must be in \[0, "),
    ],
)
def test_random_sequential_validates(kwargs, message):
    args = dict(n=10, box=(100, 100))
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        random_sequential(**args)
