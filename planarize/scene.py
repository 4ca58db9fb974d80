"""A planarize scene: a starting surface and the anodization to run on it (`PlanarizeScene`).

A scene holds top-level ``name`` and ``seed``, a surface (`SurfaceSpec`: ``kind`` and that kind's
parameters) and a run (`RunSettings`: the arguments of `planarize.anodize`). Every parameter but the
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
from .engines import ENGINES, Continuum, Fast, engine_settings
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
#: The ``[run]`` keys (`labrig.params.Param`): the run's own arguments (`planarize.anodize.RUN_ARGUMENTS`), the
#: `Model`'s fields and the engines' settings, each declared once where it is checked.
RUN_PARAMS = {
    "thickness": RUN_ARGUMENTS["thickness"],
    "step": Model.PARAMS["step"],
    "k_exp": Model.PARAMS["k_exp"],
    "engine": Param("str", choices=tuple(ENGINES), doc='the engine ("continuum": the thesis rule\'s converged '
                                                      'limit, with its error; "reference": the thesis algorithm, '
                                                      'slow)'),
    "rule": Model.PARAMS["rule"],
    "rtol": dataclasses.replace(Continuum.PARAMS["rtol"], optional=True, unset=f"{Continuum().rtol:g}"),
    "distance": Model.PARAMS["distance"],
    "volume": Model.PARAMS["volume"],
    "tolerance": Fast.PARAMS["tolerance"],
    "interacting": Fast.PARAMS["interacting"],
    "record": RUN_ARGUMENTS["record"],
    "snapshots": RUN_ARGUMENTS["snapshots"],
}
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
    `planarize.Model` (``step``, ``k_exp``, ``distance``, ``volume``, ``rule``), the engine and its settings
    (``rtol`` is the continuum engine's, ``tolerance`` and ``interacting`` the fast engine's), the
    records and snapshots."""

    thickness: float = 1.0
    step: float = 0.01
    k_exp: float = 2.3
    engine: str = "continuum"
    rule: str = "thesis"
    rtol: float | None = None
    distance: str = "thesis"
    volume: str = "exact"
    tolerance: float | None = None
    interacting: str = "wait"
    record: int | list = 50
    snapshots: list | None = None

    def __post_init__(self):
        check_fields(self, RUN_PARAMS)
        if self.engine != "fast" and (self.tolerance is not None or self.interacting != "wait"):
            raise InputError(f"tolerance and interacting are settings of the fast engine, not of engine "
                             f"{self.engine!r}: leave them out")
        if self.engine != "continuum" and self.rtol is not None:
            raise InputError(f"rtol is a setting of the continuum engine, not of engine {self.engine!r}: leave it out")
        if self.engine != "continuum" and self.rule != "thesis":
            raise InputError(f"rule {self.rule!r} is computed by the continuum engine only, not by engine "
                             f"{self.engine!r}")
        check_steps(self.thickness, self.step)
        thickness_targets(self.record, self.thickness, "record")
        if self.snapshots is not None:
            thickness_targets(self.snapshots, self.thickness, "snapshots", empty=True)

    def model(self) -> Model:
        """The physics of the run."""
        return Model(k_exp=self.k_exp, step=self.step, distance=self.distance, volume=self.volume, rule=self.rule)

    def engine_settings(self):
        """The engine and its settings (`planarize.engines.Fast`, `Reference` or `Matlab`)."""
        settings = engine_settings(self.engine)
        if isinstance(settings, Fast):
            settings = Fast(tolerance=self.tolerance, interacting=self.interacting)
        if isinstance(settings, Continuum) and self.rtol is not None:
            settings = Continuum(rtol=self.rtol)
        return settings

    def options(self) -> dict:
        """Keyword arguments of `planarize.anodize` (all but the surface and ``progress``)."""
        return {"thickness": self.thickness, "model": self.model(), "engine": self.engine_settings(),
                "record": self.record, "snapshots": self.snapshots}


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
    """

    name: str = "scene"
    seed: int = 0
    surface: SurfaceSpec = field(default_factory=SurfaceSpec)
    run: RunSettings = field(default_factory=RunSettings)

    def __post_init__(self):
        check_fields(self, TOP_PARAMS)
        if not isinstance(self.surface, SurfaceSpec) or not isinstance(self.run, RunSettings):
            raise InputError("surface must be a SurfaceSpec and run a RunSettings")

    def build_surface(self) -> Surface:
        """The starting metal surface."""
        return self.surface.build(self.seed)

    def anodize(self, *, progress: bool = False, **options) -> Anodization:
        """Run the scene (`planarize.anodize`); ``options`` replace its arguments for this call (e.g.
        ``snapshots``, ``observer``, ``max_seconds``)."""
        return anodize(self.build_surface(), progress=progress, **{**self.run.options(), **options})

    def replace(self, **changes) -> PlanarizeScene:
        """A copy with top-level fields (or ``run`` settings given as a dict) replaced."""
        if isinstance(changes.get("run"), dict):
            changes["run"] = dataclasses.replace(self.run, **changes["run"])
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
        if self.run.engine == "continuum":
            rtol = Continuum().rtol if self.run.rtol is None else self.run.rtol
            run["rtol"] = min(1.0, float(f"{rtol / fraction:.12g}"))
        return self.replace(name=f"{self.name} quick {fraction:g}", surface=SurfaceSpec(self.surface.kind, params),
                            run=run)


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


__all__ = ["PlanarizeScene", "SurfaceSpec", "RunSettings", "SCENES", "SURFACE_KINDS", "SURFACES", "RUN_PARAMS", "RUN",
           "TOP_PARAMS", "TOP", "get_scene"]
