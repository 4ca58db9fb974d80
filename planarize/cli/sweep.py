"""Sweeps of planarize runs: a base scene, axes over its keys, seeds; one roughness row per run.

The engine is `labrig.sweeps` (local cores or a Dask cluster, resumable, one
table); this module supplies the runner. A run's parameters are a scene
file's (`planarize.io.scenefile`: ``name``, ``seed``, ``[surface]``, ``[run]``, ``[engine]``),
checked like one (an unknown key is an error naming it, e.g. ``run.k_exps``)
and completed with every default before anything runs.

Thesis Fig 3-13 (the hill at several expansion coefficients; Al ~1.3, Ta 2.3)::

    [base]                         # or base = "hill" (a built-in scene: hill, depression, ta, tilted)
    surface.kind = "hill"          # or base = "hill.toml" (a scene file: `planarize scene hill --save`)
    run.thickness = 1.0
    run.step = 0.01
    run.record = [0.25, 0.5, 0.75, 1.0]     # also report the roughness at these thicknesses

    [axes]
    "run.k_exp" = [1.3, 1.8, 2.0, 2.3, 2.8]

then ``planarize sweep fig3-13.toml`` and ``planarize sweep-plot
fig3-13/table.csv --metric oxide_rms_nm --x run.k_exp``. Each row has the
final RMS and z-range of metal and oxide (and their initial values), the
thickness reached with the spread of the distances, the volume balance
error, the work done, and, when ``run.record`` is a list of thicknesses,
``metal_rms_nm@T``, ``metal_zrange_nm@T``, ``oxide_rms_nm@T``,
``oxide_zrange_nm@T`` at each of them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from labrig.sweeps import load_sweep_file
from labrig.sweeps.files import SweepFile
from labrig.validate import InputError

from ..engines import engine_to_dict
from ..io.scenefile import load_scene, scene_from_dict
from ..scene import RUN, SCENES, PlanarizeScene

#: History columns reported at each recorded thickness (``<column>@<thickness>``).
AT_COLUMNS = ("metal_rms_nm", "metal_zrange_nm", "oxide_rms_nm", "oxide_zrange_nm")
#: Keys of `planarize.cli.commands.summarize` left out of a row (they are parameters, or the sweep's own wall time).
_NOT_RESULTS = ("name", "engine", "k_exp", "step_nm", "wall_s")


def scene_to_dict(scene: PlanarizeScene) -> dict:
    """Every parameter of ``scene`` as nested plain data (a scene file's tables; unset values left out).

    ``scene_from_dict(scene_to_dict(scene)) == scene``.
    """
    surface = {key: value for key, value in scene.surface.params.items() if value is not None}
    run = {key: getattr(scene.run, key) for key in RUN if getattr(scene.run, key) is not None}
    return {"name": scene.name, "seed": scene.seed, "surface": {"kind": scene.surface.kind, **surface}, "run": run,
            "engine": engine_to_dict(scene.engine)}


@dataclass(frozen=True)
class AnodizeRunner:
    """Runs one planarize scene per parameter set (`planarize.anodize`); its row is the roughness summary.

    Parameters
    ----------
    quick : float, optional
        Scale every run down with `PlanarizeScene.quick` (in (0, 1]); the
        scaled scene is what is hashed and recorded.
    """

    quick: float | None = None
    kind = "planarize.anodize"
    state_suffix = ".npz"

    def canonical(self, params: dict) -> dict:
        """The full parameters of the scene ``params`` describes (ValueError naming a bad key)."""
        scene = scene_from_dict(params)
        return scene_to_dict(scene if self.quick is None else scene.quick(self.quick))

    def __call__(self, params: dict, state_path: Path | None = None) -> dict:
        from ..io.results import save_run
        from .commands import summarize

        scene = scene_from_dict(params)
        run = scene.anodize()
        row = {key: value for key, value in summarize(scene, run).items() if key not in _NOT_RESULTS}
        if isinstance(scene.run.record, list):
            history = run.history
            for k, target in enumerate(history["target_nm"]):
                if target < scene.run.thickness:
                    row.update({f"{column}@{target:g}": float(history[column][k]) for column in AT_COLUMNS})
        if state_path is not None:
            save_run(run, state_path)
        return row


def _read_base(name: str, base_dir: Path) -> dict:
    """``base = "hill"`` (a built-in scene) or ``base = "my-scene.toml"`` (a scene file beside the sweep).

    Its engine's settings are those it sets away from their defaults, so that an axis ``engine.kind`` switches
    engine (an engine refuses another's settings; a base that sets one says so).
    """
    if name in SCENES:
        scene = SCENES[name]
    else:
        path = base_dir / name
        if not path.is_file() and not name.endswith(".toml"):
            raise InputError(f"base {name!r} is neither a built-in scene ({', '.join(SCENES)}) nor a scene file")
        scene = load_scene(path)
    declared = type(scene.engine).PARAMS
    return {**scene_to_dict(scene),
            "engine": {"kind": scene.engine.name, **{k: v for k, v in scene.engine.options().items() if k in declared}}}


def load_sweep(path: str | os.PathLike) -> SweepFile:
    """Read a planarize sweep file (`labrig.sweeps.files`); its seeds go to the scene's ``seed``.

    An inline ``[base]`` table's ``surface.path`` (a measured height map) is
    relative to the sweep file, as in a scene file.
    """
    path = Path(path)
    sweep_file = load_sweep_file(path, seed_key="seed", read_base=_read_base)
    surface = sweep_file.sweep.base.get("surface")
    if isinstance(surface, dict) and isinstance(surface.get("path"), str):
        surface["path"] = str(path.parent / surface["path"])  # an absolute path stays as it is
    return sweep_file
