"""A planarize scene: a starting surface and the anodization to run on it (`PlanarizeScene`).

A scene holds top-level ``name`` and ``seed``, a surface (`SurfaceSpec`: ``kind`` and that kind's
parameters), a run (`RunSettings`: the thickness, the `Model`, the records) and the engine that computes it (its
settings object, `planarize.engines`; a scene file's ``[engine]`` table, keyed by ``kind``). Every parameter but the
``path`` of a ``"file"`` surface has a default (the surface kinds' defaults are those of the
`planarize.surfaces` functions); each is declared once here with its type, unit and range, which the
scene files (`planarize.io.scenefile`) write as comments. Wrong types and out-of-range values raise a
`labrig.validate.InputError` naming the key (e.g. ``run.step``).

Surface kinds: ``"hill"``, ``"depression"``, ``"bump"``, ``"tilted_plane"``,
``"random_roughness"`` (seeded by the top-level ``seed``) and ``"file"``
(a measured height map, `planarize.io.load_heights`).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from dataclasses import dataclass, field

from labrig.params import Param, check_fields, file_schema
from labrig.tomlfile import check_keys
from labrig.validate import MAX_SEED, InputError, real

from . import surfaces
from .anodize import RUN_ARGUMENTS, Anodization, anodize, check_steps, thickness_targets
from .engines import Continuum, Fast, Matlab, Reference, engine_from_dict, engine_settings, engine_to_dict
from .heightfield import Surface
from .io.heights import LOAD_OPTIONS, load_heights
from .model import Model

#: Surface kinds: kind -> (builder, {parameter: `labrig.params.Param`}); the builders check their arguments
#: with the same declarations.
SURFACE_KINDS: dict[str, tuple[Callable[..., Surface], dict[str, Param]]] = {
    "hill": (surfaces.hill, {k: p for k, p in surfaces.BUMP.items() if k != "height"}),
    "depression": (surfaces.depression, {k: p for k, p in surfaces.BUMP.items() if k != "height"}),
    "bump": (surfaces.bump, surfaces.BUMP),
    "tilted_plane": (surfaces.tilted_plane, surfaces.TILTED_PLANE),
    "random_roughness": (surfaces.random_roughness, surfaces.RANDOM_ROUGHNESS),
    "file": (load_heights, LOAD_OPTIONS),
}
#: Surface kinds as a scene file states them: kind -> (builder, {parameter: (file kind, comment)}).
SURFACES: dict[str, tuple[Callable[..., Surface], dict]] = {kind: (builder, file_schema(params)) for kind, (builder, params) in SURFACE_KINDS.items()}
#: The ``[run]`` keys (`labrig.params.Param`): the run's own arguments (`planarize.anodize.RUN_ARGUMENTS`) and the
#: `Model`'s fields, each declared once where it is checked. The engine's settings are the ``[engine]`` table's,
#: declared by each engine's settings class (`planarize.engines.engine_params`).
RUN_PARAMS = {
    "thickness": RUN_ARGUMENTS["thickness"],
    "step": Model.PARAMS["step"],
    "k_exp": Model.PARAMS["k_exp"],
    "rule": Model.PARAMS["rule"],
    "distance": Model.PARAMS["distance"],
    "volume": Model.PARAMS["volume"],
    "record": RUN_ARGUMENTS["record"],
    "snapshots": RUN_ARGUMENTS["snapshots"],
}
#: The ``[run]`` keys of scene files written before 0.3's ``[engine]`` table: still read, into ``[engine]``.
OLD_RUN_KEYS = {"engine": "kind", "rtol": "rtol", "tolerance": "tolerance", "interacting": "interacting"}
#: Run settings as a scene file states them: key -> (file kind, comment).
RUN = file_schema(RUN_PARAMS)
#: Top-level keys.
TOP_PARAMS = {"name": Param("str", high=1000, doc="label of the run"),
              "seed": Param("int", 0, MAX_SEED, doc="seeds random_roughness")}
TOP = file_schema(TOP_PARAMS)


def _defaults(kind: str) -> dict:
    builder, schema = SURFACE_KINDS[kind]
    params = inspect.signature(builder).parameters
    if kind in ("hill", "depression"):
        params = inspect.signature(surfaces.bump).parameters
    return {key: _plain(params[key].default) for key in schema if params[key].default is not inspect.Parameter.empty}


def _plain(value):
    """Tuples (of tuples) as lists: the form TOML reads back."""
    return [_plain(v) for v in value] if isinstance(value, (list, tuple)) else value


# -- the scene ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class SurfaceSpec:
    """A starting surface: a kind of `SURFACES` and all its parameters (defaults filled in).

    Building it (`build`) makes the `Surface`; construction only checks
    types and, for the synthetic kinds, builds it once to check the values.
    """

    kind: str = "hill"
    params: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in SURFACES:
            raise InputError(f"kind must be one of {', '.join(map(repr, SURFACES))}, got {self.kind!r}")
        schema = SURFACE_KINDS[self.kind][1]
        if not isinstance(self.params, dict):
            raise InputError(f"params must be a dict, got {type(self.params).__name__}")
        check_keys("surface", self.params, ["kind", *schema])
        if self.kind == "file" and "path" not in self.params:
            raise InputError("surface.path is required for kind = \"file\" (the height map to import)")
        given = {key: schema[key].check(f"surface.{key}", value) for key, value in self.params.items()}
        full = {**_defaults(self.kind), **given}
        object.__setattr__(self, "params", {key: _plain(full[key]) for key in schema if key in full})
        if self.kind != "file":
            self.build()  # the rules between values (odd points, widths that divide) are the builders'

    def build(self, seed: int = 0) -> Surface:
        """The `Surface` (``seed`` is used by ``"random_roughness"``)."""
        builder = SURFACES[self.kind][0]
        params = dict(self.params)
        if self.kind == "random_roughness":
            params["seed"] = seed
        if self.kind == "file":
            return builder(params.pop("path"), **params)
        if "slope" in params:
            params["slope"] = tuple(params["slope"])
        try:
            return builder(**params)
        except (ValueError, TypeError) as exc:
            raise InputError(_name_key(str(exc), params)) from None


def _name_key(message: str, keys) -> str:
    head = message.split(" ", 1)[0]
    return f"surface.{message}" if head in keys else f"surface: {message}"


@dataclass(frozen=True)
class RunSettings:
    """What `planarize.anodize` is asked to do, as a scene file's ``[run]`` table: the thickness, the
    `planarize.Model` (``step``, ``k_exp``, ``distance``, ``volume``, ``rule``), the records and snapshots.
    The engine that computes it is the scene's (`PlanarizeScene.engine`)."""

    thickness: float = 1.0
    step: float = 0.01
    k_exp: float = 2.3
    rule: str = "thesis"
    distance: str = "thesis"
    volume: str = "exact"
    record: int | list = 50
    snapshots: list | None = None

    def __post_init__(self):
        check_fields(self, RUN_PARAMS)
        check_steps(self.thickness, self.step)
        thickness_targets(self.record, self.thickness, "record")
        if self.snapshots is not None:
            thickness_targets(self.snapshots, self.thickness, "snapshots", empty=True)

    def model(self) -> Model:
        """The physics of the run."""
        return Model(k_exp=self.k_exp, step=self.step, distance=self.distance, volume=self.volume, rule=self.rule)

    def options(self) -> dict:
        """Keyword arguments of `planarize.anodize` (all but the surface, the engine and ``progress``)."""
        return {"thickness": self.thickness, "model": self.model(), "record": self.record, "snapshots": self.snapshots}


@dataclass(frozen=True)
class PlanarizeScene:
    """A planarize scene: a starting surface and a run.

    Attributes
    ----------
    name : str
    seed : int
        Seeds ``"random_roughness"`` surfaces.
    surface : SurfaceSpec
    run : RunSettings
    engine : Continuum, Fast, Reference or Matlab
        The engine's settings (`planarize.engines`), or an engine's name for its defaults; default `Continuum`.
    """

    name: str = "scene"
    seed: int = 0
    surface: SurfaceSpec = field(default_factory=SurfaceSpec)
    run: RunSettings = field(default_factory=RunSettings)
    engine: Continuum | Fast | Reference | Matlab = field(default_factory=Continuum)

    def __post_init__(self):
        check_fields(self, TOP_PARAMS)
        if not isinstance(self.surface, SurfaceSpec) or not isinstance(self.run, RunSettings):
            raise InputError("surface must be a SurfaceSpec and run a RunSettings")
        object.__setattr__(self, "engine", engine_settings(self.engine))
        if self.run.rule != "thesis" and self.engine.name != "continuum":
            raise InputError(f"run.rule {self.run.rule!r} is computed by the continuum engine only, not by engine "
                             f"{self.engine.name!r}")

    def build_surface(self) -> Surface:
        """The starting metal surface."""
        return self.surface.build(self.seed)

    def anodize(self, *, progress: bool = False, **options) -> Anodization:
        """Run the scene (`planarize.anodize`); ``options`` replace its arguments for this call (e.g.
        ``snapshots``, ``observer``, ``max_seconds``)."""
        return anodize(self.build_surface(), progress=progress,
                       **{**self.run.options(), "engine": self.engine, **options})

    def replace(self, **changes) -> PlanarizeScene:
        """A copy with top-level fields replaced: ``run`` settings may be given as a dict of the ones that change,
        ``engine`` as settings, a name (that engine's defaults) or a dict (an ``[engine]`` table with its
        ``kind``, or without it the settings of this scene's engine that change)."""
        if isinstance(changes.get("run"), dict):
            changes["run"] = dataclasses.replace(self.run, **changes["run"])
        engine = changes.get("engine")
        if isinstance(engine, dict):
            table = engine if "kind" in engine else {**engine_to_dict(self.engine), **engine}
            changes["engine"] = engine_from_dict(table)
        return dataclasses.replace(self, **changes)

    def quick(self, fraction: float) -> PlanarizeScene:
        """A cheaper version for a first look: ``step / fraction``, refinement ``refine * fraction``
        (rounded, at least 1), and on the continuum engine a tolerance ``rtol / fraction`` (at most 1);
        thickness, records and snapshots unchanged.
        """
        fraction = real("quick fraction", fraction, 0.0, 1.0, low_open=True)
        params = dict(self.surface.params)
        if "refine" in params:
            params["refine"] = max(1, round(params["refine"] * fraction))
        run = {"step": float(f"{self.run.step / fraction:.12g}")}
        engine = self.engine
        if isinstance(engine, Continuum):
            engine = dataclasses.replace(engine, rtol=min(1.0, float(f"{engine.rtol / fraction:.12g}")))
        return self.replace(name=f"{self.name} quick {fraction:g}", surface=SurfaceSpec(self.surface.kind, params),
                            run=run, engine=engine)


# -- named scenes ------------------------------------------------------------------------------

#: The built-in scenes: the thesis's hill and depression (Figs 3-8, 3-9), its Ta film (Figs 3-11, 3-12),
#: and a tilted plane (which anodization must leave unchanged in shape).
SCENES = {
    "hill": PlanarizeScene("hill", surface=SurfaceSpec("hill"), run=RunSettings(thickness=1.0, step=0.01)),
    "depression": PlanarizeScene("depression", surface=SurfaceSpec("depression"),
                                 run=RunSettings(thickness=1.0, step=0.01)),
    "ta": PlanarizeScene("ta", surface=SurfaceSpec("random_roughness"),
                         run=RunSettings(thickness=200.0, step=0.5, record=40,
                                         snapshots=[0.0, 50.0, 100.0, 150.0, 200.0])),
    "tilted": PlanarizeScene("tilted", surface=SurfaceSpec("tilted_plane"), run=RunSettings(thickness=1.0, step=0.01)),
}


def get_scene(name: str) -> PlanarizeScene:
    """A built-in scene by name (`SCENES`)."""
    if name not in SCENES:
        raise InputError(f"unknown scene {name!r}; built-in scenes: {', '.join(SCENES)}")
    return SCENES[name]


__all__ = ["PlanarizeScene", "SurfaceSpec", "RunSettings", "SCENES", "SURFACE_KINDS", "SURFACES", "RUN_PARAMS", "RUN", "OLD_RUN_KEYS",
           "TOP_PARAMS", "TOP", "get_scene"]
