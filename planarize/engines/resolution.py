"""The continuum engine's driver: how fine a run must be, and how far from the converged answer it is.

A continuum run (`planarize.engines.Continuum`) is computed at two resolutions: the grid it reports
and the one twice as coarse. Their difference is Richardson's estimate of the reported run's
discretization error::

    error = |R(h) - R(2h)| / (2^p - 1)

for each of the RMS and z-range of both surfaces at every recorded thickness (history columns
``*_error_nm``). The order used, `ORDER` = 1.5, lies between the orders measured on the thesis's
surfaces (about 1.3 where the piecewise-linear surface has creases, 2 and more on smooth ones:
docs/planarize_continuum.md); for any true order between 0.95 and 2.3 the estimate is within a factor
2 of the true error. If the largest relative estimate exceeds the settings' ``rtol``, the grid is
refined by 2 (the last run becomes the coarse one) until it does not, or until ``max_refine``.
The time step follows the grid (the explicit scheme's stability limit), so the estimate covers both.
The flow balances metal and oxide volumes only to its discretization error: the largest relative
error of that balance must meet ``rtol`` too (on smooth surfaces it is far below; on surfaces
steeper than about 45 degrees per grid spacing it is what asks for a finer grid).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from labrig.validate import available_memory, within_memory

from ..heightfield import MAX_POINTS, Surface
from ..metrics import ESTIMATED
from ..model import Model
from ..recording import Anodization, progress_bar, record_run

if TYPE_CHECKING:
    from .continuum import Continuum, ContinuumEngine

#: Order of convergence the error estimate assumes (see the module docstring).
ORDER = 1.5
#: A relative error is taken against at least this fraction of the quantity's value at the start (a
#: surface planarized flat has an RMS near 0, where a relative error means nothing).
FLOOR = 0.01
#: Memory the continuum engine needs per internal grid point, bytes (a dozen float arrays).
BYTES_PER_POINT = 160


def error_columns(fine: dict, coarse: dict, ratio: float) -> dict:
    """The ``*_error_nm`` columns: Richardson's estimate of ``fine``'s error from ``coarse``, a run on a
    grid ``ratio`` times coarser recorded at the same thicknesses."""
    factor = ratio ** ORDER - 1.0
    return {column.replace("_nm", "_error_nm"): np.abs(np.asarray(fine[column]) - np.asarray(coarse[column])) / factor
            for column in ESTIMATED}


def relative_error(table: dict) -> float:
    """The largest estimated error relative to its quantity (floored at `FLOOR` of the starting value)."""
    worst = 0.0
    for column in ESTIMATED:
        value = np.abs(np.asarray(table[column], dtype=float))
        scale = np.maximum(value, FLOOR * value[0]) if len(value) else value
        error = np.asarray(table[column.replace("_nm", "_error_nm")], dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(scale > 0, error / scale, np.where(error > 0, np.inf, 0.0))
        worst = max(worst, float(np.max(ratio, initial=0.0)))
    return worst


def volume_error(table: dict) -> float:
    """The largest relative error of the volume balance over the recorded thicknesses: the flow balances
    metal and oxide volumes only to its discretization error, so this is a second measure of it."""
    return float(np.max(np.abs(np.nan_to_num(table["volume_error"], nan=np.inf)), initial=0.0))


def _ladder(settings: "Continuum") -> list[float]:
    """The refinement factors to try, coarse companion first."""
    if settings.refine is not None:
        return [settings.refine / 2, settings.refine]
    top = settings.max_refine
    factors = [0.5, 1.0]
    while factors[-1] < top:
        factors.append(factors[-1] * 2)
    return factors


def converge(metal: Surface, thickness: float, model: Model, settings: "Continuum", rows_at: np.ndarray,
             shots_at: np.ndarray, *, progress: bool = False, observer=None,
             max_seconds: float | None = None) -> Anodization:
    """A continuum run of `planarize.anodize` at the resolution ``settings.rtol`` asks for, with its error
    estimate (see the module docstring); the arguments are `anodize`'s, checked."""
    factors = _ladder(settings)
    order = [factors[1], factors[0], *factors[2:]]  # the reported grid first: a budget that runs out keeps it
    start = time.perf_counter()
    levels: list[dict] = []
    runs: dict = {}
    best = None
    n = metal.z.size
    for factor in order:
        points = n * factor * factor
        if factor > order[0] and (points > MAX_POINTS or points * BYTES_PER_POINT > available_memory() / 2):
            levels.append({"factor": factor, "skipped": "more points than fit in memory"})
            break
        within_memory("the continuum run", int(points * BYTES_PER_POINT + 3 * 8 * n * (len(shots_at) + 1)),
                      available_memory())
        engine = settings.build(metal, None, model, factor)
        began = time.perf_counter() - start
        budget = None if max_seconds is None else max(max_seconds - (time.perf_counter() - start), 1e-3)
        companion = factor < order[0]
        label = f"oxide, grid {'1/2' if factor == 0.5 else f'{factor:g}x'}" + (" (error estimate)" if companion else "")
        table, shots, complete = record_run(engine, thickness, rows_at, np.zeros(0) if companion else shots_at,
                                            max_sweeps=_max_steps(engine, thickness),
                                            bar=progress_bar(thickness, label) if progress else None, observer=observer,
                                            max_seconds=budget)
        levels.append({"factor": factor, "shape": list(engine.inner.shape), "spacing": list(engine.inner.spacing),
                       "steps": engine.iterations, "wall_s": round(time.perf_counter() - start, 3)})
        table["wall_s"] = table["wall_s"] + began  # (the run's wall time counts every resolution before it)
        runs[factor] = (engine, table, shots, complete)
        if factor == order[0]:
            best = runs[factor]  # (the reported grid, even if a time budget stopped it)
        if not complete:
            break
        if companion:
            coarse, fine = runs[factor], runs[order[0]]
        elif factor != order[0]:
            coarse, fine = runs[factor / 2], runs[factor]
        else:
            continue
        ratio = coarse[0].inner.dx / fine[0].inner.dx
        if ratio <= 1.0:  # a grid of 2 points a side has no coarser companion: estimate from the next level
            continue
        fine[1].update(error_columns(fine[1], coarse[1], ratio))
        best = fine
        error, balance = relative_error(fine[1]), volume_error(fine[1])
        levels[-1]["estimated_error"], levels[-1]["volume_error"] = error, balance
        if settings.refine is not None or max(error, balance) <= settings.rtol:
            break
    engine, table, shots, complete = best
    estimated = all(column.replace("_nm", "_error_nm") in table for column in ESTIMATED)
    if not estimated:
        for column in ESTIMATED:
            table[column.replace("_nm", "_error_nm")] = np.full(len(table[column]), np.nan)
    error = relative_error(table) if estimated else math.nan
    balance = volume_error(table)
    complete = complete and estimated
    parameters = {"engine": settings.name, "thickness": thickness, "k_exp": model.k_exp, "rule": model.rule,
                  "boundary": metal.boundary, "shape": list(metal.shape), "spacing": list(metal.spacing),
                  "rtol": settings.rtol, "refine": engine.factor, "estimated_error": error, "volume_error": balance,
                  "rtol_met": bool(max(error, balance) <= settings.rtol), "order": ORDER, "levels": levels,
                  **{k: v for k, v in settings.options().items() if k != "rtol"}}
    return Anodization(parameters, table, shots, metal, engine.metal(), engine.oxide(), engine.distances(), complete)


def _max_steps(engine: "ContinuumEngine", thickness: float) -> int:
    """A bound on the time steps to ``thickness``: many times what the stability limit asks for where the
    metal stalls (diffusion coefficient ``t / (k_exp - 1)``, the largest but for sharp bumps; none without
    expansion, ``k_exp = 1``, where the metal recedes at one speed); a run past it has stopped making progress."""
    h = min(engine.dx, engine.dy)
    stalled = 2 * thickness / (engine.k_exp - 1) if engine.k_exp > 1 else 0.0
    return int(100 * (thickness / h + stalled * thickness / h ** 2) + 10_000)


__all__ = ["converge", "error_columns", "relative_error", "volume_error", "ORDER", "FLOOR"]
