"""`anodize`: grow an oxide on a metal surface to a target thickness and record how it planarizes.

>>> from planarize import anodize, surfaces
>>> run = anodize(surfaces.hill(), thickness=1.0, step=0.01, k_exp=2.3)   # doctest: +SKIP
>>> run.history["oxide_rms_nm"]                                         # doctest: +SKIP
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from labrig.validate import InputError

from .engines.base import Engine
from .metrics import history_row
from .surface import Surface


def engines() -> dict[str, type[Engine]]:
    """The available engines by name."""
    from .engines.reference import MatlabEngine, ReferenceEngine

    found = {"reference": ReferenceEngine, "matlab": MatlabEngine}
    try:
        from .engines.fast import FastEngine
    except ImportError:  # pragma: no cover - the fast engine is part of the package
        return found
    return {**found, "fast": FastEngine}


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
    """

    parameters: dict
    history: dict
    snapshots: list
    initial: Surface
    metal: Surface
    oxide: Surface
    distances: np.ndarray = field(repr=False, default=None)

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


def _targets(spec, thickness: float, name: str) -> np.ndarray:
    if isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        if spec < 1:
            raise InputError(f"{name} must be a count >= 1 or a list of thicknesses, got {spec!r}")
        return np.linspace(0.0, thickness, int(spec) + 1) if spec > 1 else np.array([0.0, thickness])
    try:
        values = np.unique(np.asarray(spec, dtype=float).ravel())
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a count or a list of thicknesses (nm), got {spec!r}") from None
    if values.size and not (np.isfinite(values).all() and values.min() >= 0 and values.max() <= thickness):
        raise InputError(f"{name} must lie in [0, thickness = {thickness:g}] nm, got {spec!r}")
    return values


def anodize(metal: Surface, thickness: float, *, step: float = 0.01, k_exp: float = 2.3, engine: str = "fast",
            distance: str = "thesis", volume: str = "exact", record=50, snapshots=None, oxide: Surface | None = None,
            progress: bool = False, **engine_options) -> Anodization:
    """Oxidize ``metal`` until the oxide is ``thickness`` nm thick everywhere (thesis section 3.3).

    Parameters
    ----------
    metal : Surface
        Starting metal surface.
    thickness : float
        Target oxide thickness, nm (>= 0): the run stops when the smallest
        metal-oxide distance reaches it (the thesis's termination).
    step : float
        Metal height consumed per oxidation, nm (> 0; thesis 0.01 for the hill, 0.5 for Ta).
    k_exp : float
        Oxide volume per metal volume (>= 1; Ta 2.3, Al ~1.3).
    engine : {"fast", "reference", "matlab"}
        ``"reference"``: the thesis's sequential algorithm
        (`planarize.engines.reference`); ``"fast"``: the batched engine
        (`planarize.engines.fast`; compiled when numba is installed); ``"matlab"``: the reference with the Matlab
        listings' shortcuts, to measure what they cost.
    distance : {"thesis", "exact"}
        Point/segment distances as in the thesis, or exact distances to the
        triangulated surfaces (`planarize.engines.features`).
    volume : {"exact", "thesis"}
        Volume accounting (`planarize.engines.base`).
    record : int or sequence of float
        Thicknesses (nm) at which to add a history row, or a count ``n`` for
        ``n + 1`` evenly spaced ones from 0 to ``thickness``. A row is taken
        as soon as the smallest distance reaches its thickness.
    snapshots : sequence of float, optional
        Thicknesses at which to keep both surfaces (default: the start and the end).
    oxide : Surface, optional
        An existing oxide to continue from (default: none yet).
    progress : bool
        Show a progress bar in nm of oxide with an ETA.
    **engine_options
        Passed to the engine (e.g. ``tolerance`` for ``"fast"``).

    Returns
    -------
    Anodization
    """
    available = engines()
    if engine not in available:
        raise InputError(f"engine must be one of {tuple(available)}, got {engine!r}")
    try:
        thickness = float(thickness)
    except (TypeError, ValueError):
        raise InputError(f"thickness must be a number of nm, got {thickness!r}") from None
    if not (math.isfinite(thickness) and thickness >= 0):
        raise InputError(f"thickness must be >= 0 nm, got {thickness!r}")
    rows_at = _targets(record, thickness, "record")
    shots_at = _targets([0.0, thickness] if snapshots is None else snapshots, thickness, "snapshots")
    sim = available[engine](metal, oxide, k_exp=k_exp, step=step, distance=distance, volume=volume,
                            **engine_options)
    parameters = {"engine": engine, "thickness": thickness, "step": sim.step, "k_exp": sim.k_exp,
                  "distance": distance, "volume": volume, "boundary": metal.boundary,
                  "shape": list(metal.shape), "spacing": list(metal.spacing), **engine_options}
    history: list[dict] = []
    shots: list[Snapshot] = []
    start = time.perf_counter()

    def catch_up(final: bool) -> None:
        reached = sim.thickness
        while len(history) < len(rows_at) and (final or rows_at[len(history)] <= reached):
            history.append(history_row(sim, rows_at[len(history)], time.perf_counter() - start))
        while len(shots) < len(shots_at) and (final or shots_at[len(shots)] <= reached):
            shots.append(Snapshot(float(shots_at[len(shots)]), reached, sim.metal(), sim.oxide(), sim.distances()))

    bar = _progress(thickness) if progress else None
    shown = time.perf_counter()
    while sim.thickness < thickness:
        catch_up(final=False)
        sim.advance()
        if bar is not None and time.perf_counter() - shown > 0.2:
            bar.update(min(sim.thickness, thickness) - bar.n)
            shown = time.perf_counter()
    catch_up(final=True)
    if bar is not None:
        bar.update(thickness - bar.n)
        bar.close()
    table = {key: np.array([row[key] for row in history]) for key in history[0]}
    return Anodization(parameters, table, shots, metal, sim.metal(), sim.oxide(), sim.distances())


def _progress(total: float):
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="nm", desc="oxide", bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} nm "
                                                                 "[{elapsed}<{remaining}]")
