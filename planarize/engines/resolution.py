"""The continuum engine's driver: how fine a run must be, how far from the converged answer it is, and what a
finer grid would cost.

A continuum run (`planarize.engines.Continuum`) is computed on a ladder of grids, each twice as fine as
the one before: a quarter and a half of the reported grid's resolution (its companions), the reported
grid, and, while the error asks for it, grids refined 2x, 4x ... up to ``max_refine``. From the three
finest grids run so far (spacings 4h, 2h and h) come, for each of the RMS and z-range of both surfaces,

* the **observed order** of convergence, ``p = log2(|R(2h) - R(4h)| / |R(h) - R(2h)|)`` (norms over the
  recorded thicknesses), and
* where ``p`` lies in [`ORDER_LOW`, `ORDER_HIGH`], the **asymptotic regime** (each refinement shrinks the
  change by a steady factor), Richardson's estimate of the finest grid's error at every recorded
  thickness, ``|R(h) - R(2h)| / (2^q - 1)`` (history columns ``*_error_nm``): ``q = min(p, ORDER_CAP)`` where
  the order one grid coarser reached `ORDER_CAP` too (or was not observed) and ``q = min(p, ROUGH_ORDER)`` otherwise
  (the first refinements of a measured map converge faster than its asymptotic regime), but ``q = SMOOTH_ORDER``
  on a map its pixels resolve (its `planarize.metrics.pixel_curvature` under `SMOOTH_CURVATURE`) where both orders
  reach `SMOOTH_STEADY` (`estimate_order`).

Where ``p`` lies outside that range the changes do not shrink steadily (pixel-scale noise in a measured
map, whose z-range converges slowly and unevenly, does this): no error is stated for that quantity (its
column is NaN), and the run says so, with the observed order and the change of the last refinement. On a map whose
pixels bend as white noise does (`NOISE_CURVATURE`) no error is stated at all: no affordable grid is asymptotic there.
Nor on the map's own grid (`OWN_GRID_FINER`): its companions sample the map at fewer points than it has, so their
changes hold the map's sampling as well as the flow's error; the first error a run states is at 2x. A
single assumed order was used before; on real AFM maps it under-stated the z-range's error up to 9x
(docs/performance.md, ``afm_real``). If the largest relative estimate of the quantities stated exceeds the
settings' ``rtol``, or none is stated, the grid is refined by 2 until it does not, or until
``max_refine``; a quantity that is not yet asymptotic asks for a finer grid only while that grid is
predicted to take at most `SETTLE_S` (on a noisy map its order may not settle at any affordable grid),
and a run that ends with one does not claim to meet ``rtol`` (that prediction is a cost in point steps, so that the
grid a run reports is the same on every machine). The
time step follows the grid (the explicit scheme's stability limit), so the estimate covers both. The
flow balances metal and oxide volumes only to its discretization error: the largest relative error of
that balance must meet ``rtol`` too.

**Cost.** Before each grid from the reported one on, its wall time is predicted from the two grids
before it (their time steps, grown by their observed ratio, times the points, at the kernels' measured
speed and at most `SECONDS_PER_POINT_STEP`: a prediction on the low side). The reported grid may take
the run's budget (``max_seconds``, or `BUDGET_S` without one); one predicted to take longer is refused
up front (`TooCostly`), with its predicted time, unless ``max_seconds`` was given (then it runs until the
budget and stops). A finer grid may take at most `LEVEL_GROWTH` times the grid before it (or
`MIN_LEVEL_S`), within the budget: one predicted to take longer is not started, one that runs longer is
stopped, and the run states the error of the grid before it, with what the finer one would have cost
(parameter ``finer``). A grid that stops making progress ends the run (`planarize.recording.Stalled`).
So every run ends.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from labrig.progress import duration
from labrig.validate import InputError, available_memory, within_memory

from ..heightfield import MAX_POINTS, Surface
from ..metrics import ESTIMATED, pixel_curvature
from ..model import Model
from ..recording import Anodization, progress_bar, record_run

if TYPE_CHECKING:
    from .continuum import Continuum, ContinuumEngine

#: Observed orders of convergence taken as asymptotic (see the module docstring): the orders measured on the
#: thesis's surfaces lie between about 1.3 (piecewise-linear surfaces with creases) and 2 and more (smooth ones).
ORDER_LOW, ORDER_HIGH = 0.7, 3.0
#: A quantity that the last refinement changed by more than ASYMPTOTIC_CHANGE of its value (relative as `relative`
#: takes it) is not in its asymptotic regime whatever its order: Richardson's expansion is one of small changes. On
#: a 17 x 17 one-pixel checkerboard at 8x the estimate at its order stated 117-125 % where the truth was 30-46 %, on
#: white noise at 1x 53 % against 10 %. At every grid from 1x of the real maps' development crops and the thesis's
#: surfaces, 6 of 117 stated numbers changed more: 5 over-stated 2.3-6x, one within 2x (1.6x); of a step, a ridge, a
#: cusp and noise, 7 of 42 (4 within 2x, 0.56-1.98; 3 over-stated 3-5.2x).
ASYMPTOTIC_CHANGE = 0.1
#: The estimate takes the observed order, but no more than ORDER_CAP: the first refinements converge faster than the
#: asymptotic regime (on the centre crops of six real AFM scans the coarse grids observed 2-2.5, the fine ones about 1),
#: and Richardson's estimate at the higher order under-stated the error up to 25x. An order of 1.5 keeps any true order
#: between 1 (the scheme's on measured maps) and 2 (on the thesis's smooth surfaces) within a factor 1.64.
ORDER_CAP = 1.5
#: The order the estimate takes at most where the last two observed orders do not both reach `ORDER_CAP`. A map's
#: pixel-scale features converge unsteadily: on the centre crops of six real AFM scans the orders of successive
#: refinements scattered between 0.4 and 2.5 and settled near 1.1-1.4 only at 16x-32x, and an order of 1.5 taken from
#: one steady-looking pair under-stated the error 2.6x. A smooth surface in its asymptotic regime shows a high order
#: twice running and keeps `ORDER_CAP`; every other quantity is estimated as the scheme's first order. The reported
#: grid, with one observed order only, keeps `ORDER_CAP` (taking 1 there would refine smooth films that meet rtol:
#: the 1025 x 1025 film of the speed benchmark, 1.7 % at its own grid, would state 3.1 % and run at 2x).
ROUGH_ORDER = 1.0
#: A map whose `planarize.metrics.pixel_curvature` is under SMOOTH_CURVATURE is resolved by its pixels (the thesis's
#: hill, depression and random films measure 1.01-1.07; the centre crops of six measured AFM maps 1.6-3.6). On such a
#: map a quantity observed at SMOOTH_STEADY or more twice running (once, on the reported grid) is estimated at
#: SMOOTH_ORDER. On those five thesis surfaces, run at every grid to 16x, the order of one refinement wandered between
#: 1.2 and 2.5 from 2x on, rising and falling (the depression's z-range 1.24, 1.40, 1.48, then 2.45): the rule above
#: took 1 and over-stated the z-range up to 4x at the grid the default run chose. A map with a crease converges at
#: order 1 (a piecewise-linear ridge, 0.53: its z-range observed 0.73-0.95) and is left to the rule above: taking
#: 1.8 there under-stated its error down to 0.29. Stated against true error at every grid from 1x to 8x: on the thesis
#: surfaces 56 of 66 within 2x (48 with the rule above), none under half; on a step, a ridge, a cusp and noise of 17 x
#: 17 points, 35 of 42 as before.
SMOOTH_CURVATURE, SMOOTH_STEADY, SMOOTH_ORDER = 1.3, 1.2, 1.8
#: A map whose `planarize.metrics.pixel_curvature` reaches NOISE_CURVATURE bends from pixel to pixel as white noise
#: does (white noise and a one-pixel pit give sqrt(20) = 4.47; twelve crops of six measured AFM scans 1.6-3.6):
#: its features are one pixel wide, and the continuum answer hangs on how the grid joins them. On such maps of 17 x 17
#: points (noise, pits 1 nm and 4 nm deep) the order of one refinement wandered between -1.5 and 4.5 at every grid
#: from 1x to 8x, and at 8x the deeper pit's stated metal RMS and z-range errors were 0.40 and 0.36 of the true ones
#: (16x truth): no grid within reach is asymptotic, so no error is stated (`error_columns`), and the grid is refined
#: only while that is cheap (`SETTLE_S`).
NOISE_CURVATURE = 4.0
#: No error is stated on a grid whose two companions are coarser than the map (the map's own grid, ``refine`` 1, and
#: coarser): they sample the map at half and a quarter of its resolution per side, a smoother surface, so their
#: changes hold what the map loses by sampling as well as the flow's own discretization error. At 1x the estimate
#: from them was 0.25 to 420 times the true error on the crops of eleven real AFM scans (the RMS of a PicoView scan's crop 223x, reported at
#: 1x; the z-range of a Park scan's 0.25x) and 8.6-9.4 times it on the smooth 129 x 129 film. As on a noisy map, the
#: grid is then refined only while the next one is cheap (`SETTLE_S`), and the run states no number where it is not.
#: Grids from OWN_GRID_FINER times the map's on have a middle grid that holds every point of the map.
OWN_GRID_FINER = 2.0
#: A relative error is taken against at least this fraction of the quantity's value at the start (a
#: surface planarized flat has an RMS near 0, where a relative error means nothing).
FLOOR = 0.01
#: Memory the continuum engine needs per internal grid point, bytes (a dozen float arrays).
BYTES_PER_POINT = 160
#: Wall time of one time step per grid point that a cost prediction assumes at most, s (the compiled kernels
#: on 2 cores take 40-100 ns; a faster measured speed is used as it is).
SECONDS_PER_POINT_STEP = 5e-8
#: A run's wall-time budget without ``max_seconds``, s: a reported grid predicted to take longer is refused.
BUDGET_S = 4 * 3600.0
#: A grid finer than the reported one may take at most this many times as long as the grid before it, or
#: `MIN_LEVEL_S`, whichever is longer (a halving of the spacing takes 8-40 times as long on the maps measured;
#: far more means the grid resolves features, steps or noise, that make the flow stiff).
LEVEL_GROWTH, MIN_LEVEL_S = 64.0, 60.0
#: A finer grid asked for only because a quantity is not yet asymptotic (every error stated meets ``rtol``) is
#: computed only if it is predicted to take at most this long, s, at `SECONDS_PER_POINT_STEP` (2e8 point steps: a
#: cost that is the same on every machine, so that the grid a run reports is too; at the measured speed, the centre
#: crop of the Bruker .spm scan of the real-map benchmark ran to 4x on a busy machine and to 8x on a quiet one).
SETTLE_S = 10.0


class TooCostly(InputError):
    """A continuum run refused before its reported grid: it is predicted to take longer than its budget."""


def observed_orders(fine: dict, middle: dict, coarse: dict, ratio: float) -> dict:
    """Each estimated column's observed order of convergence from three runs on grids ``ratio`` apart (`inf`
    where the finer change is 0 and the coarser is not, NaN where both are 0)."""
    orders = {}
    for column in ESTIMATED:
        near = np.linalg.norm(np.asarray(fine[column]) - np.asarray(middle[column]))
        far = np.linalg.norm(np.asarray(middle[column]) - np.asarray(coarse[column]))
        with np.errstate(divide="ignore", invalid="ignore"):
            orders[column] = float(np.log(far / near) / np.log(ratio)) if near > 0 or far > 0 else math.nan
    return orders


def estimate_order(order: float, previous: float, smooth: bool = False) -> float:
    """The order Richardson's estimate takes for a quantity observed at ``order`` (asymptotic) and, one grid
    coarser, at ``previous``: on a map its pixels resolve (``smooth``), `SMOOTH_ORDER` where both reach
    `SMOOTH_STEADY`; else at most `ORDER_CAP` where both reach it, at most `ROUGH_ORDER` where either does not. Where
    ``previous`` was not observed (NaN: the reported grid, whose two companions are the only coarser grids run),
    ``order`` alone decides, and a high one is taken at most as `ORDER_CAP`."""
    if smooth and min(order, SMOOTH_STEADY if math.isnan(previous) else previous) >= SMOOTH_STEADY:
        return SMOOTH_ORDER
    if math.isnan(previous):
        return min(order, ORDER_CAP)
    return min(order, ORDER_CAP if min(order, previous) >= ORDER_CAP else ROUGH_ORDER)


def error_columns(fine: dict, middle: dict, orders: dict, ratio: float, previous: dict | None = None,
                  smooth: bool = False, noisy: bool = False) -> dict:
    """The ``*_error_nm`` columns of ``fine``: Richardson's estimate from ``middle`` (a run on a grid ``ratio``
    times coarser recorded at the same thicknesses) at the order `estimate_order` takes from each column's observed
    order, the one observed one grid coarser (``previous``) and whether the map is ``smooth``, where it is
    asymptotic (0 where neither run changed it), NaN where it is not: an order outside [`ORDER_LOW`, `ORDER_HIGH`],
    a change of more than `ASYMPTOTIC_CHANGE` of the quantity, or a map whose pixels bend as noise does (``noisy``:
    `NOISE_CURVATURE`)."""
    out = {}
    for column in ESTIMATED:
        change = np.abs(np.asarray(fine[column], dtype=float) - np.asarray(middle[column], dtype=float))
        p = orders[column]
        if noisy:
            error = np.full_like(change, math.nan)
        elif math.isnan(p):
            error = np.zeros_like(change)
        elif ORDER_LOW <= p <= ORDER_HIGH and np.max(relative(fine, column, change), initial=0.0) <= ASYMPTOTIC_CHANGE:
            error = change / (ratio ** estimate_order(p, (previous or {}).get(column, math.nan), smooth) - 1.0)
        else:
            error = np.full_like(change, math.nan)
        out[column.replace("_nm", "_error_nm")] = error
    return out


def relative(table: dict, column: str, values: np.ndarray) -> np.ndarray:
    """``values`` relative to ``table[column]``, floored at `FLOOR` of its starting value."""
    value = np.abs(np.asarray(table[column], dtype=float))
    scale = np.maximum(value, FLOOR * value[0]) if len(value) else value
    values = np.asarray(values, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(scale > 0, values / scale, np.where(values > 0, np.inf, 0.0))


def relative_error(table: dict, stated_only: bool = False) -> float:
    """The largest estimated error relative to its quantity (floored at `FLOOR` of the starting value);
    NaN if a quantity's error is not stated (``stated_only``: the largest over the quantities stated, NaN
    if none is)."""
    worst, stated = 0.0, False
    for column in ESTIMATED:
        ratio = relative(table, column, table[column.replace("_nm", "_error_nm")])
        if np.isnan(ratio).any():
            if not stated_only:
                return math.nan
            continue
        stated = True
        worst = max(worst, float(np.max(ratio, initial=0.0)))
    return worst if stated else math.nan


def last_change(fine: dict, middle: dict) -> float:
    """The largest relative change of RMS or z-range between two runs (the last refinement's)."""
    return max(float(np.max(relative(fine, c, np.abs(np.asarray(fine[c]) - np.asarray(middle[c]))), initial=0.0))
               for c in ESTIMATED)


def volume_error(table: dict) -> float:
    """The largest relative error of the volume balance over the recorded thicknesses: the flow balances
    metal and oxide volumes only to its discretization error, so this is a second measure of it."""
    return float(np.max(np.abs(np.nan_to_num(table["volume_error"], nan=np.inf)), initial=0.0))


def predicted_seconds(before: dict, last: dict, points: int, measured: bool = True) -> float:
    """Predicted wall time, s, of the next grid (``points`` points) from the two grids run before it (levels
    with ``points``, ``steps`` and ``run_s``): the last one's steps grown by their observed ratio (2-16 per
    halving of the spacing), at the last one's speed per point and step but at most
    `SECONDS_PER_POINT_STEP` (``measured``), or at `SECONDS_PER_POINT_STEP` (not ``measured``: a cost in point steps,
    the same on every machine)."""
    growth = float(np.clip(last["steps"] / before["steps"], 2.0, 16.0)) if before["steps"] and last["steps"] else 4.0
    speed = SECONDS_PER_POINT_STEP
    if measured and last["steps"]:
        speed = min(speed, last["run_s"] / (last["steps"] * last["points"]))
    return max(last["steps"], 1) * growth * points * speed


def _ladder(settings: Continuum) -> list[float]:
    """The refinement factors to run, coarsest first: the reported grid's two companions, the reported
    grid, and the finer ones ``rtol`` may ask for."""
    reported = settings.refine or 1
    factors = [reported / 4, reported / 2, reported]
    while settings.refine is None and factors[-1] < settings.max_refine:
        factors.append(factors[-1] * 2)
    return factors


def _label(factor: float, companion: bool) -> str:
    grid = f"1/{round(1 / factor)}" if factor < 1 else f"{factor:g}x"
    return f"oxide, grid {grid}" + (" (error estimate)" if companion else "")


def converge(metal: Surface, thickness: float, model: Model, settings: Continuum, rows_at: np.ndarray,
             shots_at: np.ndarray, *, progress: bool = False, observer=None,
             max_seconds: float | None = None) -> Anodization:
    """A continuum run of `planarize.anodize` at the resolution ``settings.rtol`` asks for, with its error
    estimate and its cost bounded (see the module docstring); the arguments are `anodize`'s, checked."""
    start = time.perf_counter()
    budget = BUDGET_S if max_seconds is None else max_seconds
    reported = settings.refine or 1
    levels: list[dict] = []
    done: list[tuple] = []  # (level, engine, table, shots): complete runs, coarsest first
    best: tuple[dict, ContinuumEngine, dict, list, bool] | None = None  # the reported resolution's run
    n = metal.z.size
    curvature = pixel_curvature(metal)
    smooth, noisy = curvature < SMOOTH_CURVATURE, curvature >= NOISE_CURVATURE
    for factor in _ladder(settings):
        points = n * factor * factor
        if factor > reported and (points > MAX_POINTS or points * BYTES_PER_POINT > available_memory() / 2):
            levels.append({"factor": factor, "skipped": "more points than fit in memory"})
            break
        within_memory("the continuum run", int(points * BYTES_PER_POINT + 3 * 8 * n * (len(shots_at) + 1)),
                      available_memory())
        engine = settings.build(metal, None, model, factor)
        elapsed = time.perf_counter() - start
        allowed = budget - elapsed
        if factor > reported:  # a finer grid: at most LEVEL_GROWTH times the one before
            allowed = min(allowed, max(LEVEL_GROWTH * done[-1][0]["run_s"], MIN_LEVEL_S))
        if factor >= reported and len(done) >= 2:
            predicted = predicted_seconds(done[-2][0], done[-1][0], engine.inner.z.size)
            if predicted > allowed:
                if factor > reported:
                    levels.append({"factor": factor, "skipped": f"predicted to take about {duration(predicted)}",
                                   "predicted_s": predicted})
                    break
                if max_seconds is None:
                    raise TooCostly(_too_costly(engine, thickness, predicted, done[-1][0]))
        companion = factor < reported
        table, shots, complete = record_run(
            engine, thickness, rows_at, np.zeros(0) if companion else shots_at, max_sweeps=_max_steps(engine, thickness),
            bar=progress_bar(thickness, _label(factor, companion)) if progress else None, observer=observer,
            max_seconds=max(allowed, 1e-3))
        run_s = time.perf_counter() - start - elapsed
        level: dict[str, Any] = {
            "factor": factor, "shape": list(engine.inner.shape), "spacing": list(engine.inner.spacing),
            "points": engine.inner.z.size, "steps": engine.iterations, "run_s": round(run_s, 6),
            "wall_s": round(time.perf_counter() - start, 3)}
        levels.append(level)
        table["wall_s"] = table["wall_s"] + elapsed  # (the run's wall time counts every resolution before it)
        if factor > reported and not complete:  # stopped: the grid before it is the answer
            level["skipped"] = (f"stopped after {duration(run_s)} at {engine.thickness:.3g} of {thickness:g} nm, "
                                f"{'past the budget' if allowed == budget - elapsed else 'too slow'}")
            level["predicted_s"] = run_s * thickness / max(engine.thickness, 1e-300)  # (on the low side: steps shrink)
            break
        if not companion:
            best = (level, engine, table, shots, complete)
        if not complete:
            if companion:
                continue
            break
        if done and engine.inner.dx >= done[-1][1].inner.dx:  # a grid of 2 points a side has no coarser one
            done[-1] = (level, engine, table, shots)
        else:
            done.append((level, engine, table, shots))
        if companion or len(done) < 3:
            continue
        (_, _, coarse_table, _), (_, middle, middle_table, _) = done[-3], done[-2]
        ratio = middle.inner.dx / engine.inner.dx
        orders = observed_orders(table, middle_table, coarse_table, ratio)
        own_grid = factor < OWN_GRID_FINER  # its companions are coarser than the map: no error can be stated
        table.update(error_columns(table, middle_table, orders, ratio, done[-2][0].get("orders"), smooth,
                                   noisy or own_grid))
        error, balance = relative_error(table), volume_error(table)
        level.update(estimated_error=error, volume_error=balance, orders=orders, change=last_change(table, middle_table))
        known = relative_error(table, stated_only=True)
        if settings.refine is not None:
            break
        if noisy or own_grid or (math.isfinite(known) and max(known, balance) <= settings.rtol):
            # every quantity stated meets rtol (or none can be stated: a noisy map, the map's own grid); one not yet
            # asymptotic asks for a finer grid only if it is cheap
            # (the cost at SECONDS_PER_POINT_STEP, not at the measured speed: the grid a run reports does not depend
            # on the machine, nor on what else it runs)
            finer = predicted_seconds(done[-2][0], done[-1][0], 4 * engine.inner.z.size, measured=False)
            if math.isfinite(error) or finer > SETTLE_S:
                if own_grid and not noisy and not math.isfinite(error):
                    levels.append({"factor": 2 * factor, "skipped": f"not run: predicted to take about "
                                   f"{duration(finer)} at {SECONDS_PER_POINT_STEP:g} s a point step",
                                   "predicted_s": finer})
                break
    assert best is not None  # the reported resolution always runs (coarser ones first, finer ones after)
    level, engine, table, shots, complete = best
    estimated = "orders" in level and complete
    if not estimated:
        for column in ESTIMATED:
            table[column.replace("_nm", "_error_nm")] = np.full(len(table[column]), np.nan)
    error = relative_error(table) if estimated else math.nan
    balance = volume_error(table)
    orders = level.get("orders", {c: math.nan for c in ESTIMATED})
    parameters = {"engine": settings.name, "thickness": thickness, "k_exp": model.k_exp, "rule": model.rule,
                  "boundary": metal.boundary, "shape": list(metal.shape), "spacing": list(metal.spacing),
                  "rtol": settings.rtol, "refine": engine.factor, "estimated_error": error, "volume_error": balance,
                  "rtol_met": bool(math.isfinite(error) and max(error, balance) <= settings.rtol),
                  "asymptotic": bool(estimated and math.isfinite(error)), "orders": orders,
                  "not_asymptotic": [c for c in ESTIMATED if estimated
                                     and np.isnan(table[c.replace("_nm", "_error_nm")]).any()],
                  "change": level.get("change", math.nan), "pixel_curvature": curvature,
                  "smooth": smooth, "noisy": noisy,
                  "own_grid": bool(estimated and level["factor"] < OWN_GRID_FINER and not noisy),
                  "finer": (f"{levels[-1]['factor']:g}x {levels[-1]['skipped']}" if "skipped" in levels[-1] else ""),
                  "levels": levels,
                  **{k: v for k, v in settings.options().items() if k != "rtol"}}
    return Anodization(parameters, table, shots, metal, engine.metal(), engine.oxide(), engine.distances(),
                       complete and estimated)


def _too_costly(engine: ContinuumEngine, thickness: float, predicted: float, last: dict) -> str:
    nx, ny = engine.surface.shape
    grid = "its own grid" if engine.factor == 1 else f"{engine.factor:g}x its grid"
    return (f"the continuum engine would take about {duration(predicted)} to grow {thickness:g} nm of oxide on this "
            f"{nx} x {ny} map at {grid} (predicted from its run at {last['factor']:g} of that resolution: "
            f"{last['steps']:,} time steps), more than the {duration(BUDGET_S)} a run may take without max_seconds: "
            "give max_seconds (the run stops there, with what it reached), a smaller or smoother map, or the fast "
            "engine (--engine fast)")


def _max_steps(engine: ContinuumEngine, thickness: float) -> int:
    """A bound on the time steps to ``thickness``: many times what the stability limit asks for where the
    metal stalls (diffusion coefficient ``t / (k_exp - 1)``, the largest but for sharp bumps; none without
    expansion, ``k_exp = 1``, where the metal recedes at one speed); a run past it has stopped making progress."""
    h = min(engine.dx, engine.dy)
    stalled = 2 * thickness / (engine.k_exp - 1) if engine.k_exp > 1 else 0.0
    return int(100 * (thickness / h + stalled * thickness / h ** 2) + 10_000)


__all__ = ["converge", "error_columns", "observed_orders", "relative_error", "volume_error", "predicted_seconds",
           "estimate_order", "TooCostly", "ORDER_LOW", "ORDER_HIGH", "ASYMPTOTIC_CHANGE", "ORDER_CAP", "ROUGH_ORDER",
           "SMOOTH_CURVATURE", "SMOOTH_STEADY", "SMOOTH_ORDER", "NOISE_CURVATURE", "FLOOR", "BUDGET_S", "SECONDS_PER_POINT_STEP",
           "LEVEL_GROWTH", "MIN_LEVEL_S", "SETTLE_S"]
