"""The absorbing chain's block solver (`qdots.analysis.chain`) against scipy's sparse products and direct solves."""

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse.linalg import spsolve

from qdots.analysis.chain import absorbing_yields, block_cg, product
from qdots.analysis.forster import KB_EV, draw_traps, exciton_network, pair_matrix
from qdots.analysis.lqe import DRAW_BLOCK, film_lqe, lqe_exact
from qdots.placement import random_sequential
from tests.qdots.test_lqe import board


def film(n=300, seed=2):
    positions, radii = random_sequential(n, (340.0, 340.0), sigma=0.1, rng=seed)
    return board(positions, radii)


def direct(out, hop, emit, good):
    """Each draw's yields by a sparse LU of its own system on its radiative dots (the oracle)."""
    x = np.zeros(good.shape)
    for c in range(good.shape[1]):
        g = good[:, c]
        inner = hop[g][:, g]
        x[g, c] = spsolve((sparse.diags(out[g]) - inner).tocsc(), emit[g])
    return x


@pytest.mark.parametrize("columns", [1, 2, 3, 8])
def test_products_equal_scipy_for_odd_and_even_columns(columns):
    net = exciton_network(film(), seed=1, cutoff=60.0)
    x = np.random.default_rng(0).random((net.n_dots, columns))
    np.testing.assert_allclose(product(net.rates, net.rates.data, x), net.rates @ x, rtol=1e-13, atol=0.0)


@pytest.mark.parametrize("energies", [None, "size"])
def test_a_block_of_draws_equals_each_draw_solved_directly(energies):
    net = exciton_network(film(), seed=1, cutoff=60.0, energies=energies)
    good = ~np.column_stack([draw_traps(net.n_dots, 1 / 3, s) for s in range(5)])
    scale = np.ones(net.n_dots) if energies is None else \
        np.exp(-(net.energies - net.energies.mean()) / (2 * KB_EV * net.temperature))  # detailed balance
    emit = np.full(net.n_dots, net.radiative_rate)
    yields, bounds = absorbing_yields(net.total_rates(), net.rates, emit, good, scale)
    expected = direct(net.total_rates(), net.rates, emit, good)
    np.testing.assert_allclose(yields, expected, rtol=1e-9, atol=1e-12)
    assert np.all(yields[~good] == 0.0)
    assert np.all(bounds >= np.abs(yields - expected).max(axis=0)) and np.all(bounds < 1e-8)  # (as before the block)
    # without the scaling (the thesis's chain is not symmetric): the direct solve, the same yields
    lu, lu_bounds = absorbing_yields(net.total_rates(), net.rates, emit, good, None)
    np.testing.assert_allclose(lu, expected, rtol=1e-9, atol=1e-12)


def test_conjugate_gradients_say_which_draws_did_not_converge():
    net = exciton_network(film(), seed=1, cutoff=60.0)
    good = ~np.column_stack([draw_traps(net.n_dots, 1 / 3, s) for s in range(2)])
    rhs = good * net.radiative_rate
    rhs[:, 1] = 0.0  # nothing to solve: done before the first product
    _, done = block_cg(net.rates, net.rates.data, net.total_rates(), rhs, good.astype(float), 1e-13, 1)
    assert done.tolist() == [False, True]
    _, done = block_cg(net.rates, net.rates.data, net.total_rates(), rhs, good.astype(float), 1e-13, 500)
    assert done.all()


def test_film_lqe_over_more_draws_than_a_block_equals_each_draw_alone():
    b = film(120)
    draws = DRAW_BLOCK + 2
    average = film_lqe(b, draws=draws, seed=5, cutoff=60.0)
    children = np.random.SeedSequence(5).spawn(draws)
    base = exciton_network(b, seed=children[0], cutoff=60.0)
    alone = [lqe_exact(base if k == 0 else base.with_traps(draw_traps(base.n_dots, 1 / 3, children[k]))).lqe
             for k in range(draws)]
    np.testing.assert_allclose(average.values, alone, rtol=1e-12)
    assert len(set(average.values)) == draws


@pytest.mark.parametrize("n, pairs", [(300, 2000), (5, 0), (2, 1)])
def test_the_pair_matrix_equals_two_coo_triangles_added(n, pairs):
    rng = np.random.default_rng(n)
    i, j = np.divmod(np.unique(rng.choice(n * n, size=4 * pairs + 10)), n)
    order = rng.permutation(np.flatnonzero(i < j))[:pairs]  # each unordered pair once, in a shuffled order
    i, j = i[order], j[order]
    forward, backward = rng.random(len(i)), rng.random(len(i))
    oracle = (sparse.coo_matrix((forward, (i, j)), shape=(n, n)).tocsr()
              + sparse.coo_matrix((backward, (j, i)), shape=(n, n)).tocsr())
    oracle.sort_indices()
    built = pair_matrix(n, i, j, forward, backward)
    assert built.has_sorted_indices
    for part in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(built, part), getattr(oracle, part))
