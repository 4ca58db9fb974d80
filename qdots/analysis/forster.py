"""Förster exciton hopping on a board: rates, traps, dot energies (thesis Eq 2.3).

An exciton on dot ``i`` hops to dot ``j`` at the rate (thesis Eq 2.3)::

    W_ij = (1 / tau) (R_F / R_ij)^6 P(E_i, E_j),
    P = exp(-(E_j - E_i) / kT) if E_j > E_i else 1,

with ``R_ij`` the centre distance, ``R_F`` the Förster radius, ``tau`` the
radiative lifetime (26 ns) and ``kT`` at 297 K (the thesis's temperature,
25.6 meV). A radiative dot emits at rate ``1/tau`` and, when its intrinsic
efficiency ``eta`` is below 1, also decays without light at
``(1/eta - 1)/tau``; a trap (a fraction of the dots, 1/3 in the thesis)
quenches an exciton at once. The thesis sets all energies equal (then
``P = 1``); `dot_energies` gives size-dependent ones.

Units: distances px (the thesis's R_F = 15 = one mean diameter), times ns,
rates 1/ns, energies eV.

Only pairs closer than a cutoff get a rate; `qdots.analysis.cutoff` bounds the error that makes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from labrig.compiled import jit
from labrig.validate import InputError, number

from ..limits import MAX_FORSTER_PX, MAX_FORSTER_RADII  # noqa: F401 (public here too)
from ..units import THESIS_TEMPERATURE, PhysicalScale
from .cutoff import (  # noqa: F401 (CUTOFF_TOLERANCE, truncation_bound: public here too)
    CUTOFF_TOLERANCE,
    cutoff_for,
    far_field_bound,
    far_field_grid,
    smallest_cutoff,
    truncation_bound,
)
from .packing import state_arrays

#: Radiative lifetime of a dot, ns (thesis: ``radLife = 26.0``).
TAU_NS = 26.0
#: Boltzmann's constant, eV/K.
KB_EV = 8.617333262e-5
#: Default fraction of trap dots (thesis section 2.3.2).
TRAP_FRACTION = 1.0 / 3.0
#: Smallest ``forster_radius`` accepted in px, in mean radii: below it a number meant as radii or
#: diameters was most likely given as px (hops to a neighbour at one diameter would be < 1/4096 of
#: the radiative rate). Such radii can still be asked for as ``forster_radii``.
MIN_PX_FORSTER_RADII = 0.5
#: Fastest hop rate the computation holds, 1/ns: rates are summed over a dot's partners and inverted, so
#: they must stay far from the float limit (1.8e308). Real films: below 1e18 (R_F 1000x the closest gap).
MAX_HOP_RATE = 1e200

#: CdSe constants of the effective-mass (Brus) model of `dot_energies`: bulk gap (eV, 300 K),
#: electron and hole effective masses (units of the free electron mass), relative permittivity.
CDSE_BANDGAP_EV = 1.74
CDSE_ELECTRON_MASS = 0.13
CDSE_HOLE_MASS = 0.45
CDSE_PERMITTIVITY = 10.6
#: hbar^2 pi^2 / (2 m_e), eV nm^2, and e^2 / (4 pi eps_0), eV nm.
_CONFINEMENT_EV_NM2 = 0.376030
_COULOMB_EV_NM = 1.439965


def dot_energies(radii, nm_per_px: float = PhysicalScale().nm_per_px) -> np.ndarray:
    """Lowest exciton energy of CdSe dots from their radii (effective-mass model), eV.

    ``E(r) = E_g + (hbar^2 pi^2 / 2 r^2)(1/m_e + 1/m_h) - 1.786 e^2 / (4 pi eps0 eps r)``
    (L. E. Brus, J. Chem. Phys. 80, 4403 (1984)), with the CdSe values
    ``E_g = 1.74 eV``, ``m_e = 0.13``, ``m_h = 0.45``, ``eps = 10.6`` as
    commonly quoted for this model. It overestimates the confinement of small
    dots by ~0.1-0.2 eV but gives the right slope: a 5 nm dot is at 2.24 eV
    and dE/dr = -0.43 eV/nm there, so a 5 % spread of sizes spreads the
    energies by ~2 kT at 297 K. Equal radii give equal energies (the thesis).

    Parameters
    ----------
    radii : array_like
        Radii, px (> 0).
    nm_per_px : float
        Pixel size, nm (default `qdots.units.PhysicalScale`: a 15 px dot is 5 nm).
    """
    r = np.asarray(radii, dtype=float) * float(nm_per_px)
    if not np.all(np.isfinite(r) & (r > 0)):
        raise InputError("radii and nm_per_px must be finite and > 0")
    confinement = _CONFINEMENT_EV_NM2 * (1 / CDSE_ELECTRON_MASS + 1 / CDSE_HOLE_MASS) / r**2
    return CDSE_BANDGAP_EV + confinement - 1.786 * _COULOMB_EV_NM / (CDSE_PERMITTIVITY * r)


@dataclass(frozen=True, eq=False)
class ExcitonNetwork:
    """The exciton's world on one board: hop rates within the cutoff, traps, decay rates.

    Build it with `exciton_network`; `qdots.analysis.lqe.lqe_exact` and
    `qdots.analysis.lqe.lqe_monte_carlo` take it, so exact and Monte Carlo answers
    are for the same traps and the same pairs.

    Attributes
    ----------
    rates : scipy.sparse.csr_matrix, shape (N, N)
        Hop rate ``W_ij`` from dot i to dot j, 1/ns (pairs within ``cutoff``).
    traps : ndarray of bool, shape (N,)
    radiative_rate, nonradiative_rate : float
        Decay rates of a radiative dot, 1/ns.
    forster_radius, cutoff : float
        px.
    truncation_bound : float
        Bound on the LQE error from the cutoff (0 if no pair was dropped).
    energies : ndarray, shape (N,), or None
        Dot energies, eV; None when all are equal.
    temperature : float
        K.
    """

    rates: sparse.csr_matrix
    traps: np.ndarray
    radiative_rate: float
    nonradiative_rate: float
    forster_radius: float
    cutoff: float
    truncation_bound: float
    energies: np.ndarray | None
    temperature: float

    @property
    def n_dots(self) -> int:
        return len(self.traps)

    @property
    def efficiency(self) -> float:
        """Intrinsic efficiency of a radiative dot."""
        return self.radiative_rate / (self.radiative_rate + self.nonradiative_rate)

    @property
    def solution_lqe(self) -> float:
        """The LQE without transfer (dilute solution): efficiency times the radiative fraction."""
        return self.efficiency * float(np.mean(~self.traps)) if self.n_dots else math.nan

    def with_traps(self, traps) -> ExcitonNetwork:
        """The same board and rates with other traps (boolean array, shape (N,))."""
        return dataclasses.replace(self, traps=_traps(self.n_dots, 0.0, traps, None))

    def total_rates(self) -> np.ndarray:
        """Total decay-or-hop rate of each dot, 1/ns."""
        return self.radiative_rate + self.nonradiative_rate + np.asarray(self.rates.sum(axis=1)).ravel()


def draw_traps(n: int, trap_fraction: float = TRAP_FRACTION, seed=None) -> np.ndarray:
    """Boolean trap mask: each of ``n`` dots is a trap with probability ``trap_fraction`` (as the Java)."""
    if not (isinstance(trap_fraction, (int, float)) and 0 <= trap_fraction <= 1):
        raise InputError(f"trap_fraction must be in [0, 1], got {trap_fraction!r}")
    return np.random.default_rng(seed).random(n) < trap_fraction


def _traps(n: int, trap_fraction: float, traps, rng) -> np.ndarray:
    if traps is not None:
        traps = np.asarray(traps)
        if traps.shape != (n,) or traps.dtype != bool:
            raise InputError(f"traps must be a boolean array of shape ({n},), got {traps.dtype} {traps.shape}")
        return traps.copy()
    return draw_traps(n, trap_fraction, rng)


def resolve_forster_radius(radii, forster_radius: float | None = None, forster_radii: float | None = None) -> float:
    """``R_F`` in px from one of its two spellings.

    Parameters
    ----------
    radii : array_like
        The dots' radii, px.
    forster_radius : float, optional
        ``R_F``, px. Values below `MIN_PX_FORSTER_RADII` mean radii are refused: they are a
        radius or a diameter count given as px (``forster_radius=1.0`` meant as "one diameter"
        would silently give the solution LQE); give those as ``forster_radii``.
    forster_radii : float, optional
        ``R_F`` in units of the mean dot radius, as the thesis's Fig 2-5 c states it (> 0).

    Returns
    -------
    float
        ``R_F``, px. Neither given: the mean diameter (the thesis), 1 px on an empty board.
    """
    radii = np.asarray(radii, dtype=float)
    mean = float(radii.mean()) if radii.size else math.nan
    if forster_radius is not None and forster_radii is not None:
        raise InputError("give forster_radius (px) or forster_radii (mean radii), not both")
    if forster_radii is not None:
        if not (isinstance(forster_radii, (int, float, np.floating, np.integer)) and not isinstance(forster_radii, bool)
                and math.isfinite(forster_radii) and 0 < forster_radii <= MAX_FORSTER_RADII):
            raise InputError(f"forster_radii must be in (0, {MAX_FORSTER_RADII:g}] mean radii, got {forster_radii!r}")
        return float(forster_radii) * mean if radii.size else 1.0
    if forster_radius is None:
        return 2.0 * mean if radii.size else 1.0
    if not (isinstance(forster_radius, (int, float, np.floating, np.integer)) and not isinstance(forster_radius, bool)
            and math.isfinite(forster_radius) and forster_radius > 0):
        raise InputError(f"forster_radius must be > 0 px, got {forster_radius!r}")
    if forster_radius > MAX_FORSTER_PX:
        raise InputError(f"forster_radius must be at most {number(MAX_FORSTER_PX)} px, got {forster_radius!r}")
    if radii.size and forster_radius < MIN_PX_FORSTER_RADII * mean:
        raise InputError(f"forster_radius is in px: {forster_radius:g} px is {forster_radius / mean:.3g} mean radii "
                         f"(< {MIN_PX_FORSTER_RADII:g}); for R_F in mean radii pass forster_radii={forster_radius:g}")
    if radii.size and forster_radius > MAX_FORSTER_RADII * mean:
        raise InputError(f"forster_radius must be at most {MAX_FORSTER_RADII:g} mean radii "
                         f"({MAX_FORSTER_RADII * mean:g} px on this board), got {forster_radius:g} px")
    return float(forster_radius)


@jit
def transposed_buckets(n, i, j, forward, backward):
    """The matrix with ``forward[p]`` at ``(i[p], j[p])`` and ``backward[p]`` at ``(j[p], i[p])``, as the arrays
    (indptr, indices, data) of its compressed columns: column by column, each entry placed in the order of the pairs
    (two passes over the pairs: the entries counted, then put in place)."""
    indptr = np.zeros(n + 1, np.int64)
    for p in range(len(i)):
        indptr[i[p] + 1] += 1
        indptr[j[p] + 1] += 1
    for k in range(n):
        indptr[k + 1] += indptr[k]
    cursor = indptr[:-1].copy()
    indices = np.empty(indptr[n], np.int32)  # dot numbers (a board has far fewer than 2^31 dots)
    data = np.empty(indptr[n])
    for p in range(len(i)):
        a = i[p]
        b = j[p]
        indices[cursor[a]] = b  # column a holds (j -> i) = backward
        data[cursor[a]] = backward[p]
        cursor[a] += 1
        indices[cursor[b]] = a  # column b holds (i -> j) = forward
        data[cursor[b]] = forward[p]
        cursor[b] += 1
    return indptr, indices, data


def pair_matrix(n: int, i: np.ndarray, j: np.ndarray, forward: np.ndarray, backward: np.ndarray) -> sparse.csr_matrix:
    """The (N, N) matrix with ``forward`` at the pairs ``(i, j)`` and ``backward`` at ``(j, i)`` (each unordered pair
    once), in CSR with sorted indices: its columns filled in the pairs' order (`transposed_buckets`), then turned into
    rows, which comes out sorted (a third of the time of two COO triangles added and sorted)."""
    indptr, indices, data = transposed_buckets(n, np.asarray(i, np.int64), np.asarray(j, np.int64),
                                               np.asarray(forward, float), np.asarray(backward, float))
    if indptr[-1] < np.iinfo(np.int32).max:  # the index type scipy takes for such a matrix
        indptr = indptr.astype(np.int32)
    else:
        indices = indices.astype(np.int64)
    rates = sparse.csc_matrix((data, indices, indptr), shape=(n, n)).tocsr()
    rates.sort_indices()  # (already sorted: a no-op but for its check)
    return rates


def exciton_network(state, forster_radius: float | None = None, trap_fraction: float = TRAP_FRACTION, *,
                    forster_radii: float | None = None, traps=None, seed=None, efficiency: float = 1.0,
                    tau: float = TAU_NS, energies=None,
                    temperature: float = THESIS_TEMPERATURE, cutoff: float | None = None,
                    tolerance: float = CUTOFF_TOLERANCE, periodic: bool = False) -> ExcitonNetwork:
    """Hop rates, traps and decay rates of a board.

    Parameters
    ----------
    state : State
        The board (``positions``, ``radii`` in px).
    forster_radius : float, optional
        ``R_F``, px, at least `MIN_PX_FORSTER_RADII` mean radii. Default: the mean diameter (the
        thesis). See `resolve_forster_radius`.
    trap_fraction : float
        Each dot is a trap with this probability, drawn from ``seed`` (thesis 1/3).
    forster_radii : float, optional
        ``R_F`` in units of the mean dot radius (Fig 2-5 c's unit), instead of ``forster_radius``.
    traps : array of bool, optional
        Explicit traps (overrides ``trap_fraction``).
    seed : int, Generator or SeedSequence, optional
        Randomness of the trap draw.
    efficiency : float
        Intrinsic quantum efficiency of a radiative dot, (0, 1] (thesis 1).
    tau : float
        Radiative lifetime, ns (> 0; thesis 26).
    energies : None, "size" or array_like
        None (default, the thesis): all equal. ``"size"``: `dot_energies` of
        the radii. An array: energies in eV, shape (N,).
    temperature : float
        K (> 0; thesis 297).
    cutoff : float, optional
        Pair cutoff, px. Default: the smallest (`qdots.analysis.cutoff.smallest_cutoff`) where the
        smaller of `truncation_bound` and `far_field_bound` is at most ``tolerance``.
    tolerance : float
        Bound on the LQE error from the cutoff when ``cutoff`` is not given.
    periodic : bool
        Treat ``state.box`` as periodic: distances are minimum-image ones, so a finite patch of a
        film stands for an endless one (no edge dots, which on an open board have fewer partners
        and raise the LQE). The cutoff must then be below half the box's shorter side (each pair
        has one image within it). Use it for ideal lattices (the thesis's "close-packed monolayer");
        deposited films have real edges: keep them open (the default).
    """
    positions, radii = state_arrays(state)
    n = len(radii)
    forster_radius = resolve_forster_radius(radii, forster_radius, forster_radii)
    for name, value in (("tau", tau), ("temperature", temperature),
                        ("tolerance", tolerance)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be > 0, got {value!r}")
    if not (isinstance(efficiency, (int, float)) and 0 < efficiency <= 1):
        raise InputError(f"efficiency must be in (0, 1], got {efficiency!r}")
    is_trap = _traps(n, trap_fraction, traps, seed)
    if isinstance(energies, str):
        if energies != "size":
            raise InputError(f"energies must be None, 'size' or an array of eV, got {energies!r}")
        energies = dot_energies(radii)
    elif energies is not None:
        energies = np.asarray(energies, dtype=float)
        if energies.shape != (n,) or not np.all(np.isfinite(energies)):
            raise InputError(f"energies must be {n} finite values, eV, got shape {energies.shape}")
    k_r = 1.0 / tau
    k_nr = (1.0 / efficiency - 1.0) / tau
    if n < 2:
        return ExcitonNetwork(sparse.csr_matrix((n, n)), is_trap, k_r, k_nr, float(forster_radius),
                              0.0, 0.0, energies, float(temperature))
    box = np.asarray(state.box, dtype=float) if periodic else None
    if periodic:
        positions = positions % box  # cKDTree's periodic box holds [0, L)
        positions[positions >= box] = 0.0  # -1e-17 % L rounds to L
    tree = cKDTree(positions, boxsize=box)
    spacing = float(tree.query(positions, k=2)[0][:, 1].min())
    if spacing <= 0:
        raise InputError("two dots share a centre: their Förster rate is infinite")
    fastest = math.log10(k_r) + 6.0 * math.log10(forster_radius / spacing)  # of the closest pair, 1/ns
    if fastest > math.log10(MAX_HOP_RATE):
        rate = f"1e{fastest:.0f}" if math.isfinite(fastest) else "inf"
        raise InputError(f"the closest dots ({spacing:.3g} px apart, R_F {forster_radius:.4g} px, tau {tau:g} ns) "
                         f"would hop at {rate} per ns, more than the {number(MAX_HOP_RATE)} the computation holds")
    extent = math.inf if periodic else float(np.sqrt((np.ptp(positions, axis=0) ** 2).sum()))
    counts, size = far_field_grid(positions, 0.5 * forster_radius, box)

    def bound_at(radius: float) -> float:
        if radius > extent:
            return 0.0
        return min(truncation_bound(forster_radius, radius, spacing, efficiency),
                   far_field_bound(counts, size, forster_radius, radius, efficiency))

    if cutoff is None:
        cutoff = cutoff_for(forster_radius, spacing, tolerance, efficiency)
        high = min(cutoff, extent * (1 + 1e-12) + 1e-9, math.inf if box is None else box.min() / 2 * (1 - 1e-12))
        if bound_at(high) <= tolerance:
            cutoff = smallest_cutoff(bound_at, spacing, high, tolerance)
    elif not (isinstance(cutoff, (int, float)) and cutoff > spacing):
        raise InputError(f"cutoff must exceed the smallest centre distance {spacing:.4g} px, got {cutoff!r}")
    if box is not None and cutoff >= box.min() / 2:  # periodic
        raise InputError(f"periodic: the pair cutoff {cutoff:.4g} px must be below half the box's shorter side "
                         f"({box.min() / 2:.4g} px); use a larger board, a larger tolerance or a smaller cutoff")
    bound = bound_at(cutoff)
    pairs = tree.query_pairs(min(cutoff, extent * (1 + 1e-12) + 1e-9), output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    x, y = positions[:, 0].copy(), positions[:, 1].copy()  # contiguous: faster gathers
    dx, dy = x[i] - x[j], y[i] - y[j]
    if box is not None:  # periodic: minimum image
        dx -= box[0] * np.round(dx / box[0])
        dy -= box[1] * np.round(dy / box[1])
    forward = k_r * forster_radius**6 / (dx * dx + dy * dy) ** 3
    backward = forward
    if energies is not None:  # uphill hops slowed by the Boltzmann factor
        rise = (energies[j] - energies[i]) / (KB_EV * temperature)
        forward, backward = forward * np.exp(-np.maximum(rise, 0.0)), forward * np.exp(-np.maximum(-rise, 0.0))
    rates = pair_matrix(n, i, j, forward, backward)
    return ExcitonNetwork(rates, is_trap, k_r, k_nr, float(forster_radius), float(cutoff), bound,
                          energies, float(temperature))
