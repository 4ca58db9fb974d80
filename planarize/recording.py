"""The record of a run and the loop that makes it, shared by every engine: `Anodization` (what a run returns),
`Snapshot`, `record_run` (advance an engine to a thickness, taking history rows and snapshots on the way),
`progress_bar` and `Stalled`. `planarize.anodize` checks a run's arguments and hands it to its engine's settings
(`planarize.engines.protocol.EngineSettings.run`); the engines' drivers use what is here.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from labrig.validate import InputError

from .heightfield import Surface
from .metrics import history_row

#: Memory a history row takes until the run ends, bytes (a dict of 15 floats, ~1.3 kB, then its table entries).
HISTORY_ROW_BYTES = 2048
#: Memory an engine needs per grid point, bytes (measured: the fast engine 0.89 GB at 1025 x 1025;
#: the reference engine's sets are Python objects, about twice that).
ENGINE_BYTES_PER_POINT = 2000


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
    distances : ndarray or None
        Every metal point's distance to the oxide at the end, nm (None when the record does not hold them).
    complete : bool
        False when the run stopped at its wall-time budget before the target thickness.
    """

    parameters: dict
    history: dict
    snapshots: list
    initial: Surface
    metal: Surface
    oxide: Surface
    distances: np.ndarray | None = field(repr=False, default=None)
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


def run_bytes(points: int, rows: int, snapshots: int) -> int:
    """Memory a run of ``points`` grid points needs, bytes: the engine, ``snapshots`` snapshots (metal, oxide
    and distances: 3 floats per point each) and ``rows`` history rows (one more of each where a wall-time
    budget stops the run)."""
    return points * (ENGINE_BYTES_PER_POINT + 3 * 8 * (snapshots + 1)) + HISTORY_ROW_BYTES * (rows + 1)


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


def progress_bar(total: float, desc: str = "oxide"):
    """A progress bar in nm of oxide, with its ETA."""
    from labrig.progress import progress_bar

    return progress_bar(total, unit="nm", desc=desc, bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} nm "
                                                                   "[{elapsed}<{remaining}]")


__all__ = ["Anodization", "Snapshot", "Stalled", "record_run", "progress_bar", "run_bytes", "HISTORY_ROW_BYTES",
           "ENGINE_BYTES_PER_POINT"]
