"""The exciton's absorbing Markov chain solved for its yields, several trap draws at once.

For one set of radiative dots ``good``, the probability ``x_i`` that an exciton on dot ``i`` ends by emitting
solves ``out_i x_i - sum_{j good} hop_ij x_j = emit_i`` on the good dots (``x = 0`` on traps): `absorbing_yields`.
The hop rates are the same for every trap draw of a board; only ``good`` changes. So the draws of one board are
solved side by side, as the columns of one block: each product with the hop matrix reads the matrix once for two
draws (`hop_products`; the matrix, some 180 partners a dot, is what a product spends its time reading) in two
threads by rows.

Where the system is symmetric after a diagonal scaling (detailed balance: ``scale_i hop_ij / scale_j`` symmetric)
it is solved by Jacobi-preconditioned conjugate gradients, column by column in lockstep; otherwise (the thesis's
fixed-step chain), or where a column does not converge, by a sparse LU factorisation. Each column's error is bounded
rigorously from its residual (Varah: ``|x - x*|_inf <= |r|_inf / m``, ``m`` the smallest diagonal surplus of the
good rows, ``out_i - sum_{j good} hop_ij``).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve

from labrig.compiled import jit
from labrig.threads import available_threads, row_ranges, run_in_threads

#: Relative residual (2-norm, each draw's own) at which conjugate gradients stop: the yields to round-off (1e-11
#: left errors of 3e-9 on a board with energy disorder, whose scaling widens the system's spread of values).
CG_RTOL = 1e-13


@jit
def hop_products(indptr, indices, data, x, y, start, stop):
    """``y[i] = sum_j data_ij x[j]`` for the rows ``start <= i < stop`` of a CSR matrix, for every column of ``x`` and
    ``y`` (C-ordered (N, M) arrays), two columns for each read of a row."""
    m = x.shape[1]
    for i in range(start, stop):
        for k in range(0, m - 1, 2):
            s0 = 0.0
            s1 = 0.0
            for jj in range(indptr[i], indptr[i + 1]):
                a = data[jj]
                j = indices[jj]
                s0 += a * x[j, k]
                s1 += a * x[j, k + 1]
            y[i, k] = s0
            y[i, k + 1] = s1
        if m % 2:
            s = 0.0
            for jj in range(indptr[i], indptr[i + 1]):
                s += data[jj] * x[indices[jj], m - 1]
            y[i, m - 1] = s


def product(matrix: sparse.csr_matrix, data: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``matrix`` with its values replaced by ``data`` times ``x`` ((N, M)), by rows in threads (`hop_products`)."""
    x = np.ascontiguousarray(x)
    y = np.empty_like(x)
    run_in_threads(lambda rows: hop_products(matrix.indptr, matrix.indices, data, x, y, *rows),
                   row_ranges(matrix.shape[0], available_threads(), least=1024))
    return y


def column_norms(x: np.ndarray) -> np.ndarray:
    """The 2-norm of each column of ``x``."""
    return np.sqrt(np.einsum("ij,ij->j", x, x))


def block_cg(matrix: sparse.csr_matrix, data: np.ndarray, out: np.ndarray, rhs: np.ndarray, good: np.ndarray,
             rtol: float, maxiter: int) -> tuple[np.ndarray, np.ndarray]:
    """Jacobi-preconditioned conjugate gradients on each column ``c`` of ``rhs``: ``out y - good_c (S y) = rhs_c``
    with ``S`` the symmetric matrix ``matrix`` with values ``data``, ``rhs`` zero off ``good`` (so is every
    iterate). The columns run in lockstep; each stops at ``|r| <= rtol |rhs_c|``. Returns the solutions and which
    columns converged within ``maxiter`` products."""
    x = np.zeros_like(rhs)
    r = rhs.copy()
    target = rtol * column_norms(rhs)
    done = column_norms(r) <= target
    z = r / out[:, None]
    p = z.copy()
    rz = np.einsum("ij,ij->j", r, z)
    for _ in range(maxiter):
        if done.all():
            break
        q = out[:, None] * p - good * product(matrix, data, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            alpha = np.where(done, 0.0, rz / np.einsum("ij,ij->j", p, q))
        x += alpha * p
        r -= alpha * q
        done |= column_norms(r) <= target
        z = r / out[:, None]
        rz_new = np.einsum("ij,ij->j", r, z)
        with np.errstate(divide="ignore", invalid="ignore"):
            beta = np.where(done, 0.0, rz_new / rz)
        p = z + beta * p
        rz = rz_new
    return x, done


def absorbing_yields(out: np.ndarray, hop: sparse.csr_matrix, emit: np.ndarray, good: np.ndarray,
                     scale: np.ndarray | None, rtol: float = CG_RTOL) -> tuple[np.ndarray, np.ndarray]:
    """Emission probability of an exciton on each dot, for each column of ``good`` (a set of radiative dots).

    Parameters
    ----------
    out : ndarray (N,)
        Each dot's total rate (or probability) of leaving it, hops to traps included.
    hop : csr_matrix (N, N)
        Hop rates (or probabilities) ``i -> j``, non-negative, indices sorted.
    emit : ndarray (N,)
        Each dot's rate (or probability) of emitting.
    good : ndarray of bool (N, M)
        The radiative dots of each of M draws (the others are traps: ``x = 0``).
    scale : ndarray (N,) or None
        A scaling that makes the system symmetric (``scale_i hop_ij / scale_j = scale_j hop_ji / scale_i``): then
        conjugate gradients (`block_cg`); None: a sparse LU factorisation per draw.
    rtol : float
        Conjugate gradients' relative residual.

    Returns
    -------
    yields : ndarray (N, M)
        Each draw's emission probabilities (0 on its traps).
    bounds : ndarray (M,)
        Each draw's Varah bound on its yields' error (max residual over the smallest diagonal surplus).
    """
    n, draws = good.shape
    weights = good.astype(float)
    rhs = weights * emit[:, None]
    x = np.zeros((n, draws))
    solved = np.zeros(draws, dtype=bool)
    if scale is not None and n:
        symmetric = hop.data if np.all(scale == 1.0) else \
            hop.data * (np.repeat(scale, np.diff(hop.indptr)) / scale[hop.indices])  # scale_i hop_ij / scale_j
        y, solved = block_cg(hop, symmetric, out, scale[:, None] * rhs, weights, rtol, 20 * n + 100)
        x = y / scale[:, None]
    for c in np.flatnonzero(~solved):  # the thesis's chain, or a draw the gradients did not solve
        mask = good[:, c]
        inner = sparse.diags(mask.astype(float)) @ hop @ sparse.diags(mask.astype(float))
        x[:, c] = np.atleast_1d(spsolve((sparse.diags(out) - inner).tocsc(), rhs[:, c]))
    x[~good] = 0.0
    residual = np.where(good, np.abs(rhs - (out[:, None] * x - weights * product(hop, hop.data, x))), 0.0)
    surplus = np.where(good, out[:, None] - weights * product(hop, hop.data, weights), np.inf)
    bounds = np.where(good.any(axis=0), residual.max(axis=0, initial=0.0) / surplus.min(axis=0, initial=np.inf), 0.0)
    return x, bounds
