"""Exciton transport (LQE): exact solutions, the cutoff bound, and Monte Carlo within its error bars."""

import itertools
import math
from types import SimpleNamespace

import numpy as np
import pytest

import qdots
from qdots.analysis.cutoff import cutoff_for, far_field_bound, far_field_grid, truncation_bound
from qdots.analysis.forster import KB_EV, TAU_NS, dot_energies, draw_traps, exciton_network
from qdots.analysis.lqe import film_lqe, lqe_exact, lqe_monte_carlo
from qdots.analysis.lqe_thesis import _event_table, step_probabilities
from qdots.placement import hexagonal_lattice, random_sequential

R = 7.5


def board(positions, radii=R):
    positions = np.asarray(positions, dtype=float)
    return SimpleNamespace(positions=positions,
                           radii=np.broadcast_to(np.asarray(radii, float), (len(positions),)).copy())


def hex_lattice(m, pitch=2 * R):
    return hexagonal_lattice(m, pitch, origin=(50.0, 50.0))


# --------------------------------------------------------------------------- exact answers


def test_two_dots_one_trap_closed_form():
    d = 20.0
    net = exciton_network(board([[0, 0], [d, 0]]), forster_radius=15.0, traps=np.array([False, True]))
    k_r, w = 1 / TAU_NS, (15.0 / d) ** 6 / TAU_NS
    result = lqe_exact(net)
    assert result.yields[0] == pytest.approx(k_r / (k_r + w), rel=1e-12)
    assert result.lqe == pytest.approx(0.5 * k_r / (k_r + w), rel=1e-12)
    assert result.yields[1] == 0.0 and net.truncation_bound == 0.0  # every pair within the cutoff


def test_two_dots_energy_uphill_is_slower_and_detailed_balance():
    d, de, temperature = 15.0, 0.05, 297.0
    energies = np.array([2.0, 2.0 + de])
    kt = KB_EV * temperature
    for trap, expected_w in ((1, math.exp(-de / kt)), (0, 1.0)):  # exciton on 0 hops up; on 1 hops down
        traps = np.zeros(2, dtype=bool)
        traps[trap] = True
        net = exciton_network(board([[0, 0], [d, 0]]), forster_radius=15.0, traps=traps, energies=energies)
        start = 1 - trap
        w = expected_w / TAU_NS
        assert lqe_exact(net).yields[start] == pytest.approx((1 / TAU_NS) / (1 / TAU_NS + w), rel=1e-12)
    rates = net.rates.toarray()
    assert rates[0, 1] * math.exp(-energies[0] / kt) == pytest.approx(rates[1, 0] * math.exp(-energies[1] / kt))


@pytest.mark.parametrize("efficiency", [1.0, 0.6])
def test_no_traps_every_dot_emits_with_its_efficiency(efficiency):
    net = exciton_network(board(hex_lattice(8)), trap_fraction=0.0, efficiency=efficiency, seed=1)
    result = lqe_exact(net)
    np.testing.assert_allclose(result.yields, efficiency, rtol=1e-10)
    assert net.solution_lqe == efficiency


def test_small_and_large_forster_radius_limits():
    b = board(hex_lattice(10))
    weak = exciton_network(b, forster_radii=0.5 / R, seed=4)    # R_F 0.5 px: hops ~ (0.5/15)^6 = 1e-9 of the decay
    assert lqe_exact(weak).lqe == pytest.approx(weak.solution_lqe, abs=1e-7)
    strong = exciton_network(b, forster_radius=60.0, seed=4, cutoff=60.0)
    assert lqe_exact(strong).lqe < 0.02 * strong.solution_lqe


def test_energy_disorder_cg_agrees_with_direct_solve():
    positions, radii = random_sequential(250, (320.0, 320.0), sigma=0.1, rng=2)
    net = exciton_network(board(positions, radii), energies="size", seed=3, cutoff=60.0)
    result = lqe_exact(net)
    good = ~net.traps
    from scipy.sparse import diags
    from scipy.sparse.linalg import spsolve
    inner = net.rates[good][:, good]
    direct = spsolve((diags(net.total_rates()[good]) - inner).tocsc(), np.full(good.sum(), net.radiative_rate))
    np.testing.assert_allclose(result.yields[good], direct, rtol=1e-9, atol=1e-12)
    assert result.error_bound - net.truncation_bound < 1e-9


def test_dot_energies_brus_formula():
    # 5 nm CdSe dot (15 px at 1/3 nm/px): 1.74 + 0.37603 * (1/0.13 + 1/0.45) / 2.5^2 - 1.786 * 1.43996 / (10.6 * 2.5)
    expected = 1.74 + 0.37603 * (1 / 0.13 + 1 / 0.45) / 6.25 - 1.786 * 1.43996 / 26.5
    assert dot_energies([7.5])[0] == pytest.approx(expected, abs=1e-5)
    e = dot_energies([6.0, 7.5, 9.0])
    assert e[0] > e[1] > e[2]  # smaller dots have larger gaps
    with pytest.raises(ValueError, match="radii"):
        dot_energies([-1.0])


# --------------------------------------------------------------------------- pair cutoff


def test_truncation_bound_holds_and_bounds_the_dropped_rates():
    positions, radii = random_sequential(300, (350.0, 350.0), sigma=0.05, rng=5)
    b = board(positions, radii)
    traps = draw_traps(300, seed=6)
    full = exciton_network(b, traps=traps, cutoff=1e4)
    assert full.truncation_bound == 0.0
    reference = lqe_exact(full)
    d = np.sqrt(((positions[:, None] - positions[None]) ** 2).sum(-1))
    spacing = d[~np.eye(300, dtype=bool)].min()
    for cutoff in (25.0, 40.0, 80.0):
        cut = exciton_network(b, traps=traps, cutoff=cutoff)
        change = abs(lqe_exact(cut).lqe - reference.lqe)
        assert change <= cut.truncation_bound
        # The geometric part: tau * max dropped rate sum <= R_F^6 / (2 h^2 (R_c - h)^2).
        far = (d > cutoff)
        dropped = (far * np.where(far, (full.forster_radius / np.where(far, d, 1.0)) ** 6, 0.0)).sum(1).max()
        disc = truncation_bound(full.forster_radius, cutoff, spacing)
        counts, size = far_field_grid(positions, 0.5 * full.forster_radius)
        grid = far_field_bound(counts, size, full.forster_radius, cutoff)
        assert dropped <= disc and dropped <= grid
        assert cut.truncation_bound == pytest.approx(min(disc, grid))
    # The default cutoff meets the default tolerance.
    default = exciton_network(b, traps=traps)
    assert default.truncation_bound <= 1e-3 + 1e-15
    assert abs(lqe_exact(default).lqe - reference.lqe) <= default.truncation_bound
    assert cutoff_for(15.0, 15.0, 1e-3) == pytest.approx(7.5 + (15.0**6 / (2 * 56.25 * 1e-3)) ** 0.25)


def dropped_sums(positions, cutoff, box=None):
    """sum_{R_ij > cutoff} R_ij^-6 of each dot, by all pairs (minimum images in a periodic box)."""
    delta = positions[:, None] - positions[None]
    if box is not None:
        delta -= box * np.round(delta / box)
    d = np.sqrt((delta**2).sum(-1))
    far = d > cutoff
    return np.where(far, np.where(far, d, 1.0) ** -6.0, 0.0).sum(1)


def test_far_field_bound_holds_where_the_disc_bound_is_loose():
    """A measured film with one close pair (two detections 2.5 px apart): the disc bound, set by that pair, sends
    the cutoff out to 9 R_F; the count-grid bound, which sees the film's density, to under half that. Both bound
    the dropped rates, and the LQE moves by less than the bound the network states."""
    rng = np.random.default_rng(3)
    positions, radii = random_sequential(500, (400.0, 400.0), sigma=0.1, rng=4)
    positions = np.vstack([positions, positions[0] + [2.5, 0.0]])
    radii = np.append(radii, radii[0])
    b = board(positions, radii)
    traps = draw_traps(len(radii), seed=rng)
    net = exciton_network(b, traps=traps)
    disc = cutoff_for(net.forster_radius, 2.5, 1e-3)
    assert net.cutoff < 0.5 * disc and net.truncation_bound <= 1e-3
    counts, size = far_field_grid(positions, 0.5 * net.forster_radius)
    for cutoff in (20.0, 40.0, net.cutoff, 150.0):
        exact = dropped_sums(positions, cutoff).max() * net.forster_radius**6
        assert exact <= far_field_bound(counts, size, net.forster_radius, cutoff) <= 20 * exact
    reference = lqe_exact(exciton_network(b, traps=traps, cutoff=1e4))
    assert abs(lqe_exact(net).lqe - reference.lqe) <= net.truncation_bound


@pytest.mark.parametrize("box", [(200.0, 200.0), (210.0, 130.0)])
def test_far_field_bound_holds_in_a_periodic_box(box):
    box = np.array(box)
    positions = np.random.default_rng(7).random((300, 2)) * box
    counts, size = far_field_grid(positions, 6.0, box)
    assert counts.sum() == 300 and size * counts.shape == pytest.approx(box)
    for cutoff in (15.0, 30.0, 60.0):
        exact = dropped_sums(positions, cutoff, box).max() * 10.0**6
        assert exact <= far_field_bound(counts, size, 10.0, cutoff)
    # Two dots near the facing sides of cells three apart are 2 cells (20.2 px), not 3, apart.
    pair = np.array([[9.9, 5.0], [30.1, 5.0]])
    counts, size = far_field_grid(pair, 10.0, np.array([100.0, 100.0]))
    exact = dropped_sums(pair, 15.0, 100.0).max()
    assert exact == pytest.approx(20.2**-6) and far_field_bound(counts, size, 1.0, 15.0) >= exact


# --------------------------------------------------------------------------- the thesis scheme's law


@pytest.mark.parametrize("dt", [0.26, 2.6, 26.0])  # tau/100, tau/10, tau: weights up to >> 1
def test_thesis_step_probabilities_match_enumeration(dt):
    rng = np.random.default_rng(0)
    net = exciton_network(board(rng.uniform(0, 60, (7, 2)), 2.0), forster_radius=15.0,
                          traps=np.zeros(7, dtype=bool), efficiency=0.7, cutoff=1e3)
    hop, nonradiative, radiative = step_probabilities(net, dt)
    weights, targets, _ = _event_table(net, dt)
    for i in range(7):
        w = weights[i][weights[i] > 0]
        pi = np.minimum(w, 1.0)
        exact = np.zeros(len(w))
        for flags in itertools.product([False, True], repeat=len(w)):  # every set of possible events
            flags = np.array(flags)
            if flags.any():
                exact[flags] += np.prod(np.where(flags, pi, 1 - pi)) * w[flags] / w[flags].sum()
        ours = np.concatenate([hop[i].toarray().ravel()[targets[i][targets[i] >= 0]],
                               [nonradiative[i], radiative[i]]])
        np.testing.assert_allclose(ours, exact, rtol=1e-11)


def test_thesis_dt_bias_is_first_order():
    net = exciton_network(board(hex_lattice(10)), seed=1, cutoff=40.0)
    exact = lqe_exact(net).lqe
    bias = [lqe_exact(net, scheme="thesis", dt=TAU_NS * f).lqe - exact for f in (0.01, 0.001)]
    assert bias[0] > 0  # the thesis scheme overestimates here (R_F = one diameter)
    assert bias[0] / bias[1] == pytest.approx(10.0, rel=0.05)


# --------------------------------------------------------------------------- Monte Carlo


def test_gillespie_agrees_with_exact_within_three_standard_errors():
    net = exciton_network(board(hex_lattice(12)), seed=7, cutoff=40.0)
    exact = lqe_exact(net).lqe
    mc = lqe_monte_carlo(net, 200_000, seed=11)
    assert mc.method == "gillespie" and mc.standard_error == pytest.approx(math.sqrt(mc.lqe * (1 - mc.lqe) / 2e5))
    assert abs(mc.lqe - exact) < 3 * mc.standard_error


def test_gillespie_with_energy_disorder_and_inefficient_dots():
    positions, radii = random_sequential(200, (300.0, 300.0), sigma=0.1, rng=9)
    net = exciton_network(board(positions, radii), energies="size", efficiency=0.8, seed=2, cutoff=50.0)
    exact = lqe_exact(net).lqe
    mc = lqe_monte_carlo(net, 200_000, seed=3)
    assert abs(mc.lqe - exact) < 3 * mc.standard_error


def test_thesis_monte_carlo_matches_its_exact_law_and_shows_its_bias():
    # At dt = tau/10 the thesis scheme's bias (~+0.003) is far beyond 3 standard errors of 1e5 excitons,
    # and its literal Monte Carlo agrees with the exact law of the scheme.
    net = exciton_network(board(hex_lattice(12)), forster_radius=22.5, seed=1, cutoff=45.0)
    dt = TAU_NS / 10
    exact = lqe_exact(net).lqe
    thesis_exact = lqe_exact(net, scheme="thesis", dt=dt)
    mc = lqe_monte_carlo(net, 100_000, method="thesis", dt=dt, seed=5)
    assert mc.dt == dt and thesis_exact.dt == dt
    assert abs(mc.lqe - thesis_exact.lqe) < 3 * mc.standard_error
    assert abs(mc.lqe - exact) > 5 * mc.standard_error


def test_monte_carlo_is_reproducible_and_traps_count():
    net = exciton_network(board(hex_lattice(5)), trap_fraction=1.0, seed=0)
    assert lqe_monte_carlo(net, 1000, seed=1).lqe == 0.0 and lqe_exact(net).lqe == 0.0
    net = exciton_network(board(hex_lattice(6)), seed=2)
    a, b = lqe_monte_carlo(net, 5000, seed=9), lqe_monte_carlo(net, 5000, seed=9)
    assert a.lqe == b.lqe
    assert lqe_monte_carlo(net, 5000, method="thesis", seed=9).lqe == \
        lqe_monte_carlo(net, 5000, method="thesis", seed=9).lqe


def test_forster_radius_unit_cannot_be_mistaken():
    """R_F is px, or mean radii when asked for by name; a count of radii given as px is refused."""
    b = board(hex_lattice(6))
    default = exciton_network(b, seed=1)
    assert default.forster_radius == 2 * R
    in_radii = exciton_network(b, forster_radii=2.0, seed=1)
    assert in_radii.forster_radius == 2 * R
    assert (in_radii.rates != default.rates).nnz == 0
    assert exciton_network(b, forster_radius=0.5 * R, seed=1).forster_radius == 0.5 * R  # the smallest px value
    with pytest.raises(ValueError, match=r"forster_radius is in px: 1 px is 0\.133 mean radii.*forster_radii=1"):
        exciton_network(b, forster_radius=1.0)
    with pytest.raises(ValueError, match="not both"):
        exciton_network(b, forster_radius=15.0, forster_radii=2.0)
    for bad in (0.0, -1.0, math.inf, True, 1e4):
        with pytest.raises(ValueError, match=r"forster_radii must be in \(0, 1000\] mean radii"):
            exciton_network(b, forster_radii=bad)
    by_radii = film_lqe(b, draws=2, seed=0, forster_radii=1.0)  # film_lqe passes it on
    np.testing.assert_array_equal(by_radii.values, film_lqe(b, draws=2, seed=0, forster_radius=R).values)
    assert by_radii.mean > film_lqe(b, draws=2, seed=0).mean  # shorter R_F, fewer hops to traps


def test_forster_radius_is_bounded_by_what_the_rates_can_hold():
    """R_F**6 overflowed a float (OverflowError) for R_F = 1e300: R_F is bounded in mean radii as forster_radii
    is, and in px on any board; the cutoff and its bound are inf where they exceed a float; no hop may be
    faster than the computation holds."""
    b = board(hex_lattice(4))
    for radius, match in ((1e300, r"forster_radius must be at most 1e9 px, got 1e\+300"),
                          (1001 * R, r"forster_radius must be at most 1000 mean radii \(7500 px on this board\)")):
        with pytest.raises(ValueError, match=match):
            exciton_network(b, forster_radius=radius)
    widest = exciton_network(b, forster_radius=1000 * R, seed=0)
    assert widest.truncation_bound == 0.0 and widest.rates.nnz == 16 * 15  # every pair
    assert cutoff_for(1e300, 1.0, 1e-3) == math.inf and truncation_bound(1e300, 10.0, 1.0) == math.inf
    assert cutoff_for(15.0, 1e-200, 1e-3) == math.inf  # (h * h underflowed to 0)
    with pytest.raises(ValueError, match=r"would hop at 1e\d+ per ns, more than the 1e200 the computation holds"):
        exciton_network(b, tau=1e-300)


def test_film_lqe_averages_trap_draws():
    b = board(hex_lattice(10))
    avg = film_lqe(b, draws=4, seed=3)
    again = film_lqe(b, draws=4, seed=3)
    np.testing.assert_array_equal(avg.values, again.values)
    assert avg.mean == pytest.approx(avg.values.mean()) and avg.standard_error > 0
    assert len(set(avg.values)) == 4  # different traps, different LQE
    assert 0 < avg.mean < avg.solution_lqe


@pytest.mark.parametrize("kwargs, message", [
    (dict(forster_radius=-1.0), "forster_radius must be > 0"),
    (dict(trap_fraction=1.5), r"trap_fraction must be in \[0, 1\]"),
    (dict(efficiency=0.0), r"efficiency must be in \(0, 1\]"),
    (dict(energies="colour"), "energies must be"),
    (dict(energies=[1.0, 2.0]), "energies must be 4 finite values"),
    (dict(traps=[1, 0, 1, 0]), "traps must be a boolean array"),
    (dict(traps=[True, False]), "traps must be a boolean array"),
    (dict(cutoff=1.0), "cutoff must exceed"),
    (dict(tau=0.0), "tau must be > 0"),
])
def test_network_rejects_bad_input(kwargs, message):
    with pytest.raises(ValueError, match=message):
        exciton_network(board(hex_lattice(2)), **kwargs)


def test_lqe_rejects_bad_input():
    net = exciton_network(board(hex_lattice(3)), seed=0)
    with pytest.raises(ValueError, match="scheme must be"):
        lqe_exact(net, scheme="euler")
    with pytest.raises(ValueError, match="method must be"):
        lqe_monte_carlo(net, 10, method="kmc")
    with pytest.raises(ValueError, match="n_excitons must be"):
        lqe_monte_carlo(net, 0)
    with pytest.raises(ValueError, match="dt must be > 0"):
        lqe_monte_carlo(net, 10, method="thesis", dt=-1.0)
    with pytest.raises(ValueError, match="ExcitonNetwork"):
        lqe_exact(board(hex_lattice(3)))
    with pytest.raises(ValueError, match="share a centre"):
        exciton_network(board([[0, 0], [0, 0]]))


def periodic_lattice(m: int = 16, pitch: float = 15.0):
    """A close-packed hexagonal patch that tiles its box (m even: row m continues row 0)."""
    box = (m * pitch, m * pitch * math.sqrt(3) / 2)
    points = hexagonal_lattice(m, pitch) + [pitch / 4, pitch / 4]
    return qdots.State(time=0.0, positions=points, velocities=np.zeros_like(points), radii=np.full(len(points), 7.5),
                       masses=np.ones(len(points)), box=box, walls=np.zeros((0, 4)), closed=False)


def test_a_periodic_lattice_has_no_edge_dots():
    state = periodic_lattice()
    periodic = exciton_network(state, cutoff=50.0, periodic=True, trap_fraction=0.0)
    open_board = exciton_network(state, cutoff=50.0, trap_fraction=0.0)
    total = periodic.total_rates()
    assert np.ptp(total) <= 1e-12 * total.max()  # every dot sees the same endless lattice
    assert open_board.total_rates().min() < 0.6 * total.max()  # a corner dot sees a quarter of it
    # the nearest neighbours across the box's edges are one pitch away, six for every dot
    nearest = (periodic.rates >= periodic.rates.max() * (1 - 1e-12)).sum(axis=1)
    np.testing.assert_array_equal(np.asarray(nearest).ravel(), 6)


def test_periodic_edges_lower_the_film_lqe_and_keep_the_cutoff_below_half_the_box():
    state = periodic_lattice()
    open_lqe = film_lqe(state, draws=4, seed=3, cutoff=50.0).mean
    periodic_lqe = film_lqe(state, draws=4, seed=3, cutoff=50.0, periodic=True).mean
    assert periodic_lqe < open_lqe  # edge dots have fewer partners, so excitons on them reach traps less
    with pytest.raises(ValueError, match="below half the box's shorter side"):
        exciton_network(state, cutoff=state.box[1] / 2, periodic=True)
