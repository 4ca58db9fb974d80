"""`anodize`: grow an oxide on a metal surface to a target thickness and record how it planarizes.

>>> from planarize import Model, anodize, surfaces
>>> run = anodize(surfaces.hill(), thickness=1.0, model=Model(k_exp=2.3, step=0.01))   # doctest: +SKIP
>>> run.history["oxide_rms_nm"]                                         # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from labrig.params import Param
from labrig.validate import InputError, count, flag, real, reals

from .engines import engine_settings
from .engines.base import check_oxide
from .heightfield import Surface
from .model import Model
from .recording import ENGINE_BYTES_PER_POINT, HISTORY_ROW_BYTES, Anodization, Snapshot, Stalled, record_run, run_bytes

#: Thickest oxide grown, nm (1 mm).
MAX_THICKNESS = 1e6
#: Most steps of thickness a run may take (thickness / step; the thesis's hill takes 100, its Ta film 400).
MAX_STEPS_PER_RUN = 1_000_000
#: Most history rows or snapshots of a run.
MAX_RECORD = 100_000
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


def check_steps(thickness: float, step: float) -> None:
    """`InputError` unless ``step`` fits ``thickness`` (nm): at most the thickness, at least `MAX_STEPS_PER_RUN`-th
    of it (a smaller step would take days)."""
    if 0 < thickness < step:
        raise InputError(f"step ({step:g} nm) must not exceed thickness ({thickness:g} nm): one oxidation would "
                         "overshoot the target")
    if thickness / step > MAX_STEPS_PER_RUN:
        raise InputError(f"thickness / step = {thickness / step:.3g} steps per grid point, more than the "
                         f"{MAX_STEPS_PER_RUN:,} a run may take: use a larger step")


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
        at three resolutions or more so that every run states its discretization error, or that it is not yet
        in its asymptotic regime (history columns ``*_error_nm``, `planarize.engines.resolution`). ``"fast"`` (`planarize.engines.Fast`: batch tolerance,
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
    return settings.run(metal, oxide, thickness, model, rows_at, shots_at, progress=progress, observer=observer,
                        max_seconds=max_seconds)


#: `Anodization`, `Snapshot`, `Stalled`, `record_run` and `run_bytes` live in `planarize.recording`; they are
#: importable from here as before.
__all__ = ["anodize", "check_steps", "thickness_targets", "RUN_ARGUMENTS", "MAX_THICKNESS", "MAX_STEPS_PER_RUN",
           "MAX_RECORD", "Anodization", "Snapshot", "Stalled", "record_run", "run_bytes", "HISTORY_ROW_BYTES",
           "ENGINE_BYTES_PER_POINT"]
