"""`anodize`: grow an oxide on a metal surface to a target thickness and record how it planarizes.

>>> from planarize import Model, anodize, surfaces
>>> run = anodize(surfaces.hill(), thickness=1.0, model=Model(k_exp=2.3, step=0.01))   # doctest: +SKIP
>>> run.history["oxide_rms_nm"]                                         # doctest: +SKIP
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from labrig.params import Param
from labrig.validate import InputError, available_memory, count, flag, real, reals, within_memory

from .engines import engine_settings
from .engines.base import check_oxide
from .engines.continuum import Continuum
from .metrics import history_row
from .model import Model
from .heightfield import Surface

#: Thickest oxide grown, nm (1 mm).
MAX_THICKNESS = 1e6
#: Most steps of thickness a run may take (thickness / step; the thesis's hill takes 100, its Ta film 400).
MAX_STEPS_PER_RUN = 1_000_000
#: Most history rows or snapshots of a run.
MAX_RECORD = 100_000
#: Memory a history row takes until the run ends, bytes (a dict of 15 floats, ~1.3 kB, then its table entries).
HISTORY_ROW_BYTES = 2048
#: Memory an engine needs per grid point, bytes (measured: the fast engine 0.89 GB at 1025 x 1025;
#: the reference engine's sets are Python objects, about twice that).
ENGINE_BYTES_PER_POINT = 2000
#: The run's own arguments (`labrig.params.Param`): `anodize` checks them with these (and the rules between
#: them: `check_steps`, `thickness_targets`), and a scene file's ``[run]`` table takes them
#: (`planarize.scene.RunSettings`).
RUN_ARGUMENTS = {
    "thickness": Param("float", 0.0, MAX_THICKNESS, unit="nm", doc="oxide thickness to grow"),
    "record": Param("either", doc="history rows", rule="thicknesses in [0, thickness]",
                    parts=(Param("int", 1, MAX_RECORD, doc="a count n (n + 1 evenly spaced rows)"),
                           Param("floats", 0.0, MAX_THICKNESS, unit="nm", most=MAX_RECORD, doc="a list of thicknesses"))),
    "snapshots": Param("floats", 0.0, MAX_THICKNESS, unit="nm", most=MAX_RECORD, optional=True,
                       doc="thicknesses at which both surfaces are kept", rule="in [0, thickness]",
                       unset="[0, thickness]"),
}


@dataclass(frozen=True)
class Snapshot:
    """Both surfaces when the oxide reached ``target`` (``thickness``, nm, is the thickness actually reached)."""

    target: float
    thickness: float
    metal: Surface
    oxide: Surface
    distances: np.ndarray


@dataclass
class Anodization:
    """The record of one run.

    Attributes
    ----------
    parameters : dict
        Everything the run was given (engine, k_exp, step, distance, ...).
    history : dict of ndarray
        One column per `planarize.metrics.HISTORY_COLUMNS` entry, one row per
        recorded thickness.
    snapshots : list of Snapshot
        Full surfaces at the requested thicknesses.
    initial : Surface
        The metal at the start.
    metal, oxide : Surface
        The surfaces at the end.
    distances : ndarray
        Every metal point's distance to the oxide at the end, nm.
    complete : bool
        False when the run stopped at its wall-time budget before the target thickness.
    """

    parameters: dict
    history: dict
    snapshots: list
    initial: Surface
    metal: Surface
    oxide: Surface
    distances: np.ndarray = field(repr=False, default=None)
    complete: bool = True

    @property
    def thickness(self) -> float:
        """Oxide thickness reached, nm."""
        return float(self.history["thickness_nm"][-1])

    @property
    def wall_s(self) -> float:
        return float(self.history["wall_s"][-1])

    def rows(self) -> list[dict]:
        """The history as a list of row dicts (CSV/JSON friendly)."""
        keys = list(self.history)
        return [{k: self.history[k][i].item() for k in keys} for i in range(len(self.history[keys[0]]))]


def check_steps(thickness: float, step: float) -> None:
    """`InputError` unless ``step`` fits ``thickness`` (nm): at most the thickness, at least `MAX_STEPS_PER_RUN`-th
    of it (a smaller step would take days)."""
    if 0 < thickness < step:
        raise InputError(f"step ({step:g} nm) must not exceed thickness ({thickness:g} nm): one oxidation would "
                         "overshoot the target")
    if thickness / step > MAX_STEPS_PER_RUN:
        raise InputError(f"thickness / step = {thickness / step:.3g} steps per grid point, more than the "
                         f"{MAX_STEPS_PER_RUN:,} a run may take: use a larger step")


def run_bytes(points: int, rows: int, snapshots: int) -> int:
    """Memory a run of ``points`` grid points needs, bytes: the engine, ``snapshots`` snapshots (metal, oxide
    and distances: 3 floats per point each) and ``rows`` history rows (one more of each where a wall-time
    budget stops the run)."""
    return points * (ENGINE_BYTES_PER_POINT + 3 * 8 * (snapshots + 1)) + HISTORY_ROW_BYTES * (rows + 1)


def thickness_targets(spec, thickness: float, name: str, limit: int = MAX_RECORD, empty: bool = False) -> np.ndarray:
    """The thicknesses of ``record`` or ``snapshots`` (nm, ascending): a count ``n`` for ``n + 1`` evenly spaced
    ones from 0 to ``thickness``, or a list in [0, ``thickness``] (empty only if ``empty``); at most ``limit``."""
    if isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        spec = count(name, spec, 1, limit)
        return np.linspace(0.0, thickness, spec + 1) if spec > 1 else np.array([0.0, thickness])
    if empty and isinstance(spec, (list, tuple, np.ndarray)) and not len(spec):
        return np.zeros(0)
    if isinstance(spec, (str, bytes, dict)) or not hasattr(spec, "__len__") or not len(spec):
        raise InputError(f"{name} must be a count in [1, {limit:,}] or a non-empty list of thicknesses (nm), "
                         f"got {spec!r}")
    if len(spec) > limit:
        raise InputError(f"{name} lists {len(spec):,} thicknesses, more than the {limit:,} allowed")
    values = reals(name, spec, None, 0.0, thickness, unit="nm")
    return np.unique(values)


def _model_and_engine(model, engine):
    """The `Model` (default ``Model()``) and the engine settings of a call."""
    model = Model() if model is None else model
    if not isinstance(model, Model):
        raise InputError(f"model must be a planarize.Model, got {type(model).__name__}")
    return model, engine_settings(engine)


def anodize(metal: Surface, thickness: float, model: Model | None = None, engine: str | object = "continuum", *,
            record=50, snapshots=None, oxide: Surface | None = None, progress: bool = False,
            observer: Callable | None = None, max_seconds: float | None = None) -> Anodization:
    """Oxidize ``metal`` until the oxide is ``thickness`` nm thick everywhere (thesis section 3.3).

    Parameters
    ----------
    metal : Surface
        Starting metal surface.
    thickness : float
        Target oxide thickness, nm, in [0, `MAX_THICKNESS`]: the run stops when the smallest
        metal-oxide distance reaches it (the thesis's termination).
    model : Model, optional
        The physics: ``k_exp``, ``step``, ``distance``, ``volume`` (`planarize.Model`; default ``Model()``).
        The step must not exceed the thickness.
    engine : str or engine settings
        ``"continuum"`` (default; `planarize.engines.Continuum` for its settings: ``rtol``, the
        discretization error aimed at): the limit of the thesis's rule as grid and step shrink, computed
        at two resolutions so that every run states its discretization error (history columns
        ``*_error_nm``, `planarize.resolution`). ``"fast"`` (`planarize.engines.Fast`: batch tolerance,
        interacting candidates, threads), ``"reference"`` (the thesis's sequential algorithm) or
        ``"matlab"`` (the reference with the Matlab listings' shortcuts): the thesis's discrete algorithm
        at the given grid and ``model.step``.
    record : int or sequence of float
        Thicknesses (nm) at which to add a history row, or a count ``n`` (at most `MAX_RECORD`) for
        ``n + 1`` evenly spaced ones from 0 to ``thickness``. A row is taken as soon as the smallest
        distance reaches its thickness.
    snapshots : sequence of float, optional
        Thicknesses at which to keep both surfaces (default: the start and the end; ``[]`` keeps
        none; at most `MAX_RECORD`, and as many as fit in memory).
    oxide : Surface, optional
        An existing oxide to continue from (default: none yet).
    progress : bool
        Show a progress bar in nm of oxide with an ETA.
    observer : callable, optional
        ``observer(engine)`` once the engine is set up and after every sweep (the engine's
        ``thickness``, ``D``, ``zm``, ``zo``, ``iterations``, ``point_updates`` are its state): for
        measurements during a run.
    max_seconds : float, optional
        Wall-time budget, s: the run stops after the first sweep past it, with ``complete`` False
        and a last history row and snapshot at the thickness reached.

    Returns
    -------
    Anodization
    """
    model, settings = _model_and_engine(model, engine)
    if not isinstance(metal, Surface):
        raise InputError(f"metal must be a planarize.Surface, got {type(metal).__name__}")
    check_oxide(metal, oxide)
    progress = flag("progress", progress)
    if observer is not None and not callable(observer):
        raise InputError(f"observer must be a function observer(engine) or None, got {type(observer).__name__}")
    thickness = RUN_ARGUMENTS["thickness"].check("thickness", thickness)
    check_steps(thickness, model.step)
    if max_seconds is not None:
        max_seconds = real("max_seconds", max_seconds, 0.0, low_open=True, unit="s")
    rows_at = thickness_targets(record, thickness, "record", MAX_RECORD)
    shots_at = thickness_targets([0.0, thickness] if snapshots is None else snapshots, thickness, "snapshots",
                                 MAX_RECORD, empty=True)
    if isinstance(settings, Continuum):
        from .resolution import converge

        if oxide is not None:
            raise InputError("the continuum engine starts from bare metal: oxide must be None (continue an "
                             "existing oxide with engine=\"fast\")")
        return converge(metal, thickness, model, settings, rows_at, shots_at, progress=progress, observer=observer,
                        max_seconds=max_seconds)
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
                                        bar=_progress(thickness) if progress else None, observer=observer,
                                        max_seconds=max_seconds)
    return Anodization(parameters, table, shots, metal, sim.metal(), sim.oxide(), sim.distances(), complete)


class Stalled(InputError):
    """A run that stopped making progress: the map is outside what the engine can compute (say, far steeper than its
    grid resolves); one line saying so and what to try, not a traceback."""


def record_run(sim, thickness: float, rows_at: np.ndarray, shots_at: np.ndarray, *, max_sweeps: int, bar=None,
               observer: Callable | None = None, max_seconds: float | None = None) -> tuple[dict, list, bool]:
    """Advance the engine ``sim`` to ``thickness`` (nm), taking a history row at each of ``rows_at`` and a
    `Snapshot` at each of ``shots_at``; returns (history table, snapshots, complete).

    An engine that can stop at a given thickness (the continuum engine) is advanced to each target
    exactly; a sweep of the thesis's engines oxidizes the points at the smallest distance, and a row is
    taken as soon as the smallest distance has reached its thickness. ``bar`` (a progress bar in nm),
    ``observer`` and ``max_seconds`` as in `anodize`; ``max_sweeps`` bounds the loop.
    """
    history: list[dict] = []
    shots: list[Snapshot] = []
    start = time.perf_counter()
    targets = np.unique(np.concatenate([rows_at, shots_at, [thickness]]))

    def catch_up(final: bool) -> None:
        reached = sim.thickness
        while len(history) < len(rows_at) and (final or rows_at[len(history)] <= reached):
            history.append(history_row(sim, rows_at[len(history)], time.perf_counter() - start))
        while len(shots) < len(shots_at) and (final or shots_at[len(shots)] <= reached):
            shots.append(Snapshot(float(shots_at[len(shots)]), reached, sim.metal(), sim.oxide(), sim.distances()))

    if observer is not None:
        observer(sim)
    try:
        shown = time.perf_counter()
        complete = True
        while sim.thickness < thickness:
            catch_up(final=False)
            if max_seconds is not None and time.perf_counter() - start > max_seconds:
                complete = False
                break
            if sim.iterations >= max_sweeps:
                metal = sim.metal()
                slope = float(np.hypot(*np.gradient(metal.z, *metal.spacing)).max()) if min(metal.shape) > 1 else 0.0
                raise Stalled(f"the {sim.name} engine made no progress: {sim.iterations:,} sweeps reached "
                              f"{sim.thickness:.6g} of {thickness:g} nm on a map whose metal slopes reach {slope:.3g} "
                              "(steeper than its grid resolves): try the fast engine (--engine fast), or a map "
                              "smoothed or resampled to a coarser grid")
            sim.advance(float(targets[np.searchsorted(targets, sim.thickness, side="right")]))
            if not np.isfinite(sim.thickness):
                raise InputError(f"the distances became non-finite at {sim.iterations} sweeps: the surface or the "
                                 f"model (k_exp {sim.k_exp:g}) is outside the model's range")
            if observer is not None:
                observer(sim)
            if bar is not None and time.perf_counter() - shown > 0.2:
                bar.update(min(sim.thickness, thickness) - bar.n)
                shown = time.perf_counter()
        if complete:
            catch_up(final=True)
        else:  # a last row and snapshot where the budget ran out
            reached = sim.thickness
            history.append(history_row(sim, reached, time.perf_counter() - start))
            shots.append(Snapshot(reached, reached, sim.metal(), sim.oxide(), sim.distances()))
        if bar is not None:
            bar.update(min(sim.thickness, thickness) - bar.n)
    finally:  # also on Ctrl-C: the bar ends its line, so that what follows starts on a new one
        if bar is not None:
            bar.close()
    table = {key: np.array([row[key] for row in history]) for key in history[0]}
    return table, shots, complete


def _progress(total: float, desc: str = "oxide"):
    from labrig.progress import progress_bar

    return progress_bar(total, unit="nm", desc=desc, bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} nm "
                                                                   "[{elapsed}<{remaining}]")
