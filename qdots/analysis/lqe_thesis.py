"""The thesis's fixed-time-step exciton Monte Carlo (Appendix A ``determineRadiated``), and its exact law.

One step of length ``dt`` (thesis ``tau/100``) on a radiative dot: every hop
``j`` of the network (the pairs within its cutoff; the Java loops over every
dot, whose far hops the cutoff bound covers) is *possible* when a fresh
uniform number falls below its weight
``w_j = dt W_ij``, radiation when one falls below ``dt / tau`` (and, here,
non-radiative decay when one falls below ``dt k_nr``). If anything is
possible, one of the possible events is chosen with probability proportional
to its weight; otherwise the exciton stays. (Weights are not clipped at 1,
as in the Java.) An exciton on a trap is lost.

This is a discrete-time Markov chain whose step probabilities are not
``w_e``: two events possible in the same step compete, which biases the
branching by O(dt). `step_probabilities` gives the chain's exact law::

    P(e chosen) = pi_e E[w_e / (w_e + sum_{f != e} B_f w_f)]
                = pi_e w_e int_0^inf exp(-t w_e) prod_{f != e} (1 - pi_f + pi_f exp(-t w_f)) dt,

with ``pi = min(w, 1)`` and ``B_f`` the Bernoulli(pi_f) "possible" flags
(``1/a = int_0^inf exp(-t a) dt``). So the thesis method's expected LQE is
computed exactly (`qdots.analysis.lqe.lqe_exact` with ``scheme="thesis"``), and its
dt bias against the continuous-time chain follows with no sampling noise.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse
from tqdm.auto import tqdm

from labrig.validate import InputError, count, is_real, number, real

from .forster import ExcitonNetwork

#: Step of the trapezoidal rule in log-time, and the span of the log-time grid.
_LOG_STEP = 0.08
_LOG_LOW = -23.0   # t >= e^-23 / (sum of weights): the part below is added analytically
_LOG_HIGH = 4.0    # t <= e^4 / (smallest weight) (the integrand is below exp(-54) there)
#: Range of the time step of the Monte Carlo, in radiative lifetimes: from 10^4 times finer than the
#: thesis's tau / 100 (10^6 steps a lifetime) to 1000 lifetimes (every weight far above 1; the tests go to 1).
DT_FRACTION_RANGE = (1e-6, 1e3)
#: Most exciton steps of one Monte Carlo run, counted as excitons x radiative lifetime / ``dt``: 10^8
#: excitons at the thesis's tau / 100 (the method runs ~10^7 exciton steps a second).
MAX_THESIS_STEPS = 10_000_000_000
#: Largest ``block`` of `step_probabilities` and `thesis_walks`, values per chunk: 8 bytes each in about six
#: temporaries, 1 GB (the defaults are 1e6 and 2e6).
MAX_BLOCK = 20_000_000


def check_dt(network: ExcitonNetwork, dt) -> float:
    """``dt`` (ns) as a float if it is within `DT_FRACTION_RANGE` radiative lifetimes of ``network``;
    `InputError` naming it otherwise."""
    if not (is_real(dt) and math.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be > 0 ns, got {dt!r}")
    low, high = (fraction / network.radiative_rate for fraction in DT_FRACTION_RANGE)
    return real("dt", dt, low, high, unit=f"ns ({number(DT_FRACTION_RANGE[0])} to {number(DT_FRACTION_RANGE[1])} "
                                         f"radiative lifetimes)")


def check_walks(network: ExcitonNetwork, n_excitons: int, dt: float, name: str = "n_excitons") -> None:
    """`InputError` when ``n_excitons`` walks at step ``dt`` ns come to more than `MAX_THESIS_STEPS` exciton
    steps of a radiative lifetime."""
    steps = n_excitons / (dt * network.radiative_rate)
    if steps > MAX_THESIS_STEPS:
        raise InputError(f"{name} = {n_excitons:,} at dt = {dt:g} ns is {steps:.3g} exciton steps of a radiative "
                         f"lifetime, more than the {MAX_THESIS_STEPS:,} allowed: use fewer excitons or a longer dt")


def drop_trapped(network: ExcitonNetwork, alive: np.ndarray, site: np.ndarray, bar) -> tuple[np.ndarray, np.ndarray]:
    """The walking excitons ``alive`` (at ``site``) that are not on a trap (a trap takes an exciton without
    emission); ``bar`` (a tqdm bar) counts those that end there.

    Returns
    -------
    alive, site : ndarray
        The excitons still walking, and their sites.
    """
    living = ~network.traps[site]
    bar.update(int((~living).sum()))
    return alive[living], site[living]


def _event_table(network: ExcitonNetwork, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per dot, the weights ``dt * rate`` of its events, padded: hops first, then non-radiative, radiative.

    Returns ``weights (N, L + 2)``, ``targets (N, L)`` (-1 = padding), row lengths ``(N,)``.
    """
    rates = network.rates
    n = network.n_dots
    lengths = np.diff(rates.indptr)
    width = int(lengths.max()) if n else 0
    weights = np.zeros((n, width + 2))
    targets = np.full((n, width), -1, dtype=np.intp)
    rows = np.repeat(np.arange(n), lengths)
    cols = np.arange(rates.nnz) - np.repeat(rates.indptr[:-1], lengths)
    weights[rows, cols] = dt * rates.data
    targets[rows, cols] = rates.indices
    weights[:, width] = dt * network.nonradiative_rate
    weights[:, width + 1] = dt * network.radiative_rate
    return weights, targets, lengths


def step_probabilities(network: ExcitonNetwork, dt: float, block: int = 1_000_000
                       ) -> tuple[sparse.csr_matrix, np.ndarray, np.ndarray]:
    """Exact one-step probabilities of the thesis's algorithm on every dot.

    The integral of the module docstring is taken in ``u = log t`` with the
    trapezoidal rule (step 0.08 over ``[e^-23, e^4 / w_min]``), which for
    this smooth, doubly exponentially decaying integrand is accurate to about
    1e-12 relative (tested against enumeration of every subset of events).

    Parameters
    ----------
    network : ExcitonNetwork
    dt : float
        Time step, ns (> 0).
    block : int
        Work per chunk of rows (nodes x rows x events), bounds memory; at most `MAX_BLOCK`.

    Returns
    -------
    hop : csr_matrix, shape (N, N)
        Probability that one step moves the exciton from i to j.
    nonradiative, radiative : ndarray, shape (N,)
        Probability that one step ends the exciton without / with light.
    """
    if not (is_real(dt) and math.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be > 0 ns, got {dt!r}")
    block = count("block", block, 1, MAX_BLOCK)
    weights, _, _ = _event_table(network, dt)
    n, width = weights.shape
    if n == 0:
        return sparse.csr_matrix((0, 0)), np.zeros(0), np.zeros(0)
    positive = weights[weights > 0]
    total = weights.sum(axis=1)
    span = _LOG_HIGH + np.log(total.max() / positive.min()) - _LOG_LOW
    u = _LOG_LOW + _LOG_STEP * np.arange(int(np.ceil(span / _LOG_STEP)) + 1)
    quad = np.full(len(u), _LOG_STEP)
    quad[[0, -1]] *= 0.5
    prob = np.zeros_like(weights)
    rows_per_block = max(1, block // (len(u) * width))
    for start in range(0, n, rows_per_block):
        w = weights[start:start + rows_per_block]                      # (R, E)
        pi = np.minimum(w, 1.0)
        t = np.exp(u)[:, None, None] / total[start:start + rows_per_block][None, :, None]   # (U, R, 1)
        exponent = -t * w[None]                                         # (U, R, E)
        with np.errstate(divide="ignore"):
            factor = np.where(pi[None] >= 1.0, exponent,                 # log E[exp(-t B w)]
                              np.log1p(-pi[None] * -np.expm1(exponent)))
        others = factor.sum(axis=2, keepdims=True) - factor
        integrand = np.exp(exponent + others + np.log(t))                # dt = t du
        below = t[0] * 1.0                                               # int_0^t0 of ~1
        prob[start:start + rows_per_block] = pi * w * ((integrand * quad[:, None, None]).sum(axis=0) + below)
    hops = width - 2
    rates = network.rates
    lengths = np.diff(rates.indptr)
    cols = np.arange(rates.nnz) - np.repeat(rates.indptr[:-1], lengths)
    hop = sparse.csr_matrix((prob[np.repeat(np.arange(n), lengths), cols], rates.indices, rates.indptr),
                            shape=(n, n))
    return hop, prob[:, hops], prob[:, hops + 1]


def thesis_walks(network: ExcitonNetwork, starts: np.ndarray, dt: float, rng: np.random.Generator,
                 block: int = 2_000_000, progress: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Run the thesis's algorithm, literally, for excitons starting on ``starts``.

    Vectorized over excitons: each step draws one uniform number per event of
    every living exciton, as the Java does per exciton. ``dt`` (ns) must be within
    `DT_FRACTION_RANGE` radiative lifetimes, the walks at most `MAX_THESIS_STEPS` exciton steps of a
    lifetime, ``block`` (values per chunk of excitons) at most `MAX_BLOCK`.

    Returns
    -------
    radiated : ndarray of bool
        Whether each exciton emitted.
    steps : ndarray of int
        Steps each exciton lived (its lifetime in units of ``dt``).
    """
    dt = check_dt(network, dt)
    check_walks(network, len(starts), dt, "starts")
    block = count("block", block, 1, MAX_BLOCK)
    weights, targets, _ = _event_table(network, dt)
    width = targets.shape[1]
    radiated = np.zeros(len(starts), dtype=bool)
    steps = np.zeros(len(starts), dtype=np.int64)
    chunk = max(1, block // (width + 2))
    bar = tqdm(total=len(starts), desc="thesis MC", unit="exciton", disable=not progress)
    for first in range(0, len(starts), chunk):
        alive = np.arange(first, min(first + chunk, len(starts)))
        site = starts[alive].copy()
        while alive.size:
            alive, site = drop_trapped(network, alive, site, bar)
            if not alive.size:
                break
            steps[alive] += 1
            w = weights[site]
            cumulative = np.cumsum(np.where(rng.random(w.shape) < w, w, 0.0), axis=1)  # possible events
            total = cumulative[:, -1]
            pick = rng.random(len(site)) * total
            moved = total > 0
            event = np.minimum((cumulative <= pick[:, None]).sum(axis=1), width + 1)  # first cum > pick
            event[~moved] = -1
            emits = event == width + 1
            radiated[alive[emits]] = True
            ends = (event >= width)
            hops = moved & ~ends
            site[hops] = targets[site[hops], event[hops]]
            bar.update(int(ends.sum()))
            alive, site = alive[~ends], site[~ends]
    bar.close()
    return radiated, steps
