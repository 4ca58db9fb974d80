"""Luminescence quantum efficiency (LQE) of a board: exact, and by Monte Carlo.

The LQE is the fraction of excitons, each created on a dot drawn uniformly
(traps included, as the Java does), that end by emitting light. The model and
its rates are in `qdots.analysis.forster`. Three ways to compute it, all on one
`qdots.analysis.forster.ExcitonNetwork` (same pairs, same traps):

* `lqe_exact` (``scheme="continuous"``): the exciton is an absorbing Markov
  chain; the probability ``x_i`` that an exciton on radiative dot ``i`` emits
  solves ``K_i x_i - sum_{j radiative} W_ij x_j = k_r`` with
  ``K_i = k_r + k_nr + sum_j W_ij``. The matrix is symmetric after scaling
  by ``exp(-E_i / 2kT)`` (detailed balance) and diagonally dominant, so
  conjugate gradients (Jacobi-preconditioned) solve it to round-off; the
  residual gives a rigorous error bound (Varah: ``|x - x*|_inf <= |r|_inf / m``,
  ``m`` the smallest diagonal surplus, at least ``k_r + k_nr``). The solver is
  `qdots.analysis.chain`; `film_lqe`'s trap draws are solved side by side.
* ``scheme="thesis"``: the same for the thesis's fixed-``dt`` algorithm,
  using its exact step law (`qdots.analysis.lqe_thesis.step_probabilities`). The
  difference between the two is the thesis method's ``dt`` bias, free of noise.
* `lqe_monte_carlo`: ``method="gillespie"`` (continuous-time kinetic Monte
  Carlo: each event drawn with probability rate / total rate; no time step,
  no bias) or ``method="thesis"`` (the Java's algorithm, literally). Results
  carry the binomial standard error ``sqrt(p (1 - p) / n)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from tqdm.auto import tqdm

from labrig.validate import InputError, count

from ..limits import MAX_DRAWS  # noqa: F401 (public here too)
from .chain import absorbing_yields
from .forster import KB_EV, TRAP_FRACTION, ExcitonNetwork, draw_traps, exciton_network
from .lqe_thesis import check_dt, check_walks, drop_trapped, step_probabilities, thesis_walks

#: The thesis's Monte Carlo time step, in units of the radiative lifetime.
THESIS_DT_FRACTION = 0.01
#: Most excitons of one Monte Carlo run: about 100 bytes each in the walk's arrays (1 GB), a standard
#: error of 1.6e-4 at most (the tests take 2e5, the benchmark 1e6).
MAX_EXCITONS = 10_000_000
METHODS = ("gillespie", "thesis")
SCHEMES = ("continuous", "thesis")
#: Trap draws `film_lqe` solves side by side (`qdots.analysis.chain`): each product reads the hop matrix once for two.
DRAW_BLOCK = 8


@dataclass(frozen=True)
class LQEResult:
    """One LQE value with its errors.

    Attributes
    ----------
    lqe : float
        Fraction of excitons that emit.
    standard_error : float
        Statistical error (Monte Carlo); 0 for exact results.
    error_bound : float
        Bound on the systematic error: the network's pair-cutoff bound, plus
        (exact) the linear solver's residual bound.
    method : str
        ``"exact"``, ``"exact-thesis"``, ``"gillespie"`` or ``"thesis"``.
    n_excitons : int
        Excitons simulated (0 for exact).
    yields : ndarray, shape (N,), or None
        Exact only: probability that an exciton created on each dot emits (0 on traps).
    dt : float or None
        Time step of the thesis scheme, ns.
    """

    lqe: float
    standard_error: float
    error_bound: float
    method: str
    n_excitons: int = 0
    yields: np.ndarray | None = None
    dt: float | None = None


def _thesis_dt(network: ExcitonNetwork, dt) -> float:
    """The thesis scheme's time step, ns: ``dt`` (`qdots.analysis.lqe_thesis.check_dt`), or the thesis's tau / 100."""
    return THESIS_DT_FRACTION / network.radiative_rate if dt is None else check_dt(network, dt)


def _check_network(network) -> ExcitonNetwork:
    if not isinstance(network, ExcitonNetwork):
        raise InputError(f"network must be a qdots.analysis.forster.ExcitonNetwork (see exciton_network), "
                         f"got {type(network).__name__}")
    return network


def lqe_exact(network: ExcitonNetwork, scheme: str = "continuous", dt: float | None = None) -> LQEResult:
    """The LQE of a network, exactly (for its traps and pairs).

    Parameters
    ----------
    network : ExcitonNetwork
        From `qdots.analysis.forster.exciton_network`.
    scheme : {"continuous", "thesis"}
        ``"continuous"``: the physical continuous-time chain. ``"thesis"``:
        the expectation of the thesis's fixed-step algorithm.
    dt : float, optional
        Thesis scheme only: time step, ns (default ``tau / 100``, the thesis).

    Returns
    -------
    LQEResult
        With ``yields``, the emission probability of an exciton created on each dot.
    """
    network = _check_network(network)
    if scheme not in SCHEMES:
        raise InputError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    if network.n_dots == 0:
        raise InputError("the board has no dots")
    return _exact_draws(network, ~network.traps[:, None], scheme, dt)[0]


def _exact_draws(network: ExcitonNetwork, good: np.ndarray, scheme: str = "continuous",
                 dt: float | None = None) -> list[LQEResult]:
    """`lqe_exact` of ``network`` with the radiative dots of each column of ``good`` (N, M), solved side by side."""
    n = network.n_dots
    if scheme == "continuous":
        scale = np.ones(n) if network.energies is None else \
            np.exp(-(network.energies - network.energies.mean()) / (2 * KB_EV * network.temperature))
        yields, bounds = absorbing_yields(network.total_rates(), network.rates, np.full(n, network.radiative_rate),
                                          good, scale)
        step = None
    else:
        step = _thesis_dt(network, dt)
        hop, nonradiative, radiative = step_probabilities(network, step)
        out = radiative + nonradiative + np.asarray(hop.sum(axis=1)).ravel()
        yields, bounds = absorbing_yields(out, hop, radiative, good, None)
    method = "exact" if scheme == "continuous" else "exact-thesis"
    return [LQEResult(float(yields[:, c].mean()), 0.0, network.truncation_bound + bounds[c] * float(np.mean(good[:, c])),
                      method, 0, np.ascontiguousarray(yields[:, c]), step) for c in range(good.shape[1])]


def _hop_keys(rates: sparse.csr_matrix) -> np.ndarray:
    """Sorted keys ``row + (cumulative rate within the row) / (row total)``, last of each row exactly ``row + 1``."""
    lengths = np.diff(rates.indptr)
    rows = np.repeat(np.arange(rates.shape[0]), lengths)
    cumulative = np.cumsum(rates.data)
    before = np.concatenate([[0.0], cumulative])[rates.indptr[:-1]]
    totals = np.asarray(rates.sum(axis=1)).ravel()
    keys = rows + (cumulative - np.repeat(before, lengths)) / np.repeat(np.where(totals > 0, totals, 1.0), lengths)
    last = rates.indptr[1:][lengths > 0] - 1
    keys[last] = np.arange(rates.shape[0])[lengths > 0] + 1.0
    return keys


def gillespie_walks(network: ExcitonNetwork, starts: np.ndarray, rng: np.random.Generator,
                    progress: bool = False) -> np.ndarray:
    """Continuous-time kinetic Monte Carlo of excitons starting on ``starts``; whether each emitted.

    Each event of the current dot is drawn with probability rate / total rate
    (the embedded jump chain: the waiting times do not change the yield).
    Hops are located by one binary search in per-row cumulative keys; their
    float resolution (~1e-16 times the number of dots) limits the smallest
    hop probability represented to ~1e-11 per event for 10^5 dots.
    """
    rates = network.rates
    keys = _hop_keys(rates)
    hop_total = np.asarray(rates.sum(axis=1)).ravel()
    k_r, k_nr = network.radiative_rate, network.nonradiative_rate
    total = k_r + k_nr + hop_total
    radiated = np.zeros(len(starts), dtype=bool)
    alive = np.arange(len(starts))
    site = np.asarray(starts).copy()
    bar = tqdm(total=len(starts), desc="Gillespie", unit="exciton", disable=not progress)
    while alive.size:
        alive, site = drop_trapped(network, alive, site, bar)
        if not alive.size:
            break
        u = rng.random(len(site)) * total[site]
        emits = u < k_r
        radiated[alive[emits]] = True
        ends = u < k_r + k_nr
        bar.update(int(ends.sum()))
        alive, site, u = alive[~ends], site[~ends], u[~ends]
        fraction = (u - k_r - k_nr) / np.where(hop_total[site] > 0, hop_total[site], 1.0)
        entry = np.searchsorted(keys, site + fraction, side="right")
        entry = np.clip(entry, rates.indptr[site], rates.indptr[site + 1] - 1)
        site = rates.indices[entry]
    bar.close()
    return radiated


def lqe_monte_carlo(network: ExcitonNetwork, n_excitons: int = 100_000, method: str = "gillespie", *,
                    dt: float | None = None, seed=None, progress: bool = False) -> LQEResult:
    """The LQE of a network by Monte Carlo, with its standard error.

    Parameters
    ----------
    network : ExcitonNetwork
    n_excitons : int
        Excitons to create, in [1, `MAX_EXCITONS`], each on a dot drawn uniformly (the thesis method
        also takes at most `qdots.analysis.lqe_thesis.MAX_THESIS_STEPS` exciton steps,
        ``n_excitons * tau / dt``).
    method : {"gillespie", "thesis"}
        ``"gillespie"``: continuous-time kinetic MC (no time-step bias).
        ``"thesis"``: the Java's fixed-step algorithm (see `qdots.analysis.lqe_thesis`);
        biased by O(dt), see ``lqe_exact(network, scheme="thesis")``.
    dt : float, optional
        Thesis method only: time step, ns (default ``tau / 100``; within
        `qdots.analysis.lqe_thesis.DT_FRACTION_RANGE` radiative lifetimes).
    seed : int, Generator or SeedSequence, optional
    progress : bool
        tqdm progress bar.
    """
    network = _check_network(network)
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    n_excitons = count("n_excitons", n_excitons, 1, MAX_EXCITONS)
    if network.n_dots == 0:
        raise InputError("the board has no dots")
    step = None if method == "gillespie" else _thesis_dt(network, dt)
    if step is not None:
        check_walks(network, n_excitons, step)
    rng = np.random.default_rng(seed)
    starts = rng.integers(network.n_dots, size=int(n_excitons))
    if method == "gillespie":
        radiated = gillespie_walks(network, starts, rng, progress)
    else:
        assert step is not None  # the thesis method's time step, set above
        radiated, _ = thesis_walks(network, starts, step, rng, progress=progress)
    p = float(radiated.mean())
    return LQEResult(p, math.sqrt(p * (1 - p) / n_excitons), network.truncation_bound, method,
                     int(n_excitons), None, step)


@dataclass(frozen=True)
class TrapAverage:
    """Exact LQE averaged over independent trap draws on one board.

    Attributes
    ----------
    mean, standard_error : float
        Mean over the draws and its standard error (sample std / sqrt(draws)).
    values : ndarray
        Exact LQE of each draw.
    error_bound : float
        Largest systematic bound of the draws (cutoff + solver).
    solution_lqe : float
        Mean LQE without transfer over the same draws.
    first : LQEResult
        The exact result of the first draw (with its per-dot ``yields``).
    first_traps : ndarray of bool
        The traps of the first draw.
    cutoff : float
        Pair cutoff, px.
    """

    mean: float
    standard_error: float
    values: np.ndarray
    error_bound: float
    solution_lqe: float
    first: LQEResult
    first_traps: np.ndarray
    cutoff: float


def film_lqe(state, draws: int = 8, seed=0, **network_options) -> TrapAverage:
    """Exact LQE of a board averaged over ``draws`` random trap assignments (at most `MAX_DRAWS`).

    The pairs and rates are built once (`qdots.analysis.forster.exciton_network`,
    which takes ``network_options``) and only the traps are redrawn, each
    from its own child of ``numpy.random.SeedSequence(seed)``; up to `DRAW_BLOCK`
    draws are solved side by side (`qdots.analysis.chain.absorbing_yields`).
    """
    draws = count("draws", draws, 1, MAX_DRAWS)
    if "traps" in network_options:
        raise InputError("film_lqe draws its own traps: pass trap_fraction, not traps")
    children = np.random.SeedSequence(seed).spawn(int(draws))
    base = exciton_network(state, seed=children[0], **network_options)
    fraction = network_options.get("trap_fraction", TRAP_FRACTION)
    results, solution = [], []
    for first in range(0, draws, DRAW_BLOCK):  # a block of draws solved side by side (`qdots.analysis.chain`)
        traps = np.column_stack([base.traps if k == 0 else draw_traps(base.n_dots, fraction, children[k])
                                 for k in range(first, min(first + DRAW_BLOCK, draws))])
        results += _exact_draws(base, ~traps)
        solution += [base.with_traps(column).solution_lqe for column in traps.T]
    values = np.array([r.lqe for r in results])
    se = float(values.std(ddof=1) / math.sqrt(draws)) if draws > 1 else math.nan
    return TrapAverage(float(values.mean()), se, values, max(r.error_bound for r in results),
                       float(np.mean(solution)), results[0], base.traps, base.cutoff)
