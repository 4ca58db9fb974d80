"""What the two planarization engines share: state, the oxidation step (Eq 3.9), accounting.

An engine holds the metal and oxide heights on one grid, and for every metal
point ``m`` its distance ``D[m]`` to the oxide and its oxide point set (the
oxide points that grow when ``m`` is oxidized; `planarize.engines.features`). One
`advance` oxidizes a *batch* of metal points, those whose distance is within
a tolerance of the smallest:

* for each batch point ``m`` and each oxide point ``o`` of its set,
  ``F = 1 / (len(set of m) * number of metal points whose set holds o)`` (Eq 3.9);
* the metal point goes down by ``step * sum(F)``;
* each oxide point goes up by ``(k_exp - 1) * step * F``, scaled by the ratio of
  the areas the two points carry so that the oxide volume gained above the
  original surface is exactly ``(k_exp - 1)`` times the metal volume lost (the
  thesis uses equal weights, which is exact only on periodic grids: its
  accounting is available as ``volume="thesis"``).

The thesis's Matlab oxidizes one point per iteration; its ties (equal
distances, e.g. every point at the start or the mirror images on a symmetric
surface) go in storage order. Here exact ties (to round-off) are oxidized
together, which keeps flat films exactly flat and mirror/transpose symmetry
exact, and a batch tolerance above round-off is the fast engine's
speed/accuracy knob.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np

from labrig.validate import InputError, available_memory, within_memory

from ..grid import Grid
from ..heightfield import Surface, volume_weights
from ..metrics import roughness
from ..model import Model
from ..recording import Anodization, progress_bar, record_run, run_bytes
from .features import feature_tables
from .kernels import max_feature_length


@overload
def check_oxide(metal: Surface, oxide: Surface) -> Surface: ...
@overload
def check_oxide(metal: Surface, oxide: None) -> None: ...
def check_oxide(metal: Surface, oxide: Surface | None) -> Surface | None:
    """``oxide`` if it is None or a `Surface` on ``metal``'s grid lying nowhere below it; `InputError` otherwise."""
    if oxide is None:
        return None
    if not isinstance(oxide, Surface):
        raise InputError(f"oxide must be a planarize.Surface or None, got {type(oxide).__name__}")
    if (oxide.shape, oxide.spacing, oxide.boundary) != (metal.shape, metal.spacing, metal.boundary):
        raise InputError(f"oxide must be on the metal's grid: {oxide!r} vs {metal!r}")
    if np.any(oxide.z < metal.z):
        raise InputError("oxide must lie nowhere below the metal")
    return oxide


class Engine:
    """Base of the engines: the two surfaces, distances, sets and the Eq 3.9 step.

    Parameters
    ----------
    metal : Surface
        The metal surface at the start.
    oxide : Surface, optional
        The oxide surface at the start, on the same grid, nowhere below the
        metal. Default: a copy of the metal (no oxide yet).
    model : Model
        The physics: ``k_exp``, ``step``, ``distance``, ``volume`` (`planarize.model.Model`).
    """

    name = "base"

    def __init__(self, metal: Surface, oxide: Surface | None = None, model: Model | None = None):
        if not isinstance(metal, Surface):
            raise InputError(f"metal must be a planarize.Surface, got {type(metal).__name__}")
        self.model = Model() if model is None else model
        if not isinstance(self.model, Model):
            raise InputError(f"model must be a planarize.Model, got {type(self.model).__name__}")
        if self.model.rule != "thesis":
            raise InputError(f"the {self.name} engine computes the thesis's rule only, not rule "
                             f"{self.model.rule!r}: use engine=\"continuum\"")
        oxide = metal if oxide is None else check_oxide(metal, oxide)
        self.k_exp, self.step = self.model.k_exp, self.model.step
        self.distance, self.volume_rule = self.model.distance, self.model.volume
        self.surface = metal
        self.grid = Grid(metal.shape, metal.spacing, metal.periodic)
        self.tables = feature_tables(self.grid, self.distance)
        self.zm = metal.z.ravel().astype(float)
        self.zo = oxide.z.ravel().astype(float)
        self.zm0 = self.zm.copy()
        self.zo0 = self.zo.copy()
        self.area = volume_weights(metal.shape, metal.dx, metal.dy, metal.boundary).ravel()
        scale = max(1.0, float(np.abs(self.zo).max()), float(np.abs(self.zm).max()))
        #: distances closer than this (nm) are ties: round-off, not geometry
        self.tie = max(1e-9 * self.step, 64 * np.finfo(float).eps * scale)
        self.D = np.zeros(self.grid.n)
        self.iterations = 0
        self.point_updates = 0

    # -- state -----------------------------------------------------------------------------

    @property
    def thickness(self) -> float:
        """Smallest metal-oxide distance, nm: the oxide thickness reached (thesis ``smallestdist``)."""
        return float(self.D.min())

    def metal(self) -> Surface:
        return self.surface.with_heights(self.zm.reshape(self.grid.nx, self.grid.ny))

    def oxide(self) -> Surface:
        return self.surface.with_heights(self.zo.reshape(self.grid.nx, self.grid.ny))

    def distances(self) -> np.ndarray:
        """Every metal point's distance to the oxide, nm, shape (nx, ny)."""
        return self.D.reshape(self.grid.nx, self.grid.ny).copy()

    def roughness(self) -> dict:
        """RMS and z-range of both surfaces over their grid points, nm (Eqs 3.7, 3.8)."""
        return roughness(self.zm, self.zo)

    def metal_lost(self) -> float:
        """Metal volume consumed since the start, nm^3."""
        return float(np.sum(self.area * (self.zm0 - self.zm)))

    def oxide_gained(self) -> float:
        """Oxide volume added above the starting oxide surface, nm^3."""
        return float(np.sum(self.area * (self.zo - self.zo0)))

    def max_feature_length(self) -> float:
        """Longest feature edge on either surface, nm (the reach candidate searches add)."""
        return max(max_feature_length(self.tables, self.zm), max_feature_length(self.tables, self.zo))

    # -- one oxidation ---------------------------------------------------------------------

    def oxidize(self, batch_owner: np.ndarray, batch_oxide: np.ndarray, set_size: np.ndarray,
                sharers: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Apply Eq 3.9 to a batch; return the oxide and metal points that moved, and the largest move (nm).

        Parameters
        ----------
        batch_owner, batch_oxide : ndarray of int, shape (K,)
            The (metal point, oxide point) pairs of the batch's sets.
        set_size : ndarray, shape (K,)
            Size of the owner's set, for each pair.
        sharers : ndarray, shape (K,)
            Number of metal points whose set holds the pair's oxide point.
        step : float
            Metal height consumed by a full share, nm.
        """
        share = 1.0 / (set_size * sharers)
        metal_dz = np.bincount(batch_owner, weights=share, minlength=self.grid.n)
        rise = (self.k_exp - 1.0) * step * share
        if self.volume_rule == "exact":
            rise = rise * self.area[batch_owner] / self.area[batch_oxide]
        oxide_dz = np.bincount(batch_oxide, weights=rise, minlength=self.grid.n)
        metal_moved = np.flatnonzero(metal_dz)
        oxide_moved = np.flatnonzero(oxide_dz)
        self.zm[metal_moved] -= step * metal_dz[metal_moved]
        self.zo[oxide_moved] += oxide_dz[oxide_moved]
        self.iterations += 1
        self.point_updates += len(metal_moved)
        largest = max(step * float(metal_dz.max(initial=0.0)), float(oxide_dz.max(initial=0.0)))
        return oxide_moved, metal_moved, largest

    def advance(self, until: float = math.inf) -> None:
        """Oxidize one batch (the points at the smallest distance) and bring distances up to date.

        ``until`` (the next thickness a run records) does not change a sweep: the thickness reached is
        the smallest distance after it.
        """
        raise NotImplementedError


def run_sweeps(settings, metal: Surface, oxide: Surface | None, thickness: float, model: Model, rows_at: np.ndarray,
               shots_at: np.ndarray, *, progress: bool = False, observer=None,
               max_seconds: float | None = None) -> Anodization:
    """A run of one of the thesis's engines (``settings``: `planarize.engines.Fast`, `Reference`, `Matlab`) on
    the grid of ``metal``, the arguments `planarize.anodize`'s, checked: the engine ``settings.build`` makes,
    advanced sweep by sweep by `planarize.recording.record_run`."""
    n = metal.z.size
    within_memory("the run", run_bytes(n, len(rows_at), len(shots_at)), available_memory())
    sim = settings.build(metal, oxide, model)
    parameters = {"engine": settings.name, "thickness": thickness, "step": model.step, "k_exp": model.k_exp,
                  "distance": model.distance, "volume": model.volume, "boundary": metal.boundary,
                  "shape": list(metal.shape), "spacing": list(metal.spacing), **settings.options()}
    # no loop without a bound: a run of n points takes ~thickness / step point updates each (measured
    # 0.2-1.3x), far fewer sweeps; many times that means the engine stopped making progress
    max_sweeps = 100 * n * (math.ceil(thickness / model.step) + 1) + 1000
    table, shots, complete = record_run(sim, thickness, rows_at, shots_at, max_sweeps=max_sweeps,
                                        bar=progress_bar(thickness) if progress else None, observer=observer,
                                        max_seconds=max_seconds)
    return Anodization(parameters, table, shots, metal, sim.metal(), sim.oxide(), sim.distances(), complete)
