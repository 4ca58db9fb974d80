"""The two contracts of planarize's engines, as `typing.Protocol` classes.

`EngineSettings`
    What `planarize.anodize` is given as ``engine``: a frozen settings object (`planarize.engines.Continuum`,
    `Fast`, `Reference`, `Matlab`) that names its engine, states its settings as plain data, builds its engine
    on a surface and runs it. `planarize.anodize` checks a run's arguments once and calls ``run``; it knows no
    engine by its type.
`RunningEngine`
    What ``build`` returns and `planarize.recording.record_run` advances: the state of one run on one grid
    (thickness reached, both surfaces, the distances, the volumes, the counters the history records).

A new engine is a settings class and an engine class that satisfy these; its name goes into
`planarize.engines.HOMES`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from ..heightfield import Surface
    from ..model import Model
    from ..recording import Anodization


@runtime_checkable
class RunningEngine(Protocol):
    """One run's state on one grid, advanced by `planarize.recording.record_run`."""

    name: str
    k_exp: float
    iterations: int
    point_updates: int

    @property
    def thickness(self) -> float:
        """The oxide thickness reached, nm."""

    @property
    def D(self) -> np.ndarray:
        """Every metal point's distance to the oxide, nm."""

    def advance(self, until: float = ...) -> None:
        """One step or sweep, not past ``until`` (nm of oxide) where the engine can stop at a thickness."""

    def metal(self) -> Surface: ...

    def oxide(self) -> Surface: ...

    def distances(self) -> np.ndarray: ...

    def roughness(self) -> dict:
        """RMS and z-range of both surfaces, nm (`planarize.metrics.ESTIMATED`'s columns)."""

    def metal_lost(self) -> float:
        """Metal volume consumed since the start, nm^3."""

    def oxide_gained(self) -> float:
        """Oxide volume added above the starting surface, nm^3."""


@runtime_checkable
class EngineSettings(Protocol):
    """An engine's settings: what ``anodize(..., engine=...)`` takes."""

    name: str

    def options(self) -> dict:
        """The settings that differ from the defaults, as plain data (a run's ``parameters`` hold them)."""

    def build(self, metal: Surface, oxide: Surface | None, model: Model) -> RunningEngine:
        """The engine on ``metal``'s grid (with an existing ``oxide``, where the engine can continue one)."""

    def run(self, metal: Surface, oxide: Surface | None, thickness: float, model: Model, rows_at: np.ndarray,
            shots_at: np.ndarray, *, progress: bool = False, observer: Callable | None = None,
            max_seconds: float | None = None) -> Anodization:
        """The run `planarize.anodize` asks for, its arguments checked."""


__all__ = ["EngineSettings", "RunningEngine"]
